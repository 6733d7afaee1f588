"""Numba kernels of the fast checker's validity tests: one configuration, batches, motions.

Each group (the spheres covering one collision geometry) has a bounding sphere; static
obstacles and fixed robot parts are first ruled out by their distance grids, group (on the
coarse grids, which stay in cache) then sphere (on the fine ones); a group that one or two
joints move is ruled out of the fixed parts by its gap table when the grid cannot
(``self_table.py``).
A sphere that may touch a primitive is settled in three steps: its inner ball (a ball inside
the covered geometry, radius ``inner``) touching the primitive is a certain collision;
otherwise the covered geometry itself (``GroupGeometry``: a box, cylinder or sphere, or the
convex hull of each connected part of a mesh) is tested against the primitive with
:func:`gjk.convex_collide`, once per (geometry, primitive) and configuration; a geometry with
neither counts the sphere hit as a collision. Self-collision: group bounding spheres, then the
pair's gap table when one or two joints move them apart (``self_table.py``), then sphere
pairs, then the same three steps on the two geometries (every part of one against
every part of the other). Fixed robot parts are the boxes that contain their meshes
(``primitives.geometry_primitives``), so a hit is confirmed against such a box. Every "free"
answer is so proved for the solid hulls, which contain the meshes. Sphere centres are only
computed for groups that need them.

The kernels read a ``packed.PackedWorld`` (``world``) and, for one configuration, work
arrays (:class:`Work`). Each kernel takes the arrays it needs out of the named tuples once, at
its top, and hands plain arrays to the small inlined helpers: in compiled code, taking a
field out of a tuple of arrays counts a reference to every array it holds, so doing it in a
loop costs more than the work (measured with the fields read in the loops: one motion check
2.5 times slower, 98 → 241 µs on tabletop_pole).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from chekhov.collision.codes import (
    DYNAMIC,
    FIXED,
    HULL,
    INVALID,
    NO_GEOMETRY,
    NONE,
    SELF,
    STATIC,
    VALID,
)
from chekhov.collision.gjk import convex_collide
from chekhov.collision.kernels import (
    grid_classify,
    part_centre,
    place_geometry,
    signed_distance,
    transform_points,
)
from chekhov.collision.self_table import table_gap
from chekhov.robot.chain_kinematics import chain_fk_arrays


class Work(NamedTuple):
    """Work arrays of :func:`config_collides`: Rb (K, 3, 3), pb (K, 3) joint poses; cw (S, 3)
    sphere and gw (G, 3) group centres (world); done (G,) bool: cw holds group g's spheres;
    cand (C,) int64 primitive candidates, C ≥ the number of static, dynamic and fixed
    primitives; pend (G·C + self pairs, 3) int64: the pending exact tests (group, source,
    primitive or other group)."""

    Rb: np.ndarray
    pb: np.ndarray
    cw: np.ndarray
    gw: np.ndarray
    done: np.ndarray
    cand: np.ndarray
    pend: np.ndarray


@njit(cache=True, nogil=True, inline="always")
def _confirm(gk, es, pstart, vstart, hv, hc, hr, g, Rw, pw, kb, Rb, pb, sb, Vb, b0, b1, cb,
             bc, br, pad, c):  # pragma: no cover - compiled
    """False only when every part of group g's geometry (kind gk[g], size es[g], parts
    pstart[g]:pstart[g+1] with support points hv[vstart[k]:vstart[k+1]], centres hc[k] and
    bounding radii hr[k]; world pose Rw, pw) is proved more than ``pad`` (m) from shape B (as
    in :func:`gjk.convex_collide`, a point cb inside it; when a ``HULL``, inside the ball of
    radius br about bc). A part whose ball is that far from B (B's exact distance, or its
    ball's) needs no GJK. c (3,) is work space."""
    for k in range(pstart[g], pstart[g + 1]):
        part_centre(hc, k, Rw, pw, c)
        if kb == HULL:
            x, y, z = c[0] - bc[0], c[1] - bc[1], c[2] - bc[2]
            if x * x + y * y + z * z > (hr[k] + br + pad) ** 2:
                continue
        elif signed_distance(kb, Rb, pb, sb, c) > hr[k] + pad:
            continue
        if convex_collide(gk[g], Rw, pw, es[g], hv, vstart[k], vstart[k + 1], c,
                          kb, Rb, pb, sb, Vb, b0, b1, cb, pad):
            return True
    return False


@njit(cache=True, nogil=True, inline="always")
def _centers(Rb, pb, sj, sc, a, b, cw):  # pragma: no cover - compiled
    for i in range(a, b):
        j = sj[i]
        for x in range(3):
            cw[i, x] = (Rb[j, x, 0] * sc[i, 0] + Rb[j, x, 1] * sc[i, 1] + Rb[j, x, 2] * sc[i, 2]
                        + pb[j, x])


@njit(cache=True, nogil=True, inline="always")
def _near(kind, R, p, size, c, r, cand):  # pragma: no cover - compiled
    """The primitives (kind, R, p, size) closer than r to point c, into cand; returns how
    many."""
    n = 0
    for o in range(kind.shape[0]):
        if signed_distance(kind[o], R[o], p[o], size[o], c) < r:
            cand[n] = o
            n += 1
    return n


@njit(cache=True, nogil=True, inline="always")
def _group_hits(g, src, kind, R, p, size, ck, cand, ncand, cw, sr, rin, gstart, gk, pend,
                npend):  # pragma: no cover - compiled
    """Spheres of group g against the primitives cand[:ncand] of (kind, R, p, size) (source
    ``src``): -1 when the geometry certainly touches one (an inner ball does, or the geometry
    is ``NO_GEOMETRY``); otherwise the new count of pending exact tests, (g, src, primitive)
    appended to ``pend``. ``ck``: the primitives' confirmation kinds; an inner ball proves
    nothing against a ``HULL`` one (a box around part of a mesh, not a solid)."""
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
            if gk[g] == NO_GEOMETRY:
                return -1
            pend[npend, 0], pend[npend, 1], pend[npend, 2] = g, src, o
            npend += 1
    return npend


@njit(cache=True, nogil=True)
def collisions(Q, world, work, out, stop):  # pragma: no cover - compiled
    """Whether each row of Q (N, K) collides (environment, fixed robot parts, or itself) in
    ``world`` (a ``PackedWorld``), in order, into out (N,) bool; with ``stop``, rows after the
    first colliding one are left unwritten. Returns the first colliding row, or ``NONE``.
    ``work``: a :class:`Work` (see :func:`make_work`).

    Certain collisions are looked for first everywhere; the exact primitive tests of the
    uncertain sphere hits run last. The test of one configuration is a closure, which numba
    inlines here with the arrays it reads bound once for the whole batch: a compiled call
    with the packed world as argument costs about 0.4-0.7 µs (every array it holds is
    counted on the way in and out: measured on shelf_boxes, a call that does nothing), a
    quarter of checking a configuration."""
    # every array, out of the named tuples once (see the module docstring)
    Rb, pb, cw, gw, done, cand, pend = work
    chain, spheres, groups, grids = world.chain, world.spheres, world.groups, world.grids
    parent, R0, p0, axis = chain.parent, chain.R_parent_joint, chain.p_parent_joint, chain.axis
    sc, sr, sj, rin = spheres.centre, spheres.radius, spheres.joint, spheres.inner
    gstart, gc, gr, gj = groups.start, groups.centre, groups.radius, groups.joint
    self_pairs = groups.self_pairs
    st, dy, fixed = world.static, world.dynamic, world.fixed
    sk, sR, sp, ss = st.kind, st.R, st.p, st.size
    dk, dR, dp, ds = dy.kind, dy.R, dy.p, dy.size
    fprims, clusters = fixed.prims, fixed.clusters
    fk, fR, fp, fs = fprims.kind, fprims.R, fprims.p, fprims.size
    fck, fvs, fV, fcen, fallow = (fixed.hull_kind, fixed.vert_start, fixed.verts, fixed.centre,
                                  fixed.allowed)
    clc, clr, cls, clm = clusters.centre, clusters.radius, clusters.start, clusters.members
    origin, delta, V, Vc = grids.origin, grids.delta, grids.fine, grids.coarse
    h, ih, hc, ihc = grids.h, grids.inv_h, grids.coarse_h, grids.inv_coarse_h
    gfix, gsurf, order, gclear = grids.fixed, grids.surface, grids.order, grids.clear
    geo = world.geometry
    gk, eR, ep, es, pad = geo.kind, geo.R, geo.p, geo.size, geo.pad
    pstart, vstart, hv, hcen = geo.part_start, geo.vert_start, geo.verts, geo.part_centre
    hrad, fb = geo.part_radius, fprims.bound
    tpair, tjoint, tlo, tinv, tgap, tgroup = world.self_tables

    # the confirmations' work space, allocated once for the batch (six small allocations
    # per configuration cost as much as the grid lookups of a free one)
    Rw = np.empty((3, 3))
    pw = np.empty(3)
    Rw2 = np.empty((3, 3))
    pw2 = np.empty(3)
    c = np.empty(3)
    c2 = np.empty(3)

    def collides(q):
        chain_fk_arrays(q, parent, R0, p0, axis, Rb, pb)
        transform_points(Rb, pb, gj, gc, gw)
        G = gr.shape[0]
        for g in range(G):
            done[g] = False
        npend = 0
        for gi in range(G):
            g = order[gi]  # groups that collide most often first: collisions end the test early
            nd = _near(dk, dR, dp, ds, gw[g], gr[g], cand)
            fg = gfix[g]
            # one lookup clears most groups of both the static obstacles and their fixed parts
            if grid_classify(origin, ihc, hc, delta, Vc, gclear[g], gw[g], gr[g]) == VALID:
                if nd == 0:
                    continue
                env = VALID
                fix = VALID
            else:
                env = grid_classify(origin, ihc, hc, delta, Vc, 0, gw[g], gr[g])
                fix = VALID if fg < 0 else grid_classify(origin, ihc, hc, delta, Vc, fg, gw[g],
                                                         gr[g])
                if fix != VALID and table_gap(q, g, tgroup, tjoint, tlo, tinv, tgap) > pad[g]:
                    fix = VALID   # proved apart over the cell of the joints that move it
                if env == VALID and fix == VALID and nd == 0:
                    continue
            _centers(Rb, pb, sj, sc, gstart[g], gstart[g + 1], cw)
            done[g] = True
            if nd > 0:
                npend = _group_hits(g, DYNAMIC, dk, dR, dp, ds, dk, cand, nd, cw, sr, rin, gstart,
                                    gk, pend, npend)
                if npend < 0:
                    return True
            if env != VALID:
                maybe = False
                for s in range(gstart[g], gstart[g + 1]):
                    e = grid_classify(origin, ih, h, delta, V, 0, cw[s], sr[s])
                    if e == INVALID and rin[s] > 0.0 and \
                            grid_classify(origin, ih, h, delta, V, 0, cw[s], rin[s]) == INVALID:
                        return True
                    if e != VALID:
                        maybe = True
                if maybe:
                    n = _near(sk, sR, sp, ss, gw[g], gr[g], cand)
                    npend = _group_hits(g, STATIC, sk, sR, sp, ss, sk, cand, n, cw, sr, rin,
                                        gstart, gk, pend, npend)
                    if npend < 0:
                        return True
            if fix != VALID:
                maybe = False
                for s in range(gstart[g], gstart[g + 1]):
                    f = grid_classify(origin, ih, h, delta, V, fg, cw[s], sr[s])
                    if f == INVALID and rin[s] > 0.0 and gsurf[g] >= 0 and grid_classify(
                            origin, ih, h, delta, V, gsurf[g], cw[s], rin[s]) == INVALID:
                        return True
                    if f != VALID:
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
                    npend = _group_hits(g, FIXED, fk, fR, fp, fs, fck, cand, n, cw, sr, rin,
                                        gstart, gk, pend, npend)
                    if npend < 0:
                        return True
        # self-collision: group pairs, then sphere pairs
        for i in range(self_pairs.shape[0]):
            a = self_pairs[i, 0]
            b = self_pairs[i, 1]
            x = gw[a, 0] - gw[b, 0]
            y = gw[a, 1] - gw[b, 1]
            z = gw[a, 2] - gw[b, 2]
            if x * x + y * y + z * z >= (gr[a] + gr[b]) ** 2:
                continue
            if table_gap(q, i, tpair, tjoint, tlo, tinv, tgap) > pad[a] + pad[b]:
                continue      # proved apart over the whole cell of the joints between them
            for g in (a, b):
                if not done[g]:
                    _centers(Rb, pb, sj, sc, gstart[g], gstart[g + 1], cw)
                    done[g] = True
            hit = False
            for s in range(gstart[a], gstart[a + 1]):
                x = cw[s, 0] - gw[b, 0]
                y = cw[s, 1] - gw[b, 1]
                z = cw[s, 2] - gw[b, 2]
                if x * x + y * y + z * z >= (sr[s] + gr[b]) ** 2:
                    continue   # sphere s clears group b's bounding sphere, so all its spheres
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
                if gk[a] == NO_GEOMETRY or gk[b] == NO_GEOMETRY:
                    return True
                pend[npend, 0], pend[npend, 1], pend[npend, 2] = a, SELF, b
                npend += 1
        # the uncertain hits, on the exact geometry
        for i in range(npend):
            g, src, o = pend[i, 0], pend[i, 1], pend[i, 2]
            place_geometry(Rb, pb, gj, eR, ep, g, Rw, pw)
            if src == SELF:
                place_geometry(Rb, pb, gj, eR, ep, o, Rw2, pw2)
                for k in range(pstart[o], pstart[o + 1]):
                    part_centre(hcen, k, Rw2, pw2, c2)
                    if _confirm(gk, es, pstart, vstart, hv, hcen, hrad, g, Rw, pw, gk[o], Rw2,
                                pw2, es[o], hv, vstart[k], vstart[k + 1], c2, c2, hrad[k],
                                pad[g] + pad[o], c):
                        return True
                continue
            if src == STATIC:
                hit = _confirm(gk, es, pstart, vstart, hv, hcen, hrad, g, Rw, pw, sk[o], sR[o],
                               sp[o], ss[o], hv, 0, 0, sp[o], sp[o], 0.0, pad[g], c)
            elif src == FIXED:  # a fixed part: the hull of its mesh cluster, or its primitive
                hit = _confirm(gk, es, pstart, vstart, hv, hcen, hrad, g, Rw, pw, fck[o], fR[o],
                               fp[o], fs[o], fV, fvs[o], fvs[o + 1], fcen[o], fp[o], fb[o],
                               pad[g], c)
            else:
                hit = _confirm(gk, es, pstart, vstart, hv, hcen, hrad, g, Rw, pw, dk[o], dR[o],
                               dp[o], ds[o], hv, 0, 0, dp[o], dp[o], 0.0, pad[g], c)
            if hit:
                return True
        return False

    first = NONE
    for i in range(Q.shape[0]):
        hit = collides(Q[i])
        out[i] = hit
        if hit and first == NONE:
            first = i
            if stop:
                break
    return first


@njit(cache=True, nogil=True)
def config_collides(q, world, work):  # pragma: no cover - compiled
    """True if configuration q (K,) collides in ``world``: :func:`collisions` of one row
    (callers that check many configurations hand them over together)."""
    out = np.empty(1, dtype=np.bool_)
    return collisions(q.reshape((1, q.shape[0])), world, work, out, True) != NONE


@njit(cache=True, nogil=True)
def make_work(K, world):  # pragma: no cover - compiled
    """A :class:`Work` for ``world`` and K joints."""
    G = world.groups.radius.shape[0]
    C = (world.static.kind.shape[0] + world.dynamic.kind.shape[0]
         + world.fixed.prims.kind.shape[0] + 1)
    return Work(np.empty((K, 3, 3)), np.empty((K, 3)),
                np.empty((world.spheres.radius.shape[0], 3)), np.empty((G, 3)),
                np.empty(G, dtype=np.bool_), np.empty(C, dtype=np.int64),
                np.empty((G * C + world.groups.self_pairs.shape[0] + 1, 3), dtype=np.int64))


@njit(cache=True, nogil=True)
def valid_batch(Q, world):  # pragma: no cover - compiled
    """Collision-free flag for each row of Q (N, K)."""
    work = make_work(Q.shape[1], world)
    out = np.empty(Q.shape[0], dtype=np.bool_)
    collisions(Q, world, work, out, False)
    return ~out


@njit(cache=True, nogil=True, inline="always")
def _bisection_order(n, order):  # pragma: no cover - compiled
    """The interior steps 1..n-1 of a motion in bisection (van der Corput) order, into
    order[:n - 1]: the midpoint, the quarter points, ... — collisions are found early."""
    m = 0
    step = 1
    while step < n:
        step *= 2
    while step >= 1:
        for k in range(step, n, 2 * step):
            order[m] = k
            m += 1
        step //= 2


@njit(cache=True, nogil=True)
def motions_valid(Q0, Q1, resolution, first, first_m, checks, until_free, world
                  ):  # pragma: no cover - compiled
    """(out, done, resume): whether each straight joint-space motion Q0[i] → Q1[i] is free at
    every interior step k / n, n = ceil(length / resolution) (``resolution``: rad, joint-space
    Euclidean norm; end points not checked), the steps visited in bisection order.

    From motion ``first``'s position ``first_m`` in that order on (0: its first), looking at
    ``checks`` configurations at most (:data:`NO_BUDGET`: all; see :func:`check_budget`):
    out[first:done] are decided; when done < N, motion ``done`` is to be resumed at position
    ``resume``. With ``until_free`` it returns after the first free motion (done = its index
    + 1): candidates in order of preference, one call.

    Replayed on the motion checks Roadmap + TrajOpt made on 40 task cases (shelf_boxes,
    kitchen, panda_cage), this took 1.3-2.9x less time than walking each motion with
    clearance certificates (``dense_path``'s walk, used here before: a visit costs several
    checks, and a blocked motion was walked up to its collision); on RRTConnect's, 1.3x less
    in shelf_boxes and 5% more in panda_cage (the Panda's long free motions, where
    certificates skip most steps)."""
    K = Q0.shape[1]
    work = make_work(K, world)
    out = np.zeros(Q0.shape[0], dtype=np.bool_)
    buf = np.empty((0, K))
    hits = np.empty(0, dtype=np.bool_)
    order = np.empty(0, dtype=np.int64)
    left = checks
    for i in range(first, Q0.shape[0]):
        d = Q1[i] - Q0[i]
        n = int(np.ceil(np.sqrt(np.sum(d * d)) / resolution))
        m0 = first_m if i == first else 0
        if n - 1 <= m0:   # no interior step (left)
            out[i] = True
            if until_free:
                return out, i + 1, 0
            continue
        if left <= 0:
            return out, i, m0
        if n - 1 > order.shape[0]:
            order = np.empty(n - 1, dtype=np.int64)
            buf = np.empty((n - 1, K))
            hits = np.empty(n - 1, dtype=np.bool_)
        _bisection_order(n, order)
        m1 = min(n - 1, m0 + left)
        for m in range(m0, m1):
            t = order[m] / n
            for a in range(K):
                buf[m - m0, a] = Q0[i, a] + t * d[a]
        left -= m1 - m0
        if collisions(buf[:m1 - m0], world, work, hits, True) != NONE:
            continue
        if m1 < n - 1:
            return out, i, m1
        out[i] = True
        if until_free:
            return out, i + 1, 0
    return out, Q0.shape[0], 0


NO_BUDGET = 2 ** 62
"""A kernel's budget of configurations when there is none (here and in ``dense_path``)."""
CHECK_COST_S = 2e-5
"""s: what :func:`motions_valid` may take per configuration, for its budget
(:func:`check_budget`): a few times the Panda's mean near obstacles (4-5 µs on shelf_boxes
configurations its coarse grids block, each confirmed by spheres and GJK)."""
MIN_CHECKS = 16
"""Configurations one budgeted call may look at however near the deadline."""


def check_budget(left_s: float) -> int:
    """Configurations one call of :func:`motions_valid` may look at with ``left_s`` (s) before
    its deadline: those that take half of it at :data:`CHECK_COST_S` each, at least
    :data:`MIN_CHECKS`, so that the calls shrink as the deadline nears and the last overruns it
    by little (:data:`NO_BUDGET` when the deadline is far)."""
    if left_s >= NO_BUDGET * CHECK_COST_S:
        return NO_BUDGET
    return max(MIN_CHECKS, int(0.5 * left_s / CHECK_COST_S))


@njit(cache=True, nogil=True)
def group_block_rates(Q, chain, groups, grids):  # pragma: no cover - compiled
    """Per group, the fraction of configurations Q (N, K) whose bounding sphere is not proved
    free of the static obstacles and fixed parts by the coarse grids: how often the group
    needs a closer look (and, in practice, how often it collides)."""
    parent, R0, p0, axis = chain.parent, chain.R_parent_joint, chain.p_parent_joint, chain.axis
    gc, gj, gr, gfix = groups.centre, groups.joint, groups.radius, grids.fixed
    origin, delta, hc, ihc, Vc = (grids.origin, grids.delta, grids.coarse_h,
                                  grids.inv_coarse_h, grids.coarse)
    K = Q.shape[1]
    G = gr.shape[0]
    Rb = np.empty((K, 3, 3))
    pb = np.empty((K, 3))
    gw = np.empty((G, 3))
    rate = np.zeros(G)
    for i in range(Q.shape[0]):
        chain_fk_arrays(Q[i], parent, R0, p0, axis, Rb, pb)
        transform_points(Rb, pb, gj, gc, gw)
        for g in range(G):
            blocked = grid_classify(origin, ihc, hc, delta, Vc, 0, gw[g], gr[g]) != VALID
            if not blocked and gfix[g] >= 0:
                blocked = grid_classify(origin, ihc, hc, delta, Vc, gfix[g], gw[g],
                                        gr[g]) != VALID
            if blocked:
                rate[g] += 1.0
    return rate / max(Q.shape[0], 1)
