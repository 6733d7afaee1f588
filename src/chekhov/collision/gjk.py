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

# rows of convex_gap's work array W (11, 3): the simplex (4), v (GJK's direction: the closest
# point found), u (v normalised), the support points of A and B, and _closest_on_simplex's
# edges E (3). One array read by index: ten small arrays, or row views of one, had
# cost more than the arithmetic (compiled code counts references to each as it is handed on;
# 2,170 -> 1,850 ns a confirmation of the Panda's self pairs, the same gaps to the bit)
_S, _V, _U, _XA, _XB, _E = 0, 4, 5, 6, 7, 8  # _S = 0: simplex rows are W[i]


@njit(cache=True, nogil=True)
def _hull_argmax(V, v0, v1, l0, l1, l2):  # pragma: no cover - compiled
    """The first index i in v0:v1 of the largest V[i]·(l0, l1, l2): four running maxima, so
    that the comparisons do not wait on each other (a 152-point hull: 232 -> 145 ns). A call,
    not inlined, like :func:`_closest_on_simplex`: inlined into every copy of GJK they made a
    cold compile of a planner's kernels 65% longer (262 -> 430 s) for 4% less time a call."""
    b0 = b1 = b2 = b3 = -np.inf
    k0 = k1 = k2 = k3 = v0
    i = v0
    while i + 4 <= v1:
        x0 = V[i, 0] * l0 + V[i, 1] * l1 + V[i, 2] * l2
        x1 = V[i + 1, 0] * l0 + V[i + 1, 1] * l1 + V[i + 1, 2] * l2
        x2 = V[i + 2, 0] * l0 + V[i + 2, 1] * l1 + V[i + 2, 2] * l2
        x3 = V[i + 3, 0] * l0 + V[i + 3, 1] * l1 + V[i + 3, 2] * l2
        if x0 > b0:
            b0, k0 = x0, i
        if x1 > b1:
            b1, k1 = x1, i + 1
        if x2 > b2:
            b2, k2 = x2, i + 2
        if x3 > b3:
            b3, k3 = x3, i + 3
        i += 4
    while i < v1:
        x0 = V[i, 0] * l0 + V[i, 1] * l1 + V[i, 2] * l2
        if x0 > b0:
            b0, k0 = x0, i
        i += 1
    # the first index of the largest value, as one running maximum would give
    if b1 > b0 or (b1 == b0 and k1 < k0):
        b0, k0 = b1, k1
    if b2 > b0 or (b2 == b0 and k2 < k0):
        b0, k0 = b2, k2
    if b3 > b0 or (b3 == b0 and k3 < k0):
        k0 = k3
    return k0


@njit(cache=True, nogil=True, inline="always")
def support_point(kind, R, p, size, V, v0, v1, W, sign, o):  # pragma: no cover - compiled
    """W[o] = a point x of the primitive maximising x·(sign·u), u = W[_U] (the work
    array of :func:`convex_gap`): its support value h(sign·u) = x·(sign·u)."""
    u0, u1, u2 = W[_U, 0], W[_U, 1], W[_U, 2]
    x0, x1, x2 = p[0], p[1], p[2]
    if kind == HULL:
        l0 = sign * (R[0, 0] * u0 + R[1, 0] * u1 + R[2, 0] * u2)
        l1 = sign * (R[0, 1] * u0 + R[1, 1] * u1 + R[2, 1] * u2)
        l2 = sign * (R[0, 2] * u0 + R[1, 2] * u1 + R[2, 2] * u2)
        k = _hull_argmax(V, v0, v1, l0, l1, l2)
        x0 += R[0, 0] * V[k, 0] + R[0, 1] * V[k, 1] + R[0, 2] * V[k, 2]
        x1 += R[1, 0] * V[k, 0] + R[1, 1] * V[k, 1] + R[1, 2] * V[k, 2]
        x2 += R[2, 0] * V[k, 0] + R[2, 1] * V[k, 1] + R[2, 2] * V[k, 2]
    elif kind == SPHERE:
        n = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        if n > 0.0:
            x0 += sign * size[0] * u0 / n
            x1 += sign * size[0] * u1 / n
            x2 += sign * size[0] * u2 / n
    elif kind == BOX:
        for i in range(3):
            d = sign * (R[0, i] * u0 + R[1, i] * u1 + R[2, i] * u2)
            s = size[i] if d >= 0.0 else -size[i]
            x0 += s * R[0, i]
            x1 += s * R[1, i]
            x2 += s * R[2, i]
    else:
        zu = sign * (R[0, 2] * u0 + R[1, 2] * u1 + R[2, 2] * u2)
        s = size[1] if zu >= 0.0 else -size[1]
        q0 = sign * u0 - zu * R[0, 2]
        q1 = sign * u1 - zu * R[1, 2]
        q2 = sign * u2 - zu * R[2, 2]
        x0 += s * R[0, 2]
        x1 += s * R[1, 2]
        x2 += s * R[2, 2]
        n = np.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
        if n > 1e-15:
            x0 += size[0] * q0 / n
            x1 += size[0] * q1 / n
            x2 += size[0] * q2 / n
    W[o, 0] = x0
    W[o, 1] = x1
    W[o, 2] = x2


