"""Signed-distance terms of a whole trajectory and their joint-space gradients, for the optimiser.

For each waypoint (discrete terms) and each segment between waypoints (continuous terms) the
kernels return the C closest (link group, obstacle) pairs within a margin: their signed distance
(m) and its gradient with respect to the joint angles (m/rad), through the Jacobian of the
sphere centre that realises the distance (d sd / dq = nᵀ J_c(q)).

Continuous terms follow TrajOpt's swept-volume idea for spheres: the sphere swept between its
centres c₀ (at q_t) and c₁ (at q_{t+1}) is the capsule ∪_α sphere(c₀ + α (c₁ - c₀)). Its signed
distance to a convex obstacle is min_α sd(c(α)) - r, a convex problem in α (golden-section
search); at the minimiser α*, the gradient splits as (1 - α*) nᵀ J_c(q_t) and α* nᵀ J_c(q_{t+1}).

Their Python facade: :class:`~chekhov.collision.trajectory_distances.TrajectoryDistances`.
All kernels read a ``packed.PackedWorld`` (its exact primitives, not its grids): the chain,
spheres, groups, the scene's obstacles (``world.obstacles``) and the fixed robot parts.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

from chekhov.collision.codes import FIXED, NO_TERM, OBSTACLE, SELF
from chekhov.collision.kernels import (
    signed_distance,
    signed_distance_normal,
    signed_distance_xyz,
)
from chekhov.collision.self_table import table_gap
from chekhov.robot.chain_kinematics import chain_fk_arrays

Array = NDArray[np.float64]

SWEPT_ITERATIONS = 30
"""Golden-section steps, at most, of the swept spheres' closest point along a segment."""

SWEPT_TOLERANCE_M = 1e-4
"""m: the golden-section search stops once its bracket spans less than this much of the
sphere's travel (sd is 1-Lipschitz, so the minimum found is then within this of the true
one: far less than the safety margin, and the answer is certified exactly anyway). Measured
on the segment terms of 20 task cases' TrajOpt runs a scene, replayed, against 1e-5: 12-15%
less time (shelf_boxes 5.9 → 5.0 ms a case), the same terms, distances at most 2.1e-5 m
larger."""

_GOLDEN = 0.3819660112501051


class Candidates(NamedTuple):
    """Candidate terms (cap of them): distance (m), sphere, other (obstacle, fixed part or
    sphere index), source (``codes.OBSTACLE`` / ``FIXED`` / ``SELF``), alpha (where along the
    segment, 0 for a waypoint), normal (cap, 3) (unit, world)."""

    distance: np.ndarray
    sphere: np.ndarray
    other: np.ndarray
    source: np.ndarray
    alpha: np.ndarray
    normal: np.ndarray


@njit(cache=True, nogil=True, inline="always")
def _world_axes(Rb, axis, out):  # pragma: no cover - compiled
    for k in range(axis.shape[0]):
        for a in range(3):
            out[k, a] = (Rb[k, a, 0] * axis[k, 0] + Rb[k, a, 1] * axis[k, 1]
                         + Rb[k, a, 2] * axis[k, 2])


@njit(cache=True, nogil=True, inline="always")
def _add_point_gradient(n, c, joint, parent, aw, pb, scale, g):  # pragma: no cover - compiled
    """g += scale · nᵀ J_c: for each ancestor joint i of ``joint``, n · (a_i × (c - p_i))."""
    i = joint
    while i >= 0:
        r0 = c[0] - pb[i, 0]
        r1 = c[1] - pb[i, 1]
        r2 = c[2] - pb[i, 2]
        a0, a1, a2 = aw[i, 0], aw[i, 1], aw[i, 2]
        g[i] += scale * (n[0] * (a1 * r2 - a2 * r1) + n[1] * (a2 * r0 - a0 * r2)
                         + n[2] * (a0 * r1 - a1 * r0))
        i = parent[i]


