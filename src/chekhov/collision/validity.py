"""Numba kernels of the fast checker's validity tests: one configuration, batches, motions.

Each group (the spheres covering one collision geometry) has a bounding sphere; static
obstacles and fixed robot parts are first ruled out by their distance grids, group (on the
coarse grids, which stay in cache) then sphere (on the fine ones).
A sphere that may touch a primitive is settled in three steps: its inner ball (a ball inside
the covered geometry, radius ``rin``) touching the primitive is a certain collision; otherwise
the covered geometry itself (``gexact``: a box, cylinder or sphere, or the convex hull of each
connected part of a mesh) is tested against the primitive with :func:`gjk.convex_collide`,
once per (geometry, primitive) and configuration; a geometry with neither counts the sphere
hit as a collision. Self-collision: group bounding spheres, then sphere pairs, then the same
three steps on the two geometries (every part of one against every part of the other). Fixed
robot parts are the boxes that contain their meshes (``primitives.geometry_primitives``), so a
hit is confirmed against such a box. Every "free" answer is so proved for the solid hulls,
which contain the meshes. Sphere centres are only computed for groups that need them.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from chekhov.collision.gjk import HULL, convex_collide
from chekhov.collision.kernels import chain_fk, grid_classify, signed_distance


@njit(cache=True, inline="always")
def _place(Rb, pb, gk, gj, eR, ep, g, Rw, pw):  # pragma: no cover - compiled
    """World pose of group g's exact primitive."""
    j = gj[g]
    for a in range(3):
        pw[a] = (Rb[j, a, 0] * ep[g, 0] + Rb[j, a, 1] * ep[g, 1] + Rb[j, a, 2] * ep[g, 2]
                 + pb[j, a])
        for b in range(3):
            Rw[a, b] = (Rb[j, a, 0] * eR[g, 0, b] + Rb[j, a, 1] * eR[g, 1, b]
                        + Rb[j, a, 2] * eR[g, 2, b])


@njit(cache=True, inline="always")
def _part_centre(gexact, k, Rw, pw, out):  # pragma: no cover - compiled
    """World position of part k's centre, its geometry at (Rw, pw)."""
    hc = gexact[8]
    for a in range(3):
        out[a] = Rw[a, 0] * hc[k, 0] + Rw[a, 1] * hc[k, 1] + Rw[a, 2] * hc[k, 2] + pw[a]


@njit(cache=True, inline="always")
def _confirm(gexact, g, Rw, pw, kb, Rb, pb, sb, Vb, b0, b1, cb, pad, c
             ):  # pragma: no cover - compiled
    """False only when every part of group g's geometry (world pose Rw, pw) is proved more
    than ``pad`` (m) from shape B (as in :func:`gjk.convex_collide`, a point cb inside it);
    c (3,) is work space."""
    gk, _, _, es, _, pstart, vstart, hv = gexact[:8]
    for k in range(pstart[g], pstart[g + 1]):
        _part_centre(gexact, k, Rw, pw, c)
        if convex_collide(gk[g], Rw, pw, es[g], hv, vstart[k], vstart[k + 1], c,
                          kb, Rb, pb, sb, Vb, b0, b1, cb, pad):
            return True
    return False


@njit(cache=True, inline="always")
def _centers(Rb, pb, sj, sc, a, b, cw):  # pragma: no cover - compiled
    for i in range(a, b):
        j = sj[i]
        for x in range(3):
            cw[i, x] = (Rb[j, x, 0] * sc[i, 0] + Rb[j, x, 1] * sc[i, 1] + Rb[j, x, 2] * sc[i, 2]
                        + pb[j, x])


@njit(cache=True, inline="always")
def _group_hits(g, src, kind, R, p, size, ck, cand, ncand, cw, sr, rin, gstart, gk, pend,
                npend):  # pragma: no cover - compiled
    """Spheres of group g against the primitives cand[:ncand]: -1 when the geometry certainly
    touches one (an inner ball does, or the geometry has no exact primitive); otherwise the
    new count of pending exact tests, (g, src, primitive) appended to ``pend``. ``ck``: the
    primitives' confirmation kinds; an inner ball proves nothing against a ``HULL`` one (a box
    around part of a mesh, not a solid)."""
    for ii in range(ncand):
        o = cand[ii]
        hit = False
        for s in range(gstart[g], gstart[g + 1]):
            d = signed_distance(kind[o], R[o], p[o], size[o], cw[s])
            if d < rin[s] and rin[s] > 0.0 and ck[o] != HULL:
                return -1
            if d < sr[s]:
                hit = True
        if hit:
            if gk[g] < 0:
                return -1
            pend[npend, 0], pend[npend, 1], pend[npend, 2] = g, src, o
            npend += 1
    return npend