@njit(cache=True, nogil=True)
def _closest_on_simplex(W, n, idx):  # pragma: no cover - compiled
    """Closest point W[_V] to the origin on the simplex W[_S:_S + n] (n ≤ 4); the simplex is
    reduced to the smallest face holding it. Returns the new n (4 when the origin is inside).
    idx (4,) int64: work space."""
    best = np.inf
    bestmask = 0
    # the newest point (GJK's support point towards the origin) lies in the closest face
    # whenever GJK made progress, so only the faces holding it are tried (8 of 15 for a
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
        i0 = idx[0]
        w0, w1, w2 = W[i0, 0], W[i0, 1], W[i0, 2]
        for r in range(m - 1):
            k = idx[r + 1]
            W[_E + r, 0] = W[k, 0] - w0
            W[_E + r, 1] = W[k, 1] - w1
            W[_E + r, 2] = W[k, 2] - w2
        mu0 = mu1 = mu2 = 0.0
        if m == 2:
            g = W[_E, 0] ** 2 + W[_E, 1] ** 2 + W[_E, 2] ** 2
            if g < 1e-24:
                continue
            mu0 = -(W[_E, 0] * w0 + W[_E, 1] * w1 + W[_E, 2] * w2) / g
        elif m >= 3:
            # the edges' Gram matrix g and right-hand side b as scalars (g is symmetric:
            # e_r·e_c and e_c·e_r are the same products summed in the same order)
            e00, e01, e02 = W[_E, 0], W[_E, 1], W[_E, 2]
            e10, e11, e12 = W[_E + 1, 0], W[_E + 1, 1], W[_E + 1, 2]
            g00 = e00 * e00 + e01 * e01 + e02 * e02
            g01 = e00 * e10 + e01 * e11 + e02 * e12
            g11 = e10 * e10 + e11 * e11 + e12 * e12
            b0 = -(e00 * w0 + e01 * w1 + e02 * w2)
            b1 = -(e10 * w0 + e11 * w1 + e12 * w2)
            if m == 3:
                det = g00 * g11 - g01 * g01
                if abs(det) < 1e-30:
                    continue
                mu0 = (b0 * g11 - g01 * b1) / det
                mu1 = (g00 * b1 - b0 * g01) / det
            else:
                e20, e21, e22 = W[_E + 2, 0], W[_E + 2, 1], W[_E + 2, 2]
                g02 = e00 * e20 + e01 * e21 + e02 * e22
                g12 = e10 * e20 + e11 * e21 + e12 * e22
                g22 = e20 * e20 + e21 * e21 + e22 * e22
                b2 = -(e20 * w0 + e21 * w1 + e22 * w2)
                det = (g00 * (g11 * g22 - g12 * g12)
                       - g01 * (g01 * g22 - g12 * g02)
                       + g02 * (g01 * g12 - g11 * g02))
                if abs(det) < 1e-36:
                    continue
                mu0 = (b0 * (g11 * g22 - g12 * g12)
                       - g01 * (b1 * g22 - g12 * b2)
                       + g02 * (b1 * g12 - g11 * b2)) / det
                mu1 = (g00 * (b1 * g22 - g12 * b2)
                       - b0 * (g01 * g22 - g12 * g02)
                       + g02 * (g01 * b2 - b1 * g02)) / det
                mu2 = (g00 * (g11 * b2 - b1 * g12)
                       - g01 * (g01 * b2 - b1 * g02)
                       + b0 * (g01 * g12 - g11 * g02)) / det
        if mu0 < 0.0 or mu1 < 0.0 or mu2 < 0.0 or mu0 + mu1 + mu2 > 1.0:
            continue
        x0, x1, x2 = w0, w1, w2
        if m >= 2:
            x0 += mu0 * W[_E, 0]
            x1 += mu0 * W[_E, 1]
            x2 += mu0 * W[_E, 2]
        if m >= 3:
            x0 += mu1 * W[_E + 1, 0]
            x1 += mu1 * W[_E + 1, 1]
            x2 += mu1 * W[_E + 1, 2]
        if m == 4:
            x0 += mu2 * W[_E + 2, 0]
            x1 += mu2 * W[_E + 2, 1]
            x2 += mu2 * W[_E + 2, 2]
        nx = x0 * x0 + x1 * x1 + x2 * x2
        if nx < best:
            best = nx
            bestmask = mask
            W[_V, 0], W[_V, 1], W[_V, 2] = x0, x1, x2
    if bestmask == 0:  # numerically degenerate: keep the newest point
        bestmask = 1 << (n - 1)
        for a in range(3):
            W[_V, a] = W[n - 1, a]
    if bestmask == (1 << n) - 1 and n == 4:
        return 4
    m = 0
    for i in range(n):
        if bestmask & (1 << i):
            for a in range(3):
                W[m, a] = W[i, a]
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
                      pad, pad) <= pad + 1e-9


