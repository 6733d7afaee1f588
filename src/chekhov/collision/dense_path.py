"""The fast checker on a densely interpolated path, with certified skipping.

Checking a path at 100 substeps per segment (the paper's validation) means thousands of nearly
identical configurations. Here each group of spheres (bounding sphere: centre c_g, radius r_g)
gets a clearance certificate when its bounding sphere is clear of everything by a distance d
(from the static and fixed-part distance grids' lower bounds and the exact distances to dynamic
obstacles): since the centre moves by at most D_g = Σ_i |δq_i| L_gi per substep (δq the
substep's joint step, L_gi a bound on the distance from joint i to c_g that holds in every
configuration), the group stays clear for floor(d / D_g) substeps. A group whose bounding
sphere is not clear tries its own spheres: each sphere's centre lies within r_g of c_g, so
moves by at most S_g = Σ_i |δq_i| (L_gi + r_g) per substep, and when every sphere s is clear by
d_s > 0 the group stays clear for floor(min_s d_s / S_g) substeps. A group whose spheres
touch something gets the gap GJK certifies between its covered geometry and each obstacle or
fixed part within reach (beyond its confirmation margin; for the fixed parts, the group's
gap table when one or two joints move it, ``self_table.py``): the covered geometry lies in the
bounding sphere, so it too moves by at most S_g per substep. Near contact, where every
substep used to need the full check, one GJK now covers several substeps: the first answer
on the Panda's task cases went from a median of 7 ms to 4.4-5 ms (A/B, panda_cage and
panda_table_shelf, 60 cases each).

The lever-arm bounds add up the links' offsets along the chain and hold in every
configuration; the distance from a group's centre to each joint's axis *now* is often much
less (an arm bent towards its shoulder). So a group's certificate is the longer of the lever
bound's and this configuration's own (``motion_bounds.clear_for``). On the first answers of
40 task cases a scene (``benchmarks/certify_walk.py``) the walk looked at 35-41% fewer
configurations (tabletop_container 575 → 365 a path, shelf_boxes 1759 → 1134, panda_cage
670 → 432), and the decision's mean time fell in each of 8 old/new pairs run alternately
(four scenes, twice), by 2-34% (this machine is noisy; median 17%).

Self-collision pairs get certificates the same way, but a pair's gap changes only through the
joints between its two groups (below their lowest common joint: the joints above move both
rigidly), so only those joints count: from the bounding spheres' gap, else the pair's table
(``self_table.py``: one or two joints between them), else the smallest gap between their
spheres, else — spheres overlapping, as the Panda's link 5 and fingers did in a
fifth of its configurations with spheres from whole mesh triangles (4% since they are split)
— the gap GJK certifies between the covered geometries beyond
their confirmation margins (:func:`gjk.convex_gap`).

Near obstacles — a hand at a pre-grasp, an elbow beside a shelf — the bounding sphere touches
while the spheres are centimetres clear: on the task cases' certifications, 41% (shelf) to 60%
(Panda cage) of the samples needed the full check with the bounding spheres' certificates
alone. A configuration whose groups and pairs are all certified is free for the fast checker;
any other is checked in full by :func:`validity.collisions`. So the answer is the same as
checking every configuration with the fast checker (a GJK-certified gap is a true one, so at
most a configuration whose confirmation would not have converged could differ, in the free
direction of the truth), at a fraction of the cost. The lever-arm bounds L_gi are
``PackedWorld.groups.lever`` (``packed.lever_arms``).

A timed trajectory's arcs are polylines of short segments, which the walk takes several at a
time as one run (:mod:`chekhov.collision.walk_runs`); how much one compiled call may look at
near a deadline is there too.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from chekhov.collision import packed
from chekhov.collision.codes import NO_GEOMETRY, NONE
from chekhov.collision.kernels import (
    geometry_gap,
    grid_cell,
    obstacle_gap,
    place_geometry,
    signed_distance,
)
from chekhov.collision.motion_bounds import clear_for, curvature
from chekhov.collision.self_table import table_gap
from chekhov.collision.validity import NO_BUDGET, collisions, make_work
from chekhov.collision.walk_runs import run_end
from chekhov.robot.chain_kinematics import chain_fk_arrays


class WalkWork(NamedTuple):
    """Work arrays of :func:`_walk`: until (G,) / puntil (P,) int64, the last substep each
    group / self pair is certified free to; step_len (G,) m, the most a group's centre moves
    in one substep, and sphere_step (G,) m the most any of its spheres' centres does;
    pair_step / pair_sphere_step (P,) m the same for self pair k's two groups *relative to
    each other* (only the joints between them count); q (K,); Rc (K, 3, 3), pc (K, 3),
    gwc (G, 3): joint poses and group centres; swc (S, 3) sphere centres, valid for the
    substep in swc_at (G,) int64 (per group); mark (K,) bool, Rw (2, 3, 3), pw (2, 3),
    cw (2, 3) work space; budget (2,) int64: the configurations :func:`_walk` may still look
    at (those not covered by certificates) and, when it ran out, the next one it would have
    looked at (-1: it did not run out); dq (K,) rad, the most each joint turns in one substep
    of the run, and curve (G, 2) m, the second-order terms of ``motion_bounds.clear_for`` for
    a group's centre and for its spheres."""

    until: np.ndarray
    puntil: np.ndarray
    step_len: np.ndarray
    sphere_step: np.ndarray
    pair_step: np.ndarray
    pair_sphere_step: np.ndarray
    q: np.ndarray
    Rc: np.ndarray
    pc: np.ndarray
    gwc: np.ndarray
    swc: np.ndarray
    swc_at: np.ndarray
    mark: np.ndarray
    Rw: np.ndarray
    pw: np.ndarray
    cw: np.ndarray
    budget: np.ndarray
    dq: np.ndarray
    curve: np.ndarray


