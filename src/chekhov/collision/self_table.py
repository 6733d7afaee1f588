"""Self-collision tables: a gap bound per cell of one or two joints, for the group pairs whose
relative pose only those joints change (a wrist link and the hand, a forearm and the wrist).

A pair of sphere groups whose geometries move relative to each other through one or two joints
only (the joints that move one group and not the other: the symmetric difference of their
ancestors) is, on a random configuration, often close (the Panda's link 5 and hand spheres
overlapped on about a fifth of all configurations while its mesh spheres were clustered from
whole triangles; on 4% since they come from split ones, ``spheres.split_triangles``), so the
fast checker confirmed it on the covered geometry (GJK on the hulls) nearly every time: 60% of
the Panda's check time then. The
pair's gap is a function of those joints alone, so it is tabulated once per robot over a grid
of :data:`CELLS` cells a joint: each cell holds a certified lower bound on the distance
between the two geometries for every configuration in it — the GJK bound (``gjk.convex_gap``;
where the bound at the first point of A − B near the origin proves nothing, converged: that
first bound was 2-6 cm below the distance on most of the Panda's near cells) at the cell's
centre less the most the geometries can move relative to each other within the cell (each
joint's half width times a bound on the distance of the moved group's points from its axis:
``Groups.lever`` plus the group's radius) — floored to :data:`QUANTUM_M`. A pair whose
cell bound exceeds its confirmation margin (``GroupGeometry.pad``, read at run time, so
a world with larger margins stays sound) is free with one lookup; otherwise it is checked as
before. Units: rad, m.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

from chekhov.collision.codes import NO_GEOMETRY, NONE
from chekhov.collision.kernels import geometry_gap, obstacle_gap, place_geometry
from chekhov.robot.chain_kinematics import KinematicChain, chain_fk
from chekhov.robot.robot import Robot

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

CELLS = 128
"""Cells a joint: at the Panda's wrist (joint ranges 3.8 and 5.9 rad, levers about 0.2 m)
a cell's motion bound is about 6 mm."""
QUANTUM_M = 1e-3
"""m, the unit of the stored bounds (floored; 255 = 25.5 cm or more)."""
REACH_M = 0.26
"""m, how far past a cell's motion bound GJK is asked to prove the gap (the cap stored)."""


class SelfTables(NamedTuple):
    """The tables of a robot's self pairs and of its groups against its fixed parts (T
    tables, P pairs, G groups).

    pair (P,) int64: the table of self pair i (``Groups.self_pairs``), ``NONE`` for none;
    joint (T, 2) int64: the joints a table is indexed by (the second ``NONE`` for one);
    lo (T, 2) rad: their lower limits; inv_w (T, 2): cells per rad; gap (T, CELLS, CELLS)
    uint8: the lower bound on the gap over each cell, in :data:`QUANTUM_M` (one-joint tables
    use column 0); group (G,) int64: the table of group g against every fixed part it is
    checked with (``FixedParts.allowed``), ``NONE`` for none."""

    pair: IntArray
    joint: IntArray
    lo: Array
    inv_w: Array
    gap: NDArray[np.uint8]
    group: IntArray


def no_tables(n_pairs: int, n_groups: int) -> SelfTables:
    """Tables for none of ``n_pairs`` pairs and ``n_groups`` groups."""
    return SelfTables(np.full(n_pairs, NONE, dtype=np.int64), np.zeros((0, 2), dtype=np.int64),
                      np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 1, 1), dtype=np.uint8),
                      np.full(n_groups, NONE, dtype=np.int64))


@njit(cache=True, nogil=True, inline="always")
def table_gap(q, i, pair, joint, lo, inv_w, gap):  # pragma: no cover - compiled
    """The tabled lower bound (m) on self pair i's gap at q (K,), or -1 (no table, or q
    outside the table's joint limits)."""
    t = pair[i]
    if t < 0:
        return -1.0
    n = gap.shape[1]
    x = (q[joint[t, 0]] - lo[t, 0]) * inv_w[t, 0]
    if not (x >= 0.0 and x < n):
        return -1.0
    y = 0.0
    j1 = joint[t, 1]
    if j1 >= 0:
        y = (q[j1] - lo[t, 1]) * inv_w[t, 1]
        if not (y >= 0.0 and y < n):
            return -1.0
    return gap[t, int(x), int(y)] * QUANTUM_M