@njit(cache=True, nogil=True, inline="always")
def convex_gap(ka, Ra, pa, sa, Va, a0, a1, ca, kb, Rb, pb, sb, Vb, b0, b1, cb, target, near
               ):  # pragma: no cover - compiled
    """A certified lower bound (m) on the distance between convex shapes A and B (shapes as
    in :func:`convex_collide`): the largest min over A − B of x·u that GJK's directions u
    gave. GJK stops once it exceeds ``target`` + 1e-9 (returned), when a point of A − B lies
    within ``near`` (m; ``target`` to decide, below 0 to converge) of the origin (the bound
    along that point's direction is taken too: often well below the distance) or when it
    makes no progress (a converged GJK returns about the distance); ≤ ``target`` + 1e-9
    whenever the shapes are not proved more than ``target`` apart (-inf: no direction
    tried)."""
    W = np.empty((11, 3))  # rows: _S ... _E + 2
    idx = np.empty(4, dtype=np.int64)
    for a in range(3):
        W[_V, a] = ca[a] - cb[a]
    n = 0
    best = -np.inf
    for _ in range(MAX_ITER):
        v0, v1, v2 = W[_V, 0], W[_V, 1], W[_V, 2]
        nv = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        if nv <= 0.0:
            return best
        W[_U, 0], W[_U, 1], W[_U, 2] = v0 / nv, v1 / nv, v2 / nv
        # the extreme points of A along −u and of B along u: w = xa − xb is the point of
        # A − B with the least x·u, and sep = w·u the certificate along u (one scan of each
        # shape's support points gives both)
        support_point(ka, Ra, pa, sa, Va, a0, a1, W, -1.0, _XA)
        support_point(kb, Rb, pb, sb, Vb, b0, b1, W, 1.0, _XB)
        w0, w1, w2 = W[_XA, 0] - W[_XB, 0], W[_XA, 1] - W[_XB, 1], W[_XA, 2] - W[_XB, 2]
        sep = w0 * W[_U, 0] + w1 * W[_U, 1] + w2 * W[_U, 2]
        if nv <= near:     # a point of A − B within near of the origin: no proof above it
            return max(best, sep)
        if sep > target + 1e-9:
            return sep
        best = max(best, sep)
        # no progress: GJK has converged on a distance ≤ target (the certificate failed)
        if nv * nv - (v0 * w0 + v1 * w1 + v2 * w2) <= 1e-12 * nv * nv:
            return best
        W[_S + n, 0], W[_S + n, 1], W[_S + n, 2] = w0, w1, w2
        n = _closest_on_simplex(W, n + 1, idx)
        if n == 4:
            return best  # origin inside the simplex
    return best