@njit(cache=True, nogil=True, inline="always")
def _grid_lower_bound(origin, inv_h, h, delta, values, m, c):  # pragma: no cover - compiled
    """A lower bound on the distance (m) from point c to the primitives of grid m of the stack
    ``values``; -inf outside the grid. See :func:`kernels.grid_classify` for the bound."""
    q, e = grid_cell(origin, inv_h, h, values, m, c)
    return -np.inf if q < 0 else q * delta - e


@njit(cache=True, nogil=True, inline="always")
def _group_centres(q, parent, R0, p0, axis, gc, gj, Rc, pc, gwc):  # pragma: no cover - compiled
    """World centre gwc[g] of each group's bounding sphere (centre gc[g] on joint gj[g]) at q
    (runs the chain FK)."""
    chain_fk_arrays(q, parent, R0, p0, axis, Rc, pc)
    for g in range(gc.shape[0]):
        j = gj[g]
        for a in range(3):
            gwc[g, a] = (Rc[j, a, 0] * gc[g, 0] + Rc[j, a, 1] * gc[g, 1]
                         + Rc[j, a, 2] * gc[g, 2] + pc[j, a])


@njit(cache=True, nogil=True, inline="always")
def _point_clearance(origin, ih, h, delta, V, fix, dk, dR, dp, ds, c):  # pragma: no cover
    """A lower bound (m) on the distance from point c to the static obstacles, the fixed
    robot part grid ``fix`` (-1: none) and the dynamic obstacles (exact)."""
    d = _grid_lower_bound(origin, ih, h, delta, V, 0, c)
    if fix >= 0:
        d = min(d, _grid_lower_bound(origin, ih, h, delta, V, fix, c))
    for o in range(dk.shape[0]):
        d = min(d, signed_distance(dk[o], dR[o], dp[o], ds[o], c))
    return d


@njit(cache=True, nogil=True, inline="always")
def _sphere_centres(g, m, start, sc, sj, Rc, pc, swc, swc_at):  # pragma: no cover - compiled
    """World centres swc of group g's spheres at substep m (once per substep and group; the
    joint poses Rc, pc must be those of substep m)."""
    if swc_at[g] == m:
        return
    swc_at[g] = m
    for s in range(start[g], start[g + 1]):
        j = sj[s]
        for a in range(3):
            swc[s, a] = (Rc[j, a, 0] * sc[s, 0] + Rc[j, a, 1] * sc[s, 1]
                         + Rc[j, a, 2] * sc[s, 2] + pc[j, a])


