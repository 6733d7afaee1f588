"""The greedy steps of a brake's time scaling in one compiled call (:func:`brake_steps`), for
:func:`~chekhov.execute.motion.brake_along`.

A brake takes a few hundred steps of :data:`~chekhov.execute.motion.BRAKE_DT_S`, each reading
the braked motion's q̇ and q̈ on a grid of its own time and solving for the strongest
deceleration within the limits; done in Python on (K,) arrays that cost ~7 ms a brake, a
third of a control step in a react episode's chains of reactions. The kernel runs the same
steps on the grid it is given and returns when the brake is over, when it needs the grid
further on (the caller samples more and calls again) or when the output rows are full.
Units: s (the motion's own time and the brake's), rad/s, rad/s².
"""

from __future__ import annotations

import numpy as np
from numba import njit

DONE, NEED_GRID, FULL = 0, 1, 2
"""Why :func:`brake_steps` returned: the brake is at rest (or at the motion's end), the next
step reads past the grid, the output rows are full."""

HALVINGS = 5
"""Tries per step: a step whose end breaks the end limits is halved, at most this many times
less one (the last try is kept)."""


@njit(cache=True, nogil=True, inline="always")
def _grid_at(n_rows, s, s0, h):  # pragma: no cover - compiled
    """Index i and fraction f of own time ``s`` on the grid (s0 + h·i), or i = -1 when
    row i + 1 is not among the ``n_rows`` sampled yet."""
    x = (s - s0) / h
    i = int(x)
    if i + 1 >= n_rows:
        return -1, 0.0
    return i, x - i


@njit(cache=True, nogil=True, inline="always")
def _deceleration(V, A, i, f, sd, a):  # pragma: no cover - compiled
    """The largest k ≥ 0 with |q̈ ṡ² - q̇ k| ≤ a for every joint moving faster than 1e-9,
    q̇ and q̈ interpolated at grid row i + f (0 when no joint moves or none is)."""
    lo, hi, moving = -np.inf, np.inf, False
    for j in range(V.shape[1]):
        v = V[i, j] + f * (V[i + 1, j] - V[i, j])
        if abs(v) < 1e-9:
            continue
        moving = True
        b = (A[i, j] + f * (A[i + 1, j] - A[i, j])) * sd * sd
        k1, k2 = (b - a[j]) / v, (b + a[j]) / v
        lo = max(lo, min(k1, k2))
        hi = min(hi, max(k1, k2))
    if not moving:
        return 0.0
    lo = max(lo, 0.0)
    return hi if hi >= lo and np.isfinite(hi) else 0.0


@njit(cache=True, nogil=True, inline="always")
def _within(V, A, i, f, sd, sdd, a):  # pragma: no cover - compiled
    """Whether |q̈ ṡ² - q̇ s̈| ≤ a for every joint at grid row i + f."""
    for j in range(V.shape[1]):
        v = V[i, j] + f * (V[i + 1, j] - V[i, j])
        acc = A[i, j] + f * (A[i + 1, j] - A[i, j])
        if not abs(acc * sd * sd - v * sdd) <= a[j]:
            return False
    return True


@njit(cache=True, nogil=True)
def brake_steps(V, A, s0, h, t_end, a, end_a, dt, state, rows, n):  # pragma: no cover
    """Brake steps from ``state`` = [clock time since the brake began, s, ṡ] (updated in
    place) appended to ``rows`` (M, 4) from row ``n``: each row (time at the step's end, s,
    ṡ there, the step's s̈). V, A (G, K): q̇ and q̈ of the motion at own times s0 + h·g;
    ``a`` / ``end_a`` (K,): the accelerations a step aims at / may reach at its end; ``dt``
    the step. Returns (rows filled, why: DONE, NEED_GRID or FULL)."""
    t, s, sd = state[0], state[1], state[2]
    while sd > 0 and s < t_end:
        if n >= rows.shape[0]:
            return n, FULL
        i, f = _grid_at(V.shape[0], s, s0, h)
        if i < 0:
            return n, NEED_GRID
        sdd = _deceleration(V, A, i, f, sd, a)
        step = min(dt, sd / sdd) if sdd > 0 else dt
        s2, sd2 = s, sd
        for k in range(HALVINGS):
            s2 = min(s + sd * step - 0.5 * sdd * step * step, t_end)
            sd2 = max(sd - sdd * step, 0.0)
            if sdd == 0.0 or k == HALVINGS - 1:
                break
            i2, f2 = _grid_at(V.shape[0], s2, s0, h)
            if i2 < 0:
                return n, NEED_GRID
            if _within(V, A, i2, f2, sd2, sdd, end_a):
                break
            step *= 0.5
        t += step
        s, sd = s2, (0.0 if sd2 < 1e-9 or s2 >= t_end else sd2)
        rows[n, 0], rows[n, 1], rows[n, 2], rows[n, 3] = t, s, sd, sdd
        n += 1
        state[0], state[1], state[2] = t, s, sd
    return n, DONE