def robot_self_tables(robot: Robot, chain: KinematicChain, groups: Any, geometry: Any,
                      fixed: Any, key: bytes) -> SelfTables:
    """:func:`build_self_tables` for ``robot``, kept in ``robot.caches`` under ``key`` (the
    sphere model's bytes: checkers of one robot and cover share them, and its fixed parts
    depend on the robot and cover alone; 0.1-0.5 s to build)."""
    cache = robot.caches.setdefault("self_tables", {})
    assert isinstance(cache, dict)
    if key not in cache:
        cache[key] = build_self_tables(chain, robot.lower, robot.upper, groups, geometry, fixed)
    tables = cache[key]
    assert isinstance(tables, SelfTables)
    return tables


def _ancestors(parent: IntArray, j: int) -> set[int]:
    out = set()
    while j >= 0:
        out.add(j)
        j = int(parent[j])
    return out


def build_self_tables(chain: KinematicChain, lower: Array, upper: Array, groups: Any,
                      geometry: Any, fixed: Any) -> SelfTables:
    """Tables for the self pairs of ``groups`` (a ``packed.Groups``; typed Any here, as
    ``packed`` imports this module) whose relative pose depends on one or two joints with
    finite limits (``lower``, ``upper``: (K,) rad), both with covered geometry
    (``packed.GroupGeometry``); and for each group with covered geometry that one or two
    joints move (all its joints: the fixed parts do not move), against the fixed parts
    (``packed.FixedParts``) it is checked with — a TIAGo's upper arm beside its torso, 2 cm
    from it in nearly every configuration, was confirmed by GJK on every check."""
    parent = chain.parent
    gj, gr, lever, pairs = groups.joint, groups.radius, groups.lever, groups.self_pairs
    pair_t = np.full(len(pairs), NONE, dtype=np.int64)
    group_t = np.full(len(gj), NONE, dtype=np.int64)
    rows: list[tuple[int, int, list[int], list[float]]] = []

    def tabled(joints: list[int], *kinds: int) -> bool:
        return 1 <= len(joints) <= 2 and NO_GEOMETRY not in kinds and all(
            np.isfinite([lower[j], upper[j]]).all() for j in joints)

    for i, (a, b) in enumerate(pairs):
        anc_a, anc_b = _ancestors(parent, int(gj[a])), _ancestors(parent, int(gj[b]))
        joints = sorted(anc_a ^ anc_b)
        if not tabled(joints, geometry.kind[a], geometry.kind[b]):
            continue
        # how far the moved group's points can be from each joint's axis (m)
        arm = [float(lever[b, j] + gr[b]) if j in anc_b else float(lever[a, j] + gr[a])
               for j in joints]
        pair_t[i] = len(rows)
        rows.append((int(a), int(b), joints, arm))
    for g in range(len(gj)):
        joints = sorted(_ancestors(parent, int(gj[g])))
        if tabled(joints, geometry.kind[g]) and fixed.allowed[g].any():
            group_t[g] = len(rows)
            rows.append((g, NONE, joints, [float(lever[g, j] + gr[g]) for j in joints]))
    T = len(rows)
    joint = np.full((T, 2), NONE, dtype=np.int64)
    lo, inv_w, arms = np.zeros((T, 2)), np.ones((T, 2)), np.zeros((T, 2))
    ab = np.zeros((T, 2), dtype=np.int64)
    for t, (a, b, joints, arm) in enumerate(rows):
        ab[t] = a, b
        for c, (j, r) in enumerate(zip(joints, arm, strict=True)):
            joint[t, c], lo[t, c], arms[t, c] = j, lower[j], r
            inv_w[t, c] = CELLS / max(float(upper[j] - lower[j]), 1e-9)
    q_ref = np.clip(np.zeros(len(lower)), lower, upper)
    gap = np.zeros((T, CELLS, CELLS), dtype=np.uint8)
    _fill(q_ref, joint, lo, inv_w, arms, ab, chain, gj, groups.centre, gr, geometry, fixed, gap)
    return SelfTables(pair_t, joint, lo, inv_w, gap, group_t)