@njit(cache=True, nogil=True, inline="always")
def _pair_gap(start, sr, swc, a, b):  # pragma: no cover - compiled
    """The smallest gap (m) between a sphere of group a and one of group b (≤ 0: overlap)."""
    gap = np.inf
    for s in range(start[a], start[a + 1]):
        for t in range(start[b], start[b + 1]):
            d = np.sqrt((swc[s, 0] - swc[t, 0]) ** 2 + (swc[s, 1] - swc[t, 1]) ** 2
                        + (swc[s, 2] - swc[t, 2]) ** 2) - sr[s] - sr[t]
            gap = min(gap, d)
            if gap <= 0.0:
                return gap
    return gap


@njit(cache=True, nogil=True, inline="always")
def _relative_steps(dq, a, b, parent, gj, gr, lever, mark, pair_step, pair_sphere_step, k
                    ):  # pragma: no cover - compiled
    """pair_step[k] / pair_sphere_step[k] (m): the most group b's centre / any point within
    r_b of it moves relative to group a's (and a's relative to their common ancestor) in one
    substep that turns each joint i by at most dq[i] (rad): only the joints below the groups'
    lowest common joint count, each by dq_i times its lever (plus the group's radius). A
    joint that moves both groups moves them rigidly together and leaves their gaps as they
    are."""
    for i in range(mark.shape[0]):
        mark[i] = False
    i = gj[a]
    while i >= 0:
        mark[i] = True
        i = parent[i]
    centre = 0.0
    sphere = 0.0
    i = gj[b]
    while i >= 0 and not mark[i]:
        centre += dq[i] * lever[b, i]
        sphere += dq[i] * (lever[b, i] + gr[b])
        i = parent[i]
    common = i
    i = gj[a]
    while i != common:
        centre += dq[i] * lever[a, i]
        sphere += dq[i] * (lever[a, i] + gr[a])
        i = parent[i]
    pair_step[k] = centre + 1e-12
    pair_sphere_step[k] = sphere + 1e-12


GAP_LOOK = 8
"""Substeps of relative motion a self pair's geometry gap is asked to cover (beyond the
confirmation margins) when GJK measures it: a farther target costs more GJK iterations."""