@njit(cache=True, nogil=True, inline="always")
def _centres(q, parent, R0, p0, axis, sc, sj, gc, gj, Rb, pb, cw, gw
             ):  # pragma: no cover - compiled
    """Joint poses, sphere centres cw (S, 3) and group centres gw (G, 3), world, at q (the
    chain's arrays, the spheres' and groups' centres and joints)."""
    chain_fk_arrays(q, parent, R0, p0, axis, Rb, pb)
    for s in range(sc.shape[0]):
        j = sj[s]
        for a in range(3):
            cw[s, a] = (Rb[j, a, 0] * sc[s, 0] + Rb[j, a, 1] * sc[s, 1] + Rb[j, a, 2] * sc[s, 2]
                        + pb[j, a])
    for g in range(gc.shape[0]):
        j = gj[g]
        for a in range(3):
            gw[g, a] = (Rb[j, a, 0] * gc[g, 0] + Rb[j, a, 1] * gc[g, 1] + Rb[j, a, 2] * gc[g, 2]
                        + pb[j, a])


@njit(cache=True, nogil=True, inline="always")
def _candidates(cap):  # pragma: no cover - compiled
    """Empty :class:`Candidates` for ``cap`` terms."""
    return Candidates(np.empty(cap), np.empty(cap, dtype=np.int64),
                      np.empty(cap, dtype=np.int64), np.empty(cap, dtype=np.int64),
                      np.empty(cap), np.empty((cap, 3)))


@njit(cache=True, nogil=True, inline="always")
def _select(cd, n, C, order):  # pragma: no cover - compiled
    """Indices of the min(C, n) smallest cd[:n] into order; returns how many."""
    m = min(C, n)
    for k in range(m):
        best, bi = np.inf, -1
        for i in range(n):
            if cd[i] < best:
                taken = False
                for kk in range(k):
                    if order[kk] == i:
                        taken = True
                if not taken:
                    best, bi = cd[i], i
        order[k] = bi
    return m


@njit(cache=True, nogil=True, inline="always")
def _sd_along(kind, R, p, size, a0, a1, a2, b0, b1, b2, alpha):  # pragma: no cover - compiled
    """sd(a + α (b - a)), m, of the points a = (a0, a1, a2) and b (scalars: a work array
    allocated per call cost a third of the segment terms' time)."""
    return signed_distance_xyz(kind, R, p, size, a0 + alpha * (b0 - a0),
                               a1 + alpha * (b1 - a1), a2 + alpha * (b2 - a2))


@njit(cache=True, nogil=True)
def _swept_min(kind, R, p, size, a0, a1, a2, b0, b1, b2, iters, above=np.inf
               ):  # pragma: no cover - compiled
    """(min over α ∈ [0, 1] of sd(a + α (b - a)), α*) for the sphere centre moving from a =
    (a0, a1, a2) to b, within :data:`SWEPT_TOLERANCE_M` — or, once the search proves the
    minimum at least ``above`` (m; sd is ``|b - a|``-Lipschitz in α, so no point of a bracket
    lies more than its width times that below its lowest sample), some value ≥ ``above``.
    sd is convex along a line for a convex obstacle, so when it does not descend from an end
    over the first ``e`` of the segment (``e`` |b - a| = the tolerance), no point beyond
    is lower than that end (f(α) ≥ f(0) + (α / e) (f(e) - f(0)); likewise from α = 1) and the
    minimum lies within the tolerance of it, no more than the tolerance lower (sd is
    1-Lipschitz): four evaluations decide most segments, which move a sphere steadily
    towards or away from an obstacle. Otherwise a golden-section search, one new evaluation a
    step (the other interior point is the last step's), at most ``iters`` steps, fewer once
    the bracket spans less than the tolerance of the travel."""
    travel = np.sqrt((b0 - a0) ** 2 + (b1 - a1) ** 2 + (b2 - a2) ** 2)
    e = min(0.5, SWEPT_TOLERANCE_M / max(travel, 1e-300))
    f0 = _sd_along(kind, R, p, size, a0, a1, a2, b0, b1, b2, 0.0)
    if _sd_along(kind, R, p, size, a0, a1, a2, b0, b1, b2, e) >= f0:
        return f0, 0.0
    f_end = _sd_along(kind, R, p, size, a0, a1, a2, b0, b1, b2, 1.0)
    if _sd_along(kind, R, p, size, a0, a1, a2, b0, b1, b2, 1.0 - e) >= f_end:
        return f_end, 1.0
    if 0.5 * (f0 + f_end - travel) >= above:
        return min(f0, f_end), 0.0
    lo, hi = 0.0, 1.0
    m1, m2 = lo + _GOLDEN * (hi - lo), hi - _GOLDEN * (hi - lo)
    f1 = _sd_along(kind, R, p, size, a0, a1, a2, b0, b1, b2, m1)
    f2 = _sd_along(kind, R, p, size, a0, a1, a2, b0, b1, b2, m2)
    for _ in range(iters):
        if (hi - lo) * travel < SWEPT_TOLERANCE_M:
            break
        if min(f1, f2) - (hi - lo) * travel >= above and min(f0, f_end) >= above:
            return min(f0, f_end, f1, f2), 0.5 * (lo + hi)
        if f1 <= f2:   # the minimum is in [lo, m2]: m1 becomes its upper interior point
            hi, m2, f2 = m2, m1, f1
            m1 = lo + _GOLDEN * (hi - lo)
            f1 = _sd_along(kind, R, p, size, a0, a1, a2, b0, b1, b2, m1)
        else:          # in [m1, hi]: m2 becomes its lower interior point
            lo, m1, f1 = m1, m2, f2
            m2 = hi - _GOLDEN * (hi - lo)
            f2 = _sd_along(kind, R, p, size, a0, a1, a2, b0, b1, b2, m2)
    best_a = 0.5 * (lo + hi)
    best = _sd_along(kind, R, p, size, a0, a1, a2, b0, b1, b2, best_a)
    if f0 < best:    # rounding: an end found lower
        best, best_a = f0, 0.0
    if f_end < best:
        best, best_a = f_end, 1.0
    return best, best_a