@njit(cache=True, nogil=True)
def _fill(q_ref, joint, lo, inv_w, arms, ab, chain, gj, gc, gr, geometry, fixed,
          gap):  # pragma: no cover - compiled
    """Each table's cells: the GJK bound at the centre (converged where the first one
    proves nothing) less the cell's motion bound. A table of a group against the fixed
    parts (ab[t, 1] ``NONE``) bounds its geometry's gap to every part it is checked with."""
    K = q_ref.shape[0]
    Rb, pb = np.empty((K, 3, 3)), np.empty((K, 3))
    Rw, pw, cw = np.empty((2, 3, 3)), np.empty((2, 3)), np.empty((2, 3))
    c = np.empty(3)
    q = q_ref.copy()
    n = gap.shape[1]
    for t in range(joint.shape[0]):
        j0, j1 = joint[t, 0], joint[t, 1]
        bound = 0.5 * arms[t, 0] / inv_w[t, 0]
        if j1 >= 0:
            bound += 0.5 * arms[t, 1] / inv_w[t, 1]
        for x in range(n):
            q[j0] = lo[t, 0] + (x + 0.5) / inv_w[t, 0]
            for y in range(n if j1 >= 0 else 1):
                if j1 >= 0:
                    q[j1] = lo[t, 1] + (y + 0.5) / inv_w[t, 1]
                chain_fk(q, chain, Rb, pb)
                cap = REACH_M + bound
                d = _cell_gap(Rb, pb, gj, gc, gr, geometry, fixed, ab[t, 0], ab[t, 1], cap,
                              False, Rw, pw, cw, c)
                if d < bound + QUANTUM_M:   # the first near point's bound: converge
                    d = _cell_gap(Rb, pb, gj, gc, gr, geometry, fixed, ab[t, 0], ab[t, 1], cap,
                                  True, Rw, pw, cw, c)
                v = np.floor((d - bound) / QUANTUM_M)
                gap[t, x, y] = np.uint8(min(max(v, 0.0), 255.0))
        q[:] = q_ref


@njit(cache=True, nogil=True, inline="always")
def _cell_gap(Rb, pb, gj, gc, gr, geo, fixed, a, b, cap, converge, Rw, pw, cw, c
              ):  # pragma: no cover - compiled
    """A certified lower bound (m, at most ``cap``) on the gap between groups a and b's
    geometries, or (b ``NONE``) between group a's and the fixed parts it is checked with, at
    the joint poses Rb, pb; GJK converged with ``converge``, else stopped at a first near
    point."""
    if b >= 0:
        return geometry_gap(geo, gj, Rb, pb, a, b, cap, -1.0 if converge else cap, Rw, pw, cw)
    j = gj[a]
    for x in range(3):
        c[x] = Rb[j, x, 0] * gc[a, 0] + Rb[j, x, 1] * gc[a, 1] + Rb[j, x, 2] * gc[a, 2] + pb[j, x]
    place_geometry(Rb, pb, gj, geo.R, geo.p, a, Rw[0], pw[0])
    pr = fixed.prims
    return obstacle_gap(a, c, gr[a], cap, converge, pr.kind, pr.R, pr.p, pr.size,
                        fixed.hull_kind, fixed.verts, fixed.vert_start, fixed.centre,
                        fixed.allowed[a], geo.kind, geo.size, geo.part_start, geo.vert_start,
                        geo.verts, geo.part_centre, geo.part_radius, Rw[0], pw[0], cw[0])