@njit(cache=True, nogil=True)
def _walk(P, t0, t1, n, m_first, m_last, check_ends, world, work, ww
          ):  # pragma: no cover - compiled
    """Configurations m = m_first … m_last of the run of segments P[t0] → … → P[t1] of P
    (T, K), n substeps a segment: configuration m is P[t] + (r / n)(P[t + 1] - P[t]),
    t = t0 + m // n, r = m % n (m = (t1 - t0) n: P[t1]); in order: the first m the fast
    checker calls colliding, or ``NONE``. Clearance certificates skip the rest (see the
    module docstring), counted in substeps that turn each joint i by at most dq_i, the
    largest |P[t + 1, i] - P[t, i]| / n of the run: the lever and local bounds
    (``motion_bounds``) need no more of a substep, so certificates hold across the run's
    knots. With ``check_ends`` False, the run's first and last configurations only give
    certificates. ``work``: a ``validity.Work``; ``ww``: a :class:`WalkWork`. Each
    configuration looked at takes one from ``ww.budget[0]``; when none is left before
    m_last, ``NONE`` with the next m in ``ww.budget[1]`` (the walk is to resume there)."""
    K = P.shape[1]
    m_end = (t1 - t0) * n
    # every array, out of the named tuples once (see ``validity.py``'s docstring)
    chain, groups, grids, dyn = world.chain, world.groups, world.grids, world.dynamic
    parent, R0, p0, axis = chain.parent, chain.R_parent_joint, chain.p_parent_joint, chain.axis
    gc, gj, gr, lever = groups.centre, groups.joint, groups.radius, groups.lever
    start, sc, sr, sj = groups.start, world.spheres.centre, world.spheres.radius, \
        world.spheres.joint
    self_pairs = groups.self_pairs
    origin, h, ih, delta, V, gfix = (grids.origin, grids.h, grids.inv_h, grids.delta,
                                     grids.fine, grids.fixed)
    dk, dR, dp, ds = dyn.kind, dyn.R, dyn.p, dyn.size
    (until, puntil, step_len, sphere_step, pair_step, pair_sphere_step, q, Rc, pc, gwc, swc,
     swc_at, mark, Rw, pw, cw, budget, dq, curve) = ww
    geo = world.geometry
    tpair, tjoint, tlo, tinv, tgap, tgroup = world.self_tables
    st, fixed = world.static, world.fixed
    sk, sR, sp, ss = st.kind, st.R, st.p, st.size
    fk, fR, fp, fs = fixed.prims.kind, fixed.prims.R, fixed.prims.p, fixed.prims.size
    fck, fvs, fV, fcen, fallow = (fixed.hull_kind, fixed.vert_start, fixed.verts,
                                  fixed.centre, fixed.allowed)
    gk, gR, gp, gsize, gpad = geo.kind, geo.R, geo.p, geo.size, geo.pad
    pstart, vstart, hv, hcen = geo.part_start, geo.vert_start, geo.verts, geo.part_centre
    hrad = geo.part_radius
    no_v, no_vs = np.empty((0, 3)), np.empty(0, dtype=np.int64)
    all_static = np.ones(sk.shape[0], dtype=np.bool_)
    all_dynamic = np.ones(dk.shape[0], dtype=np.bool_)
    q_row = q.reshape((1, K))   # q, as the one row validity.collisions checks
    hit = np.empty(1, dtype=np.bool_)
    G = gr.shape[0]
    for i in range(K):
        dq[i] = 0.0
        for t in range(t0, t1):
            dq[i] = max(dq[i], abs(P[t + 1, i] - P[t, i]))
        dq[i] /= max(n, 1)
    for g in range(G):
        curvature(g, dq, parent, gj, gr, lever, curve)
        until[g] = -1
        swc_at[g] = -1
        s_ = 0.0
        for i in range(K):
            s_ += dq[i] * lever[g, i]
        step_len[g] = s_ + 1e-12
        r_ = 0.0
        i = gj[g]
        while i >= 0:   # the joints that move the group, each by at most its lever + r_g
            r_ += dq[i] * (lever[g, i] + gr[g])
            i = parent[i]
        sphere_step[g] = r_ + 1e-12
    for k in range(self_pairs.shape[0]):
        puntil[k] = -1
        _relative_steps(dq, self_pairs[k, 0], self_pairs[k, 1], parent, gj, gr, lever, mark,
                        pair_step, pair_sphere_step, k)
    for m in range(m_first, m_last + 1):
        t = t0 + m // n if n > 0 else t0
        if t >= t1:
            for i in range(K):
                q[i] = P[t1, i]
        else:
            r = (m - (t - t0) * n) / n
            for i in range(K):
                q[i] = P[t, i] + r * (P[t + 1, i] - P[t, i])
        chain_needed = True
        need_full = False
        for g in range(G):
            if until[g] >= m:
                continue
            if chain_needed:
                _group_centres(q, parent, R0, p0, axis, gc, gj, Rc, pc, gwc)
                chain_needed = False
            # a lower bound on the clearance of g's bounding sphere, then of its spheres
            d = _point_clearance(origin, ih, h, delta, V, gfix[g], dk, dR, dp, ds, gwc[g]) \
                - gr[g]
            if d > 0.0:
                until[g] = m + clear_for(d, g, 0.0, curve[g, 0], step_len[g], dq, parent,
                                          gj, axis, Rc, pc, gwc)
                continue
            _sphere_centres(g, m, start, sc, sj, Rc, pc, swc, swc_at)
            d = np.inf
            for s in range(start[g], start[g + 1]):
                d = min(d, _point_clearance(origin, ih, h, delta, V, gfix[g], dk, dR, dp, ds,
                                            swc[s]) - sr[s])
                if d <= 0.0:
                    break
            if d <= 0.0 and gk[g] != NO_GEOMETRY:
                # spheres touching: the covered geometry's gap to what is near, past its pad
                place_geometry(Rc, pc, gj, gR, gp, g, Rw[0], pw[0])
                # static obstacles, then dynamic ones, then fixed parts, while none is near
                d = obstacle_gap(g, gwc[g], gr[g], gpad[g] + GAP_LOOK * sphere_step[g], False,
                                 sk, sR, sp, ss, sk, no_v, no_vs, sp, all_static, gk, gsize,
                                 pstart, vstart, hv, hcen, hrad, Rw[0], pw[0], cw[0])
                if d > gpad[g] and dk.shape[0] > 0:
                    d = obstacle_gap(g, gwc[g], gr[g], d, False, dk, dR, dp, ds, dk, no_v,
                                     no_vs, dp, all_dynamic, gk, gsize, pstart, vstart, hv,
                                     hcen, hrad, Rw[0], pw[0], cw[0])
                if d > gpad[g] and gfix[g] >= 0:
                    # the fixed parts: the group's table (a bound at q), else GJK
                    e = table_gap(q, g, tgroup, tjoint, tlo, tinv, tgap)
                    if e > gpad[g] + GAP_LOOK * sphere_step[g]:
                        d = min(d, e)
                    else:
                        d = obstacle_gap(g, gwc[g], gr[g], d, False, fk, fR, fp, fs, fck, fV,
                                         fvs, fcen, fallow[g], gk, gsize, pstart, vstart, hv,
                                         hcen, hrad, Rw[0], pw[0], cw[0])
                d -= gpad[g]
            if d > 0.0:
                until[g] = m + clear_for(d, g, gr[g], curve[g, 1], sphere_step[g], dq, parent,
                                          gj, axis, Rc, pc, gwc)
            else:
                need_full = True
        for k in range(self_pairs.shape[0]):
            if puntil[k] >= m:
                continue
            a = self_pairs[k, 0]
            b = self_pairs[k, 1]
            if chain_needed:
                _group_centres(q, parent, R0, p0, axis, gc, gj, Rc, pc, gwc)
                chain_needed = False
            d = np.sqrt((gwc[a, 0] - gwc[b, 0]) ** 2 + (gwc[a, 1] - gwc[b, 1]) ** 2
                        + (gwc[a, 2] - gwc[b, 2]) ** 2) - gr[a] - gr[b]
            if d > 0.0:
                puntil[k] = m + int(d / pair_step[k])
                continue
            # the pair's table: a gap bound over q's cell (one lookup, past the pads)
            d = table_gap(q, k, tpair, tjoint, tlo, tinv, tgap) - gpad[a] - gpad[b]
            if d > 0.0:
                puntil[k] = m + int(d / pair_sphere_step[k])
                continue
            _sphere_centres(a, m, start, sc, sj, Rc, pc, swc, swc_at)
            _sphere_centres(b, m, start, sc, sj, Rc, pc, swc, swc_at)
            d = _pair_gap(start, sr, swc, a, b)
            if d <= 0.0:   # overlapping spheres: the covered geometries' gap, past the pads
                pads = gpad[a] + gpad[b]
                look = pads + GAP_LOOK * pair_sphere_step[k]
                d = geometry_gap(geo, gj, Rc, pc, a, b, look, look, Rw, pw, cw) - pads
            if d > 0.0:
                puntil[k] = m + int(d / pair_sphere_step[k])
            else:
                need_full = True
        if need_full and (check_ends or 0 < m < m_end) \
                and collisions(q_row, world, work, hit, True) != NONE:
            return m
        if not chain_needed:   # m was looked at
            budget[0] -= 1
            if budget[0] <= 0 and m < m_last:
                budget[1] = m + 1
                return NONE
    return NONE