@njit(cache=True, nogil=True)
def _closest_in_group(kind, R, p, size, g, gstart, sr, cw0, cw1, swept, margin, iters
                      ):  # pragma: no cover - compiled
    """Closest sphere of group g to one obstacle, statically (cw0) or swept (cw0 → cw1):
    (signed distance m, sphere, α*), exact when below ``margin`` (m). A swept sphere is
    searched only when its lower bound (sd at mid-segment − radius − half its travel; sd is
    1-Lipschitz) is below both the margin and the closest found so far, and only until it is
    proved not below them (``_swept_min``'s ``above``). (Searching the spheres in the order
    of their bounds instead saved nothing: 62 searches a segment among 13 pairs, most
    needed.)"""
    best, bs, balpha = np.inf, -1, 0.0
    for s in range(gstart[g], gstart[g + 1]):
        a0, a1, a2 = cw0[s, 0], cw0[s, 1], cw0[s, 2]
        if not swept:
            d = signed_distance_xyz(kind, R, p, size, a0, a1, a2) - sr[s]
            alpha = 0.0
        else:
            b0, b1, b2 = cw1[s, 0], cw1[s, 1], cw1[s, 2]
            half = (b0 - a0) ** 2 + (b1 - a1) ** 2 + (b2 - a2) ** 2
            if signed_distance_xyz(kind, R, p, size, 0.5 * (a0 + b0), 0.5 * (a1 + b1),
                                   0.5 * (a2 + b2)) - sr[s] - 0.5 * np.sqrt(half) \
                    >= min(margin, best):
                continue
            f, alpha = _swept_min(kind, R, p, size, a0, a1, a2, b0, b1, b2, iters,
                                  min(margin, best) + sr[s])
            d = f - sr[s]
        if d < best:
            best, bs, balpha = d, s, alpha
    return best, bs, balpha


@njit(cache=True, nogil=True, inline="always")
def _push(kind, R, p, size, o, src, g, gstart, sr, cw0, cw1, swept, margin, iters, y, nrm, cd,
          cs, co, ck, ca, cn, n):  # pragma: no cover - compiled
    """Push the closest sphere of group g to primitive o (kind, R, p, size: that primitive's;
    source ``src``) when within margin (y, nrm: (3,) work space) into the candidate arrays
    (those of :class:`Candidates`); returns the new count."""
    best, bs, alpha = _closest_in_group(kind, R, p, size, g, gstart, sr, cw0, cw1, swept,
                                        margin, iters)
    if best < margin and n < cd.shape[0]:
        for a in range(3):
            y[a] = cw0[bs, a] + alpha * (cw1[bs, a] - cw0[bs, a])
        signed_distance_normal(kind, R, p, size, y, nrm)
        cd[n], cs[n], co[n], ck[n], ca[n] = best, bs, o, src, alpha
        cn[n, 0], cn[n, 1], cn[n, 2] = nrm[0], nrm[1], nrm[2]
        n += 1
    return n