@njit(cache=True)
def config_collides(q, chain, spheres, groups, static, dyn, fixed, fixed_csr, self_pairs,
                    grids, gexact, rin, Rb, pb, cw, gw, done, cand, pend
                    ):  # pragma: no cover - compiled
    """True if configuration q collides (environment, fixed robot parts, or itself).

    Certain collisions are looked for first everywhere; the exact primitive tests of the
    uncertain sphere hits run last. Work arrays: Rb (K, 3, 3), pb (K, 3), cw (S, 3), gw (G, 3),
    done (G,) bool, cand (C,) int64 with C ≥ the number of static, dynamic and fixed
    primitives, pend (G·C + self pairs, 3) int64."""
    parent, R0, p0, axis = chain
    sc, sr, sj = spheres
    gstart, gc, gr, gj = groups
    sk, sR, sp, ss = static
    dk, dR, dp, ds = dyn
    fk, fR, fp, fs = fixed
    _, _, fallow, clc, clr, cls, clm = fixed_csr
    origin, h, delta, V, gfix, hc, Vc, order = grids
    gk, eR, ep, es, pad = gexact[:5]
    fck, fvs, fV, fcen, gsurf = gexact[9:14]
    ih = 1.0 / h
    ihc = 1.0 / hc
    chain_fk(q, parent, R0, p0, axis, Rb, pb)
    G = gr.shape[0]
    for g in range(G):
        j = gj[g]
        for a in range(3):
            gw[g, a] = (Rb[j, a, 0] * gc[g, 0] + Rb[j, a, 1] * gc[g, 1]
                        + Rb[j, a, 2] * gc[g, 2] + pb[j, a])
        done[g] = False
    npend = 0
    for gi in range(G):
        g = order[gi]  # groups that collide most often first: collisions end the test early
        env = grid_classify(origin, ihc, hc, delta, Vc, 0, gw[g], gr[g])
        fg = gfix[g]
        fix = 1 if fg < 0 else grid_classify(origin, ihc, hc, delta, Vc, fg, gw[g], gr[g])
        nd = 0
        for o in range(dk.shape[0]):
            if signed_distance(dk[o], dR[o], dp[o], ds[o], gw[g]) < gr[g]:
                cand[nd] = o
                nd += 1
        if env == 1 and fix == 1 and nd == 0:
            continue
        _centers(Rb, pb, sj, sc, gstart[g], gstart[g + 1], cw)
        done[g] = True
        if nd > 0:
            npend = _group_hits(g, 2, dk, dR, dp, ds, dk, cand, nd, cw, sr, rin, gstart, gk,
                                pend, npend)
            if npend < 0:
                return True
        if env != 1:
            maybe = False
            for s in range(gstart[g], gstart[g + 1]):
                e = grid_classify(origin, ih, h, delta, V, 0, cw[s], sr[s])
                if e == -1 and rin[s] > 0.0 and \
                        grid_classify(origin, ih, h, delta, V, 0, cw[s], rin[s]) == -1:
                    return True
                if e != 1:
                    maybe = True
            if maybe:
                n = 0
                for o in range(sk.shape[0]):
                    if signed_distance(sk[o], sR[o], sp[o], ss[o], gw[g]) < gr[g]:
                        cand[n] = o
                        n += 1
                npend = _group_hits(g, 0, sk, sR, sp, ss, sk, cand, n, cw, sr, rin, gstart,
                                    gk, pend, npend)
                if npend < 0:
                    return True
        if fix != 1:
            maybe = False
            for s in range(gstart[g], gstart[g + 1]):
                f = grid_classify(origin, ih, h, delta, V, fg, cw[s], sr[s])
                if f == -1 and rin[s] > 0.0 and gsurf[g] >= 0 and \
                        grid_classify(origin, ih, h, delta, V, gsurf[g], cw[s], rin[s]) == -1:
                    return True
                if f != 1:
                    maybe = True
            if maybe:
                n = 0
                for cl in range(clc.shape[0]):  # clusters of fixed parts, then their members
                    dc = np.sqrt((gw[g, 0] - clc[cl, 0]) ** 2 + (gw[g, 1] - clc[cl, 1]) ** 2
                                 + (gw[g, 2] - clc[cl, 2]) ** 2)
                    if dc - clr[cl] >= gr[g]:
                        continue
                    for ii in range(cls[cl], cls[cl + 1]):
                        o = clm[ii]
                        if fallow[g, o] and \
                                signed_distance(fk[o], fR[o], fp[o], fs[o], gw[g]) < gr[g]:
                            cand[n] = o
                            n += 1
                npend = _group_hits(g, 1, fk, fR, fp, fs, fck, cand, n, cw, sr, rin, gstart,
                                    gk, pend, npend)
                if npend < 0:
                    return True
    for i in range(self_pairs.shape[0]):
        a = self_pairs[i, 0]
        b = self_pairs[i, 1]
        x = gw[a, 0] - gw[b, 0]
        y = gw[a, 1] - gw[b, 1]
        z = gw[a, 2] - gw[b, 2]
        if x * x + y * y + z * z >= (gr[a] + gr[b]) ** 2:
            continue
        for g in (a, b):
            if not done[g]:
                _centers(Rb, pb, sj, sc, gstart[g], gstart[g + 1], cw)
                done[g] = True
        hit = False
        for s in range(gstart[a], gstart[a + 1]):
            for t in range(gstart[b], gstart[b + 1]):
                x = cw[s, 0] - cw[t, 0]
                y = cw[s, 1] - cw[t, 1]
                z = cw[s, 2] - cw[t, 2]
                d2 = x * x + y * y + z * z
                if d2 < (rin[s] + rin[t]) ** 2 and rin[s] > 0.0 and rin[t] > 0.0:
                    return True
                if d2 < (sr[s] + sr[t]) ** 2:
                    hit = True
        if hit:
            if gk[a] < 0 or gk[b] < 0:
                return True
            pend[npend, 0], pend[npend, 1], pend[npend, 2] = a, 3, b
            npend += 1
    # the uncertain hits, on the exact geometry
    Rw = np.empty((3, 3))
    pw = np.empty(3)
    Rw2 = np.empty((3, 3))
    pw2 = np.empty(3)
    c = np.empty(3)
    c2 = np.empty(3)
    pstart, vstart, hv = gexact[5], gexact[6], gexact[7]
    for i in range(npend):
        g, src, o = pend[i, 0], pend[i, 1], pend[i, 2]
        _place(Rb, pb, gk, gj, eR, ep, g, Rw, pw)
        if src == 3:
            _place(Rb, pb, gk, gj, eR, ep, o, Rw2, pw2)
            for k in range(pstart[o], pstart[o + 1]):
                _part_centre(gexact, k, Rw2, pw2, c2)
                if _confirm(gexact, g, Rw, pw, gk[o], Rw2, pw2, es[o], hv, vstart[k],
                            vstart[k + 1], c2, pad[g] + pad[o], c):
                    return True
            continue
        if src == 0:
            hit = _confirm(gexact, g, Rw, pw, sk[o], sR[o], sp[o], ss[o], hv, 0, 0, sp[o],
                           pad[g], c)
        elif src == 1:  # a fixed part: the hull of its mesh cluster, or its primitive
            hit = _confirm(gexact, g, Rw, pw, fck[o], fR[o], fp[o], fs[o], fV, fvs[o],
                           fvs[o + 1], fcen[o], pad[g], c)
        else:
            hit = _confirm(gexact, g, Rw, pw, dk[o], dR[o], dp[o], ds[o], hv, 0, 0, dp[o],
                           pad[g], c)
        if hit:
            return True
    return False