@njit(cache=True, nogil=True)
def make_walk_work(K, world):  # pragma: no cover - compiled
    """A :class:`WalkWork` for ``world`` and K joints."""
    G = world.groups.radius.shape[0]
    S = world.spheres.radius.shape[0]
    P = world.groups.self_pairs.shape[0]
    return WalkWork(np.empty(G, dtype=np.int64), np.empty(P, dtype=np.int64), np.empty(G),
                    np.empty(G), np.empty(P), np.empty(P), np.empty(K), np.empty((K, 3, 3)),
                    np.empty((K, 3)), np.empty((G, 3)), np.empty((S, 3)),
                    np.empty(G, dtype=np.int64), np.empty(K, dtype=np.bool_),
                    np.empty((2, 3, 3)), np.empty((2, 3)), np.empty((2, 3)),
                    np.array([NO_BUDGET, -1]), np.empty(K), np.empty((G, 2)))


@njit(cache=True, nogil=True, inline="always")
def with_margin(world, pad, grow):  # pragma: no cover - compiled
    """``world`` with group g's confirmation margin (``GroupGeometry.pad``) at least pad[g]
    and its spheres' and bounding sphere's radii grow[g] larger (m, (G,) each): a
    configuration it calls free has each group's geometry either cleared by the spheres (so
    at least the spheres' padding plus grow[g] from everything) or proved more than pad[g]
    from it (pad[a] + pad[b] from another group b)."""
    geo, sph, grp = world.geometry, world.spheres, world.groups
    radius = sph.radius.copy()
    for g in range(grow.shape[0]):
        for s in range(grp.start[g], grp.start[g + 1]):
            radius[s] += grow[g]
    geometry = packed.GroupGeometry(geo.kind, geo.R, geo.p, geo.size, np.maximum(geo.pad, pad),
                                    geo.part_start, geo.vert_start, geo.verts, geo.part_centre,
                                    geo.part_radius)
    spheres = packed.Spheres(sph.centre, radius, sph.joint, sph.inner)
    groups = packed.Groups(grp.start, grp.centre, grp.radius + grow, grp.joint, grp.lever,
                           grp.self_pairs)
    return packed.PackedWorld(world.chain, spheres, groups, geometry, world.fixed, world.grids,
                              world.static, world.dynamic, world.obstacles, world.self_tables)