@njit(cache=True, nogil=True, inline="always")
def _keep_smallest(top, d):  # pragma: no cover - compiled
    """Insert d into top (C,), the C smallest values so far, ascending."""
    k = top.shape[0] - 1
    if d >= top[k]:
        return
    while k > 0 and top[k - 1] > d:
        top[k] = top[k - 1]
        k -= 1
    top[k] = d


@njit(cache=True, nogil=True)
def _obstacle_candidates(margin, world, cw0, cw1, gw0, gw1, swept, iters, cand, C
                         ):  # pragma: no cover - compiled
    """Push into ``cand`` the closest sphere of every (group, obstacle / fixed part) pair that
    is within margin and may be among the C closest; returns how many.

    Each pair gets a lower bound first (sd at the group's centre mid-segment − its radius −
    half its centre's travel: every sphere of the group stays that close to it), those below
    the margin are searched in the order of their bounds, and the search stops at the first
    whose bound is not below the C-th closest found so far (nor is any after it): the C
    closest are those of the full search (compared bit for bit on 214 TrajOpt evaluations of
    shelf_boxes task cases; segment terms 18.3 → 15.5 µs a segment with ``_swept_min``'s
    ``above``). The culling is in the loop itself, and :func:`_push` is called on the few
    pairs that remain: an inlined call binds each array argument anew (counting a reference
    to it), which, per pair, cost 4 times the culling (measured)."""
    # every array, out of the named tuples once (see ``validity.py``'s docstring)
    gstart, gr, sr = world.groups.start, world.groups.radius, world.spheres.radius
    env, fixed = world.obstacles, world.fixed
    ek, eR, ep, es, eb = env.kind, env.R, env.p, env.size, env.bound
    fprims, cl, allowed = fixed.prims, fixed.clusters, fixed.allowed
    fk, fR, fp, fs, fb = fprims.kind, fprims.R, fprims.p, fprims.size, fprims.bound
    clc, clr, cls, clm = cl.centre, cl.radius, cl.start, cl.members
    cd, cs, co, ck, ca, cn = cand
    n_pairs = gr.shape[0] * (ek.shape[0] + fk.shape[0])
    lb, pair = np.empty(n_pairs), np.empty((n_pairs, 3), dtype=np.int64)
    x = np.empty(3)
    y = np.empty(3)
    nrm = np.empty(3)
    m = 0
    for g in range(gr.shape[0]):
        half = 0.0
        for a in range(3):
            x[a] = 0.5 * (gw0[g, a] + gw1[g, a])
            half += (gw1[g, a] - gw0[g, a]) ** 2
        # the group's radius + half the centre's travel (+ margin: its reach, mid-segment)
        slack = gr[g] + 0.5 * np.sqrt(half)
        reach = slack + margin
        for o in range(ek.shape[0]):
            dc = np.sqrt((x[0] - ep[o, 0]) ** 2 + (x[1] - ep[o, 1]) ** 2
                         + (x[2] - ep[o, 2]) ** 2)
            if dc - eb[o] < reach:
                d = signed_distance(ek[o], eR[o], ep[o], es[o], x)
                if d < reach:
                    lb[m], pair[m, 0], pair[m, 1], pair[m, 2] = d - slack, g, o, OBSTACLE
                    m += 1
        for c in range(clc.shape[0]):  # a cluster of fixed robot parts: cull it at once
            dc = np.sqrt((x[0] - clc[c, 0]) ** 2 + (x[1] - clc[c, 1]) ** 2
                         + (x[2] - clc[c, 2]) ** 2)
            if dc - clr[c] >= reach:
                continue
            for k in range(cls[c], cls[c + 1]):
                o = clm[k]
                dc = np.sqrt((x[0] - fp[o, 0]) ** 2 + (x[1] - fp[o, 1]) ** 2
                             + (x[2] - fp[o, 2]) ** 2)
                if allowed[g, o] and dc - fb[o] < reach:
                    d = signed_distance(fk[o], fR[o], fp[o], fs[o], x)
                    if d < reach:
                        lb[m], pair[m, 0], pair[m, 1], pair[m, 2] = d - slack, g, o, FIXED
                        m += 1
    top = np.full(max(C, 1), np.inf)   # the C closest found so far
    n = 0
    for i in np.argsort(lb[:m]):
        cut = min(margin, top[-1])
        if lb[i] >= cut:
            break
        g, o, before = pair[i, 0], pair[i, 1], n
        if pair[i, 2] == OBSTACLE:
            n = _push(ek[o], eR[o], ep[o], es[o], o, OBSTACLE, g, gstart, sr, cw0, cw1, swept,
                      cut, iters, y, nrm, cd, cs, co, ck, ca, cn, n)
        else:
            n = _push(fk[o], fR[o], fp[o], fs[o], o, FIXED, g, gstart, sr, cw0, cw1, swept,
                      cut, iters, y, nrm, cd, cs, co, ck, ca, cn, n)
        if n > before:
            _keep_smallest(top, cd[n - 1])
    return n


