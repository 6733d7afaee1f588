"""Exact convex primitive–primitive tests for the fast checker (numba), to confirm sphere hits.

A sphere of the cover overlapping an obstacle only says that the geometry it covers *may* touch
it. These kernels decide it on the geometry itself: GJK looks for the closest point of the
Minkowski difference A − B to the origin, and the answer "separated" is only given with a
certificate that does not depend on GJK's numerics: a unit direction u with

    min over A of x·u − max over B of x·u = −h_A(−u) − h_B(u) > pad,

h being the closed-form support value of each primitive. Anything else (touching, overlap,
GJK not converged, a degenerate simplex) answers "collision", so the fast checker stays
conservative. Kinds as in ``codes``: ``SPHERE`` (radius), ``BOX`` (half extents),
``CYLINDER`` along its z axis (radius, half length); world pose R (3, 3), p (3,). Metres.

Kind ``HULL`` is a convex polytope given by points V[v0:v1] (n, 3) in its own frame (the
vertices of a mesh part's convex hull): h(u) = p·u + max over those points of v·(Rᵀu), exact
for any point set, so the certificate holds for the mesh part whatever the hull's numerics as
long as the points include every extreme vertex of the part (see ``primitives.hull_parts``).
Other kinds ignore V, v0, v1.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from chekhov.collision.codes import BOX, HULL, SPHERE

MAX_ITER = 32


@njit(cache=True, nogil=True, inline="always")
def support_point(kind, R, p, size, V, v0, v1, u, sign, out):  # pragma: no cover - compiled
    """out = a point x of the primitive maximising x·(sign·u), for any direction u (3,)
    (its support value h(sign·u) = x·(sign·u))."""
    for a in range(3):
        out[a] = p[a]
    if kind == HULL:
        l0 = sign * (R[0, 0] * u[0] + R[1, 0] * u[1] + R[2, 0] * u[2])
        l1 = sign * (R[0, 1] * u[0] + R[1, 1] * u[1] + R[2, 1] * u[2])
        l2 = sign * (R[0, 2] * u[0] + R[1, 2] * u[1] + R[2, 2] * u[2])
        best = -np.inf
        k = v0
        for i in range(v0, v1):
            d = V[i, 0] * l0 + V[i, 1] * l1 + V[i, 2] * l2
            if d > best:
                best = d
                k = i
        for a in range(3):
            out[a] += R[a, 0] * V[k, 0] + R[a, 1] * V[k, 1] + R[a, 2] * V[k, 2]
    elif kind == SPHERE:
        n = np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
        if n > 0.0:
            for a in range(3):
                out[a] += sign * size[0] * u[a] / n
    elif kind == BOX:
        for i in range(3):
            d = sign * (R[0, i] * u[0] + R[1, i] * u[1] + R[2, i] * u[2])
            s = size[i] if d >= 0.0 else -size[i]
            for a in range(3):
                out[a] += s * R[a, i]
    else:
        zu = sign * (R[0, 2] * u[0] + R[1, 2] * u[1] + R[2, 2] * u[2])
        s = size[1] if zu >= 0.0 else -size[1]
        perp = np.empty(3)
        for a in range(3):
            perp[a] = sign * u[a] - zu * R[a, 2]
            out[a] += s * R[a, 2]
        n = np.sqrt(perp[0] * perp[0] + perp[1] * perp[1] + perp[2] * perp[2])
        if n > 1e-15:
            for a in range(3):
                out[a] += size[0] * perp[a] / n


@njit(cache=True, nogil=True)
def _closest_on_simplex(S, n, v, idx, E, x, G, b):  # pragma: no cover - compiled
    """Closest point v to the origin on the simplex S[:n] (n ≤ 4); S is reduced to the
    smallest face holding it. Returns the new n (4 when the origin is inside). idx (4,)
    int64, E (3, 3), x (3,), G (3, 3), b (3,): work space (allocations here, a dozen a call,
    had cost as much as the arithmetic)."""
    best = np.inf
    bestmask = 0
    # the newest point S[n-1] (GJK's support point towards the origin) lies in the closest
    # face whenever GJK made progress, so only the faces holding it are tried (8 of 15 for a
    # tetrahedron): 2-10% less time a call on random hull pairs, the same gaps to the bit;
    # the certificate does not depend on this choice (module docstring)
    newest = 1 << (n - 1)
    for mask in range(1, 1 << n):
        if not mask & newest:
            continue
        m = 0
        for i in range(n):
            if mask & (1 << i):
                idx[m] = i
                m += 1
        w0 = S[idx[0]]
        for r in range(m - 1):
            for a in range(3):
                E[r, a] = S[idx[r + 1], a] - w0[a]
        mu0 = mu1 = mu2 = 0.0
        if m == 2:
            g = E[0, 0] ** 2 + E[0, 1] ** 2 + E[0, 2] ** 2
            if g < 1e-24:
                continue
            mu0 = -(E[0, 0] * w0[0] + E[0, 1] * w0[1] + E[0, 2] * w0[2]) / g
        elif m >= 3:
            for r in range(3):
                b[r] = 0.0
                for c in range(3):
                    G[r, c] = 0.0
            for r in range(m - 1):
                b[r] = -(E[r, 0] * w0[0] + E[r, 1] * w0[1] + E[r, 2] * w0[2])
                for c in range(m - 1):
                    G[r, c] = E[r, 0] * E[c, 0] + E[r, 1] * E[c, 1] + E[r, 2] * E[c, 2]
            if m == 3:
                det = G[0, 0] * G[1, 1] - G[0, 1] * G[1, 0]
                if abs(det) < 1e-30:
                    continue
                mu0 = (b[0] * G[1, 1] - G[0, 1] * b[1]) / det
                mu1 = (G[0, 0] * b[1] - b[0] * G[1, 0]) / det
            else:
                det = (G[0, 0] * (G[1, 1] * G[2, 2] - G[1, 2] * G[2, 1])
                       - G[0, 1] * (G[1, 0] * G[2, 2] - G[1, 2] * G[2, 0])
                       + G[0, 2] * (G[1, 0] * G[2, 1] - G[1, 1] * G[2, 0]))
                if abs(det) < 1e-36:
                    continue
                mu0 = (b[0] * (G[1, 1] * G[2, 2] - G[1, 2] * G[2, 1])
                       - G[0, 1] * (b[1] * G[2, 2] - G[1, 2] * b[2])
                       + G[0, 2] * (b[1] * G[2, 1] - G[1, 1] * b[2])) / det
                mu1 = (G[0, 0] * (b[1] * G[2, 2] - G[1, 2] * b[2])
                       - b[0] * (G[1, 0] * G[2, 2] - G[1, 2] * G[2, 0])
                       + G[0, 2] * (G[1, 0] * b[2] - b[1] * G[2, 0])) / det
                mu2 = (G[0, 0] * (G[1, 1] * b[2] - b[1] * G[2, 1])
                       - G[0, 1] * (G[1, 0] * b[2] - b[1] * G[2, 0])
                       + b[0] * (G[1, 0] * G[2, 1] - G[1, 1] * G[2, 0])) / det
        if mu0 < 0.0 or mu1 < 0.0 or mu2 < 0.0 or mu0 + mu1 + mu2 > 1.0:
            continue
        for a in range(3):
            x[a] = w0[a]
            if m >= 2:
                x[a] += mu0 * E[0, a]
            if m >= 3:
                x[a] += mu1 * E[1, a]
            if m == 4:
                x[a] += mu2 * E[2, a]
        nx = x[0] * x[0] + x[1] * x[1] + x[2] * x[2]
        if nx < best:
            best = nx
            bestmask = mask
            for a in range(3):
                v[a] = x[a]
    if bestmask == 0:  # numerically degenerate: keep the newest point
        bestmask = 1 << (n - 1)
        for a in range(3):
            v[a] = S[n - 1, a]
    if bestmask == (1 << n) - 1 and n == 4:
        return 4
    m = 0
    for i in range(n):
        if bestmask & (1 << i):
            for a in range(3):
                S[m, a] = S[i, a]
            m += 1
    return m


@njit(cache=True, nogil=True)
def primitives_collide(ka, Ra, pa, sa, kb, Rb, pb, sb, pad):  # pragma: no cover - compiled
    """False only when primitives A and B (kinds 0-2) are proven more than ``pad`` (m) apart."""
    V = np.empty((0, 3))
    return convex_collide(ka, Ra, pa, sa, V, 0, 0, pa, kb, Rb, pb, sb, V, 0, 0, pb, pad)


@njit(cache=True, nogil=True)
def convex_collide(ka, Ra, pa, sa, Va, a0, a1, ca, kb, Rb, pb, sb, Vb, b0, b1, cb, pad
                   ):  # pragma: no cover - compiled
    """False only when convex shapes A and B are proven more than ``pad`` (m) apart.

    Each shape is (kind, R, p, size, V, v0, v1) as in :func:`support_point`, and a point of it
    (world, m) to start from: ca, cb (e.g. its centre)."""
    return convex_gap(ka, Ra, pa, sa, Va, a0, a1, ca, kb, Rb, pb, sb, Vb, b0, b1, cb,
                      pad) <= pad + 1e-9


@njit(cache=True, nogil=True, inline="always")
def convex_gap(ka, Ra, pa, sa, Va, a0, a1, ca, kb, Rb, pb, sb, Vb, b0, b1, cb, target
               ):  # pragma: no cover - compiled
    """A certified lower bound (m) on the distance between convex shapes A and B (shapes as
    in :func:`convex_collide`): the largest min over A − B of x·u that GJK's directions u
    gave. GJK stops once it exceeds ``target`` + 1e-9 (returned), when a point of A − B lies
    within ``target`` of the origin (the bound along that point's direction is taken too, so
    a converged GJK returns about the distance) or when it makes no progress; ≤ ``target`` +
    1e-9 whenever the shapes are not proved more than ``target`` apart (-inf: no direction
    tried)."""
    S = np.empty((4, 3))
    v = np.empty(3)
    u = np.empty(3)
    xa = np.empty(3)
    xb = np.empty(3)
    idx = np.empty(4, dtype=np.int64)
    E = np.empty((3, 3))
    x = np.empty(3)
    G = np.empty((3, 3))
    b = np.empty(3)
    for a in range(3):
        v[a] = ca[a] - cb[a]
    n = 0
    best = -np.inf
    for _ in range(MAX_ITER):
        nv = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        if nv <= 0.0:
            return best
        for a in range(3):
            u[a] = v[a] / nv
        # the extreme points of A along −u and of B along u: w = xa − xb is the point of
        # A − B with the least x·u, and sep = w·u the certificate along u (one scan of each
        # shape's support points gives both)
        support_point(ka, Ra, pa, sa, Va, a0, a1, u, -1.0, xa)
        support_point(kb, Rb, pb, sb, Vb, b0, b1, u, 1.0, xb)
        w0, w1, w2 = xa[0] - xb[0], xa[1] - xb[1], xa[2] - xb[2]
        sep = w0 * u[0] + w1 * u[1] + w2 * u[2]
        if nv <= target:   # a point of A − B within target of the origin: no proof above it
            return max(best, sep)
        if sep > target + 1e-9:
            return sep
        best = max(best, sep)
        # no progress: GJK has converged on a distance ≤ target (the certificate failed)
        if nv * nv - (v[0] * w0 + v[1] * w1 + v[2] * w2) <= 1e-12 * nv * nv:
            return best
        S[n, 0], S[n, 1], S[n, 2] = w0, w1, w2
        n = _closest_on_simplex(S, n + 1, v, idx, E, x, G, b)
        if n == 4:
            return best  # origin inside the simplex
    return best