@njit(cache=True, nogil=True)
def first_dense_collision(P, substeps, start, visits, pad, grow, world
                          ):  # pragma: no cover - compiled
    """(i, resume): i the index (>= ``start``) of the first configuration of the densified
    path that the fast checker calls colliding, or ``NONE``. The densified path has
    ``substeps`` configurations between each pair of waypoints of P (T, K), waypoints
    included (the order of :func:`exact.densify`); configurations before index ``start`` are
    not looked at. At most ``visits`` configurations are looked at (those certificates do not
    cover; the cost of a call near contact, where the clock cannot be looked at): when they
    run out first, i is ``NONE`` and ``resume`` the index to call again from (-1: the whole
    path was decided). With ``pad`` and ``grow`` (G,) m, in ``with_margin(world, pad,
    grow)``; empty: in ``world``."""
    if pad.shape[0] > 0:
        world = with_margin(world, pad, grow)
    T, K = P.shape
    work = make_work(K, world)
    ww = make_walk_work(K, world)
    ww.budget[0] = visits
    n = substeps + 1
    t = start // n
    m_first = start - t * n
    while t < T - 1:
        t1 = run_end(P, t, T - 1, n, ww.dq)
        m = _walk(P, t, t1, n, m_first, (t1 - t) * n - 1, True, world, work, ww)
        if m >= 0:
            return t * n + m, -1
        if ww.budget[1] >= 0:
            return NONE, t * n + ww.budget[1]
        if ww.budget[0] <= 0 and t1 < T - 1:   # ran out at a run's end
            return NONE, t1 * n
        t = t1
        m_first = 0
    if start > (T - 1) * n:
        return NONE, -1
    m = _walk(P, T - 1, T - 1, 0, 0, 0, True, world, work, ww)
    return ((T - 1) * n if m >= 0 else NONE), -1