@njit(cache=True, nogil=True)
def _self_candidates(q, margin, clear, world, cw, gw, n, cand):  # pragma: no cover - compiled
    """Push the closest sphere pair of each self pair of groups within margin into ``cand``
    (from index n), except a pair whose tabled gap bound at q (``self_table.table_gap``: the
    geometries' own, certified) is at least ``clear`` m; returns the new count."""
    gstart, gr = world.groups.start, world.groups.radius
    self_pairs, sr = world.groups.self_pairs, world.spheres.radius
    tpair, tjoint, tlo, tinv, tgap, tgroup = world.self_tables
    cd, cs, co, ck, ca, cn = cand
    for i in range(self_pairs.shape[0]):
        a, b = self_pairs[i, 0], self_pairs[i, 1]
        if np.sqrt((gw[a, 0] - gw[b, 0]) ** 2 + (gw[a, 1] - gw[b, 1]) ** 2
                   + (gw[a, 2] - gw[b, 2]) ** 2) - gr[a] - gr[b] >= margin:
            continue
        if table_gap(q, i, tpair, tjoint, tlo, tinv, tgap) >= clear:
            continue
        best, bs, bt = np.inf, -1, -1
        for s in range(gstart[a], gstart[a + 1]):
            for u in range(gstart[b], gstart[b + 1]):
                d = np.sqrt((cw[s, 0] - cw[u, 0]) ** 2 + (cw[s, 1] - cw[u, 1]) ** 2
                            + (cw[s, 2] - cw[u, 2]) ** 2) - sr[s] - sr[u]
                if d < best:
                    best, bs, bt = d, s, u
        if best < margin and n < cd.shape[0]:
            nd = np.sqrt((cw[bs, 0] - cw[bt, 0]) ** 2 + (cw[bs, 1] - cw[bt, 1]) ** 2
                         + (cw[bs, 2] - cw[bt, 2]) ** 2)
            cd[n], cs[n], co[n], ck[n], ca[n] = best, bs, bt, SELF, 0.0
            if nd > 1e-12:
                for k in range(3):
                    cn[n, k] = (cw[bs, k] - cw[bt, k]) / nd
            else:
                cn[n] = 0.0
                cn[n, 2] = 1.0
            n += 1
    return n