@njit(cache=True)
def _work(K, spheres, groups, static, dyn, fixed, self_pairs):  # pragma: no cover - compiled
    G = groups[1].shape[0]
    C = static[0].shape[0] + dyn[0].shape[0] + fixed[0].shape[0] + 1
    return (np.empty((K, 3, 3)), np.empty((K, 3)), np.empty((spheres[0].shape[0], 3)),
            np.empty((G, 3)), np.empty(G, dtype=np.bool_), np.empty(C, dtype=np.int64),
            np.empty((G * C + self_pairs.shape[0] + 1, 3), dtype=np.int64))


@njit(cache=True)
def valid_batch(Q, chain, spheres, groups, static, dyn, fixed, fixed_csr, self_pairs, grids,
                gexact, rin):  # pragma: no cover - compiled
    """Collision-free flag for each row of Q (N, K)."""
    Rb, pb, cw, gw, done, cand, pend = _work(Q.shape[1], spheres, groups, static, dyn, fixed,
                                             self_pairs)
    out = np.empty(Q.shape[0], dtype=np.bool_)
    for i in range(Q.shape[0]):
        out[i] = not config_collides(Q[i], chain, spheres, groups, static, dyn, fixed,
                                     fixed_csr, self_pairs, grids, gexact, rin, Rb, pb, cw, gw,
                                     done, cand, pend)
    return out


