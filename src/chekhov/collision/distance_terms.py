"""Signed-distance terms of a whole trajectory and their joint-space gradients, for the optimiser.

For each waypoint (discrete terms) and each segment between waypoints (continuous terms) the
kernels return the C closest (link group, obstacle) pairs within a margin: their signed distance
(m) and its gradient with respect to the joint angles (m/rad), through the Jacobian of the
sphere centre that realises the distance (d sd / dq = nᵀ J_c(q)).

Continuous terms follow TrajOpt's swept-volume idea for spheres: the sphere swept between its
centres c₀ (at q_t) and c₁ (at q_{t+1}) is the capsule ∪_α sphere(c₀ + α (c₁ - c₀)). Its signed
distance to a convex obstacle is min_α sd(c(α)) - r, a convex problem in α (golden-section
search); at the minimiser α*, the gradient splits as (1 - α*) nᵀ J_c(q_t) and α* nᵀ J_c(q_{t+1}).

All kernels read the packed arrays of :meth:`FastChecker._exact_args` (exact primitives, no
grids): chain, spheres, groups, env obstacles, fixed robot parts, fixed pairs, self pairs.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np
from numba import njit
from numpy.typing import NDArray

from chekhov.collision.kernels import (
    chain_fk,
    signed_distance,
    signed_distance_normal,
)
from chekhov.collision.primitives import bounding_radius
from chekhov.errors import DeadlineError

if TYPE_CHECKING:
    from chekhov.collision.fast import FastChecker

Array = NDArray[np.float64]

DEADLINE_CHUNK_S = 5e-4
"""s: work per compiled call when a deadline is to be kept (the first call takes one segment,
the next ones as many as the time per segment so far says fit, at most twice the last and
:data:`DEADLINE_CHUNK_MAX`: segments of one path differ in cost by 30x and more)."""
DEADLINE_CHUNK_MAX = 2

_GOLDEN = 0.3819660112501051
_NO_TERM = 1e3  # distance written to unused slots (m): the hinge is zero there


@njit(cache=True, inline="always")
def _world_axes(Rb, axis, out):  # pragma: no cover - compiled
    for k in range(axis.shape[0]):
        for a in range(3):
            out[k, a] = (Rb[k, a, 0] * axis[k, 0] + Rb[k, a, 1] * axis[k, 1]
                         + Rb[k, a, 2] * axis[k, 2])


@njit(cache=True, inline="always")
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


@njit(cache=True, inline="always")
def _centres(q, chain, sc, sj, gc, gj, Rb, pb, cw, gw):  # pragma: no cover - compiled
    chain_fk(q, chain[0], chain[1], chain[2], chain[3], Rb, pb)
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


@njit(cache=True, inline="always")
def _candidates(cap):  # pragma: no cover - compiled
    """Empty candidate arrays for ``cap`` terms: distance, sphere, other, kind, α, normal."""
    return (np.empty(cap), np.empty(cap, dtype=np.int64), np.empty(cap, dtype=np.int64),
            np.empty(cap, dtype=np.int64), np.empty(cap), np.empty((cap, 3)))


@njit(cache=True, inline="always")
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


@njit(cache=True)
def _swept_min(kind, R, p, size, c0, c1, iters):  # pragma: no cover - compiled
    """(min over α ∈ [0, 1] of sd(c0 + α (c1 - c0)), α*): golden-section search (sd is convex
    along a line for a convex obstacle), ends included."""
    x = np.empty(3)
    lo, hi = 0.0, 1.0
    for _ in range(iters):
        m1 = lo + _GOLDEN * (hi - lo)
        m2 = hi - _GOLDEN * (hi - lo)
        for a in range(3):
            x[a] = c0[a] + m1 * (c1[a] - c0[a])
        f1 = signed_distance(kind, R, p, size, x)
        for a in range(3):
            x[a] = c0[a] + m2 * (c1[a] - c0[a])
        f2 = signed_distance(kind, R, p, size, x)
        if f1 <= f2:
            hi = m2
        else:
            lo = m1
    best_a = 0.5 * (lo + hi)
    for a in range(3):
        x[a] = c0[a] + best_a * (c1[a] - c0[a])
    best = signed_distance(kind, R, p, size, x)
    for a_end in (0.0, 1.0):  # the minimum may sit at an end (flat or monotone sd)
        for a in range(3):
            x[a] = c0[a] + a_end * (c1[a] - c0[a])
        f = signed_distance(kind, R, p, size, x)
        if f < best:
            best, best_a = f, a_end
    return best, best_a


@njit(cache=True)
def _closest_in_group(kind, R, p, size, g, gstart, sr, cw0, cw1, swept, margin, iters
                      ):  # pragma: no cover - compiled
    """Closest sphere of group g to one obstacle, statically (cw0) or swept (cw0 → cw1):
    (signed distance m, sphere, α*)."""
    best, bs, balpha = np.inf, -1, 0.0
    x = np.empty(3)
    for s in range(gstart[g], gstart[g + 1]):
        if not swept:
            d = signed_distance(kind, R, p, size, cw0[s]) - sr[s]
            alpha = 0.0
        else:
            half = 0.0
            for a in range(3):
                x[a] = 0.5 * (cw0[s, a] + cw1[s, a])
                half += (cw1[s, a] - cw0[s, a]) ** 2
            if signed_distance(kind, R, p, size, x) - sr[s] - 0.5 * np.sqrt(half) >= margin:
                continue
            f, alpha = _swept_min(kind, R, p, size, cw0[s], cw1[s], iters)
            d = f - sr[s]
        if d < best:
            best, bs, balpha = d, s, alpha
    return best, bs, balpha


@njit(cache=True)
def _obstacle_candidates(t, margin, groups, sr, env, ebound, fixed, fbound, allowed, clusters,
                         cw0, cw1, gw0, gw1, swept, iters, cd, cs, co, ck, ca, cn
                         ):  # pragma: no cover - compiled
    """Push the closest (group, obstacle) pairs within margin; returns how many."""
    gstart, gc, gr, gj = groups
    ek, eR, ep, es = env
    fk, fR, fp, fs = fixed
    cl_c, cl_r, cl_start, cl_members = clusters
    G = gr.shape[0]
    x = np.empty(3)
    nrm = np.empty(3)
    n = 0
    for g in range(G):
        reach = gr[g] + margin
        half = 0.0
        for a in range(3):
            x[a] = 0.5 * (gw0[g, a] + gw1[g, a])
            half += (gw1[g, a] - gw0[g, a]) ** 2
        reach += 0.5 * np.sqrt(half)
        for src in range(2):
            if src == 0:
                count = ek.shape[0]
            else:
                count = cl_c.shape[0]
            for o_or_l in range(count):
                if src == 0:
                    lo, hi = o_or_l, o_or_l + 1
                else:  # a cluster of fixed robot parts: cull all of it at once
                    dc = np.sqrt((x[0] - cl_c[o_or_l, 0]) ** 2 + (x[1] - cl_c[o_or_l, 1]) ** 2
                                 + (x[2] - cl_c[o_or_l, 2]) ** 2)
                    if dc - cl_r[o_or_l] >= reach:
                        continue
                    lo, hi = cl_start[o_or_l], cl_start[o_or_l + 1]
                for m in range(lo, hi):
                    if src == 0:
                        o = m
                        kind, R, p, size, bnd = ek[o], eR[o], ep[o], es[o], ebound[o]
                    else:
                        o = cl_members[m]
                        if not allowed[g, o]:
                            continue
                        kind, R, p, size, bnd = fk[o], fR[o], fp[o], fs[o], fbound[o]
                    dc = np.sqrt((x[0] - p[0]) ** 2 + (x[1] - p[1]) ** 2 + (x[2] - p[2]) ** 2)
                    if dc - bnd >= reach or signed_distance(kind, R, p, size, x) >= reach:
                        continue
                    best, bs, alpha = _closest_in_group(kind, R, p, size, g, gstart, sr, cw0,
                                                        cw1, swept, margin, iters)
                    if best < margin and n < cd.shape[0]:
                        for a in range(3):
                            x[a] = cw0[bs, a] + alpha * (cw1[bs, a] - cw0[bs, a])
                        signed_distance_normal(kind, R, p, size, x, nrm)
                        cd[n], cs[n], co[n], ck[n], ca[n] = best, bs, o, src, alpha
                        cn[n, 0], cn[n, 1], cn[n, 2] = nrm[0], nrm[1], nrm[2]
                        for a in range(3):
                            x[a] = 0.5 * (gw0[g, a] + gw1[g, a])
                        n += 1
    return n


@njit(cache=True)
def _self_candidates(margin, groups, sr, self_pairs, cw, gw, n, cd, cs, co, ck, ca, cn
                     ):  # pragma: no cover - compiled
    gstart, gc, gr, gj = groups
    for i in range(self_pairs.shape[0]):
        a, b = self_pairs[i, 0], self_pairs[i, 1]
        dx = gw[a] - gw[b]
        if np.sqrt(np.sum(dx * dx)) - gr[a] - gr[b] >= margin:
            continue
        best, bs, bt = np.inf, -1, -1
        for s in range(gstart[a], gstart[a + 1]):
            for u in range(gstart[b], gstart[b + 1]):
                d = np.sqrt((cw[s, 0] - cw[u, 0]) ** 2 + (cw[s, 1] - cw[u, 1]) ** 2
                            + (cw[s, 2] - cw[u, 2]) ** 2) - sr[s] - sr[u]
                if d < best:
                    best, bs, bt = d, s, u
        if best < margin and n < cd.shape[0]:
            dx = cw[bs] - cw[bt]
            nd = np.sqrt(np.sum(dx * dx))
            cd[n], cs[n], co[n], ck[n], ca[n] = best, bs, bt, 2, 0.0
            if nd > 1e-12:
                cn[n] = dx / nd
            else:
                cn[n] = 0.0
                cn[n, 2] = 1.0
            n += 1
    return n


@njit(cache=True)
def waypoint_terms(Q, margin, C, with_obstacles, chain, spheres, groups, env, ebound, fixed,
                   fbound, allowed, clusters, self_pairs, dist, grad
                   ):  # pragma: no cover - compiled
    """Discrete terms at each waypoint Q[t]: the C closest (group, obstacle / fixed part /
    other group) pairs within ``margin`` (m): dist (T, C) m and grad (T, C, K) m/rad; unused
    slots get dist 1e3 and a zero gradient. ``with_obstacles`` False keeps self-collision only
    (when continuous terms already cover the obstacles)."""
    T, K = Q.shape
    parent, axis = chain[0], chain[3]
    sc, sr, sj = spheres
    gstart, gc, gr, gj = groups
    S, G = sc.shape[0], gc.shape[0]
    Rb = np.empty((K, 3, 3))
    pb = np.empty((K, 3))
    aw = np.empty((K, 3))
    cw = np.empty((S, 3))
    gw = np.empty((G, 3))
    cd, cs, co, ck, ca, cn = _candidates(G * (env[0].shape[0] + fixed[0].shape[0])
                                         + self_pairs.shape[0] + 1)
    order = np.empty(C, dtype=np.int64)
    for t in range(T):
        _centres(Q[t], chain, sc, sj, gc, gj, Rb, pb, cw, gw)
        _world_axes(Rb, axis, aw)
        n = 0
        if with_obstacles:
            n = _obstacle_candidates(t, margin, groups, sr, env, ebound, fixed, fbound, allowed,
                                     clusters, cw, cw, gw, gw, False, 0, cd, cs, co, ck, ca, cn)
        n = _self_candidates(margin, groups, sr, self_pairs, cw, gw, n, cd, cs, co, ck, ca, cn)
        m = _select(cd, n, C, order)
        for k in range(C):
            grad[t, k, :] = 0.0
            if k >= m:
                dist[t, k] = _NO_TERM
                continue
            i = order[k]
            dist[t, k] = cd[i]
            _add_point_gradient(cn[i], cw[cs[i]], sj[cs[i]], parent, aw, pb, 1.0, grad[t, k])
            if ck[i] == 2:
                u = co[i]
                _add_point_gradient(cn[i], cw[u], sj[u], parent, aw, pb, -1.0, grad[t, k])


@njit(cache=True)
def segment_terms(Q, margin, C, chain, spheres, groups, env, ebound, fixed, fbound, allowed,
                  clusters, dist, grad0, grad1, iters=30):  # pragma: no cover - compiled
    """Continuous terms of each segment Q[t] → Q[t+1] against obstacles and fixed robot parts
    (swept spheres): dist (T-1, C) m, grad0 / grad1 (T-1, C, K) m/rad with respect to Q[t] /
    Q[t+1]; unused slots get dist 1e3 and zero gradients."""
    T, K = Q.shape
    parent, axis = chain[0], chain[3]
    sc, sr, sj = spheres
    gstart, gc, gr, gj = groups
    S, G = sc.shape[0], gc.shape[0]
    Rb = np.empty((T, K, 3, 3))
    pb = np.empty((T, K, 3))
    aw = np.empty((T, K, 3))
    cw = np.empty((T, S, 3))
    gw = np.empty((T, G, 3))
    for t in range(T):
        _centres(Q[t], chain, sc, sj, gc, gj, Rb[t], pb[t], cw[t], gw[t])
        _world_axes(Rb[t], axis, aw[t])
    cd, cs, co, ck, ca, cn = _candidates(G * (env[0].shape[0] + fixed[0].shape[0]) + 1)
    order = np.empty(C, dtype=np.int64)
    for t in range(T - 1):
        n = _obstacle_candidates(t, margin, groups, sr, env, ebound, fixed, fbound, allowed,
                                 clusters, cw[t], cw[t + 1], gw[t], gw[t + 1], True, iters,
                                 cd, cs, co, ck, ca, cn)
        m = _select(cd, n, C, order)
        for k in range(C):
            grad0[t, k, :] = 0.0
            grad1[t, k, :] = 0.0
            if k >= m:
                dist[t, k] = _NO_TERM
                continue
            i = order[k]
            s = cs[i]
            dist[t, k] = cd[i]
            _add_point_gradient(cn[i], cw[t, s], sj[s], parent, aw[t], pb[t], 1.0 - ca[i],
                                grad0[t, k])
            _add_point_gradient(cn[i], cw[t + 1, s], sj[s], parent, aw[t + 1], pb[t + 1],
                                ca[i], grad1[t, k])


class TrajectoryDistances:
    """Signed-distance terms of whole trajectories against a :class:`FastChecker`'s world.

    Reads the checker's current obstacles on every call (dynamic ones included). Fixed robot
    parts are grouped into spatial clusters with bounding spheres, so a link far from the torso
    skips all of its primitives with one test.
    """

    def __init__(self, fast: FastChecker) -> None:
        self.fast = fast
        chain, spheres, groups, _, fixed, _, self_pairs = fast._exact_args()
        self._chain, self._spheres, self._groups = chain, spheres, groups
        self._fixed, self._self_pairs = fixed, self_pairs
        fk, _, _, fs = fixed
        self._fbound = bounding_radius(fk, fs)
        # the fast checker's clusters of fixed robot parts and its (group, part) pairs
        self._allowed, *clusters = fast._fixed_csr[2:]
        self._clusters = tuple(clusters)
        self._env_version = -1
        q = 0.5 * (fast.robot.lower + fast.robot.upper)  # compile the kernels now, not in a
        self.segments(np.vstack([q, q + 0.05]), 0.05, 1)  # planner's time limit
        self.waypoints(q[None], 0.05, 1)

    def _env(self) -> tuple[tuple, Array]:
        if self._env_version != self.fast.obstacles_version:
            env = self.fast._exact_args()[3]
            self._env_cache = (env, bounding_radius(env[0], env[3]))
            self._env_version = self.fast.obstacles_version
        return self._env_cache

    def waypoints(self, Q: Array, margin: float, C: int, with_obstacles: bool = True
                  ) -> tuple[Array, Array]:
        """Discrete terms of Q (T, K): dist (T, C) m and grad (T, C, K) m/rad."""
        Q = np.ascontiguousarray(Q, dtype=float)
        T, K = Q.shape
        dist, grad = np.empty((T, C)), np.empty((T, C, K))
        env, ebound = self._env()
        waypoint_terms(Q, float(margin), int(C), bool(with_obstacles), self._chain,
                       self._spheres, self._groups, env, ebound, self._fixed, self._fbound,
                       self._allowed, self._clusters, self._self_pairs, dist, grad)
        return dist, grad

    def segments(self, Q: Array, margin: float, C: int, deadline: float = math.inf
                 ) -> tuple[Array, Array, Array]:
        """Continuous (swept) terms of the segments of Q (T, K): dist (T-1, C) m and grad0 /
        grad1 (T-1, C, K) m/rad with respect to each segment's first / second waypoint.
        With a finite ``deadline`` (``time.perf_counter()`` value, s) the segments go in
        chunks of about :data:`DEADLINE_CHUNK_S` of work, and :class:`DeadlineError` is raised
        between two when it has passed."""
        Q = np.ascontiguousarray(Q, dtype=float)
        T, K = Q.shape
        dist = np.empty((T - 1, C))
        g0, g1 = np.empty((T - 1, C, K)), np.empty((T - 1, C, K))
        env, ebound = self._env()
        a, step = 0, T - 1 if math.isinf(deadline) else 1
        while a < T - 1:
            if time.perf_counter() > deadline:
                raise DeadlineError("time limit reached while evaluating collision terms")
            b = min(a + step, T - 1)
            t = time.perf_counter()
            segment_terms(Q[a:b + 1], float(margin), int(C), self._chain, self._spheres,
                          self._groups, env, ebound, self._fixed, self._fbound, self._allowed,
                          self._clusters, dist[a:b], g0[a:b], g1[a:b])
            per_segment = (time.perf_counter() - t) / (b - a)
            step = max(1, min(2 * step, DEADLINE_CHUNK_MAX,
                              int(DEADLINE_CHUNK_S / max(per_segment, 1e-7))))
            a = b
        return dist, g0, g1