@njit(cache=True, nogil=True)
def waypoint_terms(Q, margin, clear, C, with_obstacles, dist, grad, world
                   ):  # pragma: no cover - compiled
    """Discrete terms at each waypoint Q[t]: the C closest (group, obstacle / fixed part /
    other group) pairs within ``margin`` (m): dist (T, C) m and grad (T, C, K) m/rad; unused
    slots get dist ``NO_TERM`` and a zero gradient. ``with_obstacles`` False keeps
    self-collision only (when continuous terms already cover the obstacles). A self pair
    whose tabled gap bound is at least ``clear`` (m) is no term."""
    T, K = Q.shape
    chain, spheres, groups = world.chain, world.spheres, world.groups
    parent, R0, p0, axis = chain.parent, chain.R_parent_joint, chain.p_parent_joint, chain.axis
    sc, sj, gc, gj = spheres.centre, spheres.joint, groups.centre, groups.joint
    S, G = sj.shape[0], gc.shape[0]
    Rb = np.empty((K, 3, 3))
    pb = np.empty((K, 3))
    aw = np.empty((K, 3))
    cw = np.empty((S, 3))
    gw = np.empty((G, 3))
    cand = _candidates(G * (world.obstacles.kind.shape[0] + world.fixed.prims.kind.shape[0])
                       + groups.self_pairs.shape[0] + 1)
    cd, cs, co, ck, ca, cn = cand
    order = np.empty(C, dtype=np.int64)
    for t in range(T):
        _centres(Q[t], parent, R0, p0, axis, sc, sj, gc, gj, Rb, pb, cw, gw)
        _world_axes(Rb, axis, aw)
        n = 0
        if with_obstacles:
            n = _obstacle_candidates(margin, world, cw, cw, gw, gw, False, 0, cand, C)
        n = _self_candidates(Q[t], margin, clear, world, cw, gw, n, cand)
        m = _select(cd, n, C, order)
        for k in range(C):
            grad[t, k, :] = 0.0
            if k >= m:
                dist[t, k] = NO_TERM
                continue
            i = order[k]
            s = cs[i]
            dist[t, k] = cd[i]
            _add_point_gradient(cn[i], cw[s], sj[s], parent, aw, pb, 1.0, grad[t, k])
            if ck[i] == SELF:
                u = co[i]
                _add_point_gradient(cn[i], cw[u], sj[u], parent, aw, pb, -1.0, grad[t, k])


@njit(cache=True, nogil=True)
def segment_terms(Q, margin, C, dist, grad0, grad1, iters, world
                  ):  # pragma: no cover - compiled
    """Continuous terms of each segment Q[t] → Q[t+1] against obstacles and fixed robot parts
    (swept spheres): dist (T-1, C) m, grad0 / grad1 (T-1, C, K) m/rad with respect to Q[t] /
    Q[t+1]; unused slots get dist ``NO_TERM`` and zero gradients."""
    T, K = Q.shape
    chain, spheres, groups = world.chain, world.spheres, world.groups
    parent, R0, p0, axis = chain.parent, chain.R_parent_joint, chain.p_parent_joint, chain.axis
    sc, sj, gc, gj = spheres.centre, spheres.joint, groups.centre, groups.joint
    S, G = sj.shape[0], gc.shape[0]
    Rb = np.empty((T, K, 3, 3))
    pb = np.empty((T, K, 3))
    aw = np.empty((T, K, 3))
    cw = np.empty((T, S, 3))
    gw = np.empty((T, G, 3))
    for t in range(T):
        _centres(Q[t], parent, R0, p0, axis, sc, sj, gc, gj, Rb[t], pb[t], cw[t], gw[t])
        _world_axes(Rb[t], axis, aw[t])
    cand = _candidates(G * (world.obstacles.kind.shape[0] + world.fixed.prims.kind.shape[0])
                       + 1)
    cd, cs, co, ck, ca, cn = cand
    order = np.empty(C, dtype=np.int64)
    for t in range(T - 1):
        n = _obstacle_candidates(margin, world, cw[t], cw[t + 1], gw[t], gw[t + 1], True, iters,
                                 cand, C)
        m = _select(cd, n, C, order)
        for k in range(C):
            grad0[t, k, :] = 0.0
            grad1[t, k, :] = 0.0
            if k >= m:
                dist[t, k] = NO_TERM
                continue
            i = order[k]
            s = cs[i]
            al = ca[i]
            dist[t, k] = cd[i]
            _add_point_gradient(cn[i], cw[t, s], sj[s], parent, aw[t], pb[t], 1.0 - al,
                                grad0[t, k])
            _add_point_gradient(cn[i], cw[t + 1, s], sj[s], parent, aw[t + 1],
                                pb[t + 1], al, grad1[t, k])
