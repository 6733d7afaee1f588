"""How far a group of the robot's spheres can move along a straight joint-space motion, from
the configuration it is in: the compiled bounds behind the dense walk's clearance
certificates (``dense_path.py``).

A joint turning by dq moves a point at distance r from its axis by at most r·dq; the lever
bounds (``packed.lever_arms``) bound r over every configuration by adding up the links'
offsets, while the distance from the axis *now* is often much less. :func:`clear_for` keeps
the longer of the two certificates; :func:`curvature` is its second-order term, computed once
per segment. ``tests/test_collision.py`` checks it against forward kinematics along the
motion.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, inline="always")
def curvature(g, dq, parent, gj, gr, lever, curve):  # pragma: no cover - compiled
    """curve[g] (m): Σ_i dq_i β_i over the joints i that move group g, β_i = Σ_j dq_j ρ_j over
    the joints j between i and the group (ρ_j: lever[g, j] for the centre, plus the group's
    radius for its spheres): how fast, per substep, the distances from the joints' axes to
    the centre (to any point within its radius) can grow (see :func:`clear_for`)."""
    centre = sphere = 0.0
    below = below_s = 0.0   # Σ dq_j ρ_j over the joints visited so far (those below i)
    i = gj[g]
    while i >= 0:
        centre += dq[i] * below
        sphere += dq[i] * below_s
        below += dq[i] * lever[g, i]
        below_s += dq[i] * (lever[g, i] + gr[g])
        i = parent[i]
    curve[g, 0] = centre
    curve[g, 1] = sphere


@njit(cache=True, nogil=True, inline="always")
def clear_for(d, g, r, curve, step, dq, parent, gj, axis, Rc, pc, gwc
              ):  # pragma: no cover - compiled
    """Substeps for which group g's centre (r = 0), or any point within r of it, moves by
    less than d (m) from this configuration (joint poses Rc, pc; centres gwc).

    Two bounds, the longer kept. ``d / step``: ``step`` the most it moves in a substep in any
    configuration (``lever``). And this configuration's own: joint i turning by dq_i moves a
    point at distance r_i from its axis by at most r_i dq_i, and r_i can only grow through
    the joints between i and the group, by at most β_i per substep (``curve`` = Σ_i dq_i β_i,
    :func:`curvature`); so over s substeps the point moves at most A s + curve s² / 2, A =
    Σ_i dq_i (r_i + r) with r_i the centre's distance from axis i now — less than d for
    s < 2 d / (A + sqrt(A² + 2 curve d)). The lever bounds add up the links' offsets and hold
    in every configuration; the distances from the axes are often much less."""
    a = 1e-12
    i = gj[g]
    while i >= 0:
        if dq[i] > 0.0:
            # the joint's axis in the world: Rc[i] @ axis[i], through pc[i]
            ux = Rc[i, 0, 0] * axis[i, 0] + Rc[i, 0, 1] * axis[i, 1] + Rc[i, 0, 2] * axis[i, 2]
            uy = Rc[i, 1, 0] * axis[i, 0] + Rc[i, 1, 1] * axis[i, 1] + Rc[i, 1, 2] * axis[i, 2]
            uz = Rc[i, 2, 0] * axis[i, 0] + Rc[i, 2, 1] * axis[i, 1] + Rc[i, 2, 2] * axis[i, 2]
            vx, vy, vz = gwc[g, 0] - pc[i, 0], gwc[g, 1] - pc[i, 1], gwc[g, 2] - pc[i, 2]
            cx, cy, cz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
            norm = np.sqrt(ux * ux + uy * uy + uz * uz)
            a += dq[i] * (np.sqrt(cx * cx + cy * cy + cz * cz) / norm + r)
        i = parent[i]
    local = 2.0 * d / (a + np.sqrt(a * a + 2.0 * curve * d))
    return int(min(max(local * (1.0 - 1e-9), d / step), 1e15))


@njit(cache=True, nogil=True)
def decision_margins(P, diff, W, scale, touches, padding, grid, slack
                     ):  # pragma: no cover - compiled
    """The margins of one exact path decision (``path_check._Coal``), in one call.

    P (M, K) rad: the steps between samples, or (``diff``) a path whose waypoint differences,
    times ``scale``, are. W (U, K) m/rad: the collision pairs' distinct motion-weight rows.
    Returns one array (2 U + 2 G,), its parts in order (one allocation; a tuple of four
    arrays costs more than the arithmetic): L (U,) m, each row's largest motion bound
    Σ_k |step_k| W[u, k] over the steps, at least 1e-12; mu (U,) m, L / 2 rounded up to a
    power of ``grid``, plus ``slack``; pad (G,) m, per fast-checker group the largest mu of
    the rows its pairs have (``touches`` (G, U) bool; 0 with none); grow (G,) m, pad less
    the spheres' ``padding``, at least 0."""
    U, K = W.shape
    G = touches.shape[0]
    M = P.shape[0] - 1 if diff else P.shape[0]
    out = np.zeros(2 * U + 2 * G)
    L, mu, pad, grow = out[:U], out[U:2 * U], out[2 * U:2 * U + G], out[2 * U + G:]
    a = np.empty(K)
    for m in range(M):
        for k in range(K):
            a[k] = abs(P[m + 1, k] - P[m, k] if diff else P[m, k])
        for u in range(U):
            s = 0.0
            for k in range(K):
                s += a[k] * W[u, k]
            if s > L[u]:
                L[u] = s
    log_grid = np.log(grid)
    for u in range(U):
        L[u] = max(L[u] * scale, 1e-12)
        half = 0.5 * L[u]
        r = grid ** np.ceil(np.log(half) / log_grid)
        if r < half:       # the power's last bit
            r *= grid
        mu[u] = r + slack
    for g in range(G):
        for u in range(U):
            if touches[g, u] and mu[u] > pad[g]:
                pad[g] = mu[u]
        grow[g] = max(pad[g] - padding, 0.0)
    return out