@njit(cache=True)
def motions_valid(Q0, Q1, resolution, chain, spheres, groups, static, dyn, fixed, fixed_csr,
                  self_pairs, grids, gexact, rin):  # pragma: no cover - compiled
    """Whether each straight joint-space motion Q0[i] -> Q1[i] is free at every interior step.

    Steps are at most ``resolution`` (rad, joint-space Euclidean norm) apart and are visited in
    bisection order so that collisions are found early. The end points are not checked.
    """
    K = Q0.shape[1]
    Rb, pb, cw, gw, done, cand, pend = _work(K, spheres, groups, static, dyn, fixed,
                                             self_pairs)
    out = np.empty(Q0.shape[0], dtype=np.bool_)
    q = np.empty(K)
    for i in range(Q0.shape[0]):
        d = Q1[i] - Q0[i]
        n = int(np.ceil(np.sqrt(np.sum(d * d)) / resolution))
        ok = True
        # bisection (van der Corput) order over the interior points 1..n-1
        step = 1
        while step < n:
            step *= 2
        while step >= 1 and ok:
            for k in range(step, n, 2 * step):
                t = k / n
                for a in range(K):
                    q[a] = Q0[i, a] + t * d[a]
                if config_collides(q, chain, spheres, groups, static, dyn, fixed, fixed_csr,
                                   self_pairs, grids, gexact, rin, Rb, pb, cw, gw, done, cand,
                                   pend):
                    ok = False
                    break
            step //= 2
        out[i] = ok
    return out


@njit(cache=True)
def group_block_rates(Q, chain, groups, grids):  # pragma: no cover - compiled
    """Per group, the fraction of configurations Q (N, K) whose bounding sphere is not proved
    free of the static obstacles and fixed parts by the coarse grids: how often the group
    needs a closer look (and, in practice, how often it collides)."""
    parent, R0, p0, axis = chain
    _, gc, gr, gj = groups
    origin, _, delta, _, gfix, hc, Vc, _ = grids
    K = Q.shape[1]
    G = gr.shape[0]
    Rb = np.empty((K, 3, 3))
    pb = np.empty((K, 3))
    c = np.empty(3)
    rate = np.zeros(G)
    for i in range(Q.shape[0]):
        chain_fk(Q[i], parent, R0, p0, axis, Rb, pb)
        for g in range(G):
            j = gj[g]
            for a in range(3):
                c[a] = (Rb[j, a, 0] * gc[g, 0] + Rb[j, a, 1] * gc[g, 1]
                        + Rb[j, a, 2] * gc[g, 2] + pb[j, a])
            blocked = grid_classify(origin, 1.0 / hc, hc, delta, Vc, 0, c, gr[g]) != 1
            if not blocked and gfix[g] >= 0:
                blocked = grid_classify(origin, 1.0 / hc, hc, delta, Vc, gfix[g], c, gr[g]) != 1
            if blocked:
                rate[g] += 1.0
    return rate / max(Q.shape[0], 1)
