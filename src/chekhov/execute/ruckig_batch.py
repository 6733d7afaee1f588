"""A Ruckig trajectory sampled at many times in one compiled call (:func:`batch_sampler`).

The executive samples its Ruckig moves (joins, dodges, stops) at every check step of every
candidate: ``Trajectory.at_time`` one time at a time from Python cost ~7 µs a sample, a fifth
of the control step in a react run. A one-section trajectory is, per joint, an optional brake
pre-phase (two constant-jerk pieces) and seven constant-jerk phases, after which it keeps its
final acceleration; its profiles give each phase's start state and jerk, so the states at N
times are closed-form (the same as ``Trajectory.at_time``; checked in the tests to 1e-9).
Units: s, rad.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

Array = NDArray[np.float64]


def batch_sampler(traj: Any) -> Callable[[Array], tuple[Array, Array, Array]] | None:
    """(q, q̇, q̈ at times ts (N,) s, each (N, K)) of ``traj`` (a ``ruckig.Trajectory``), or
    None for what it does not cover (several sections, an acceleration pre-phase)."""
    sections = traj.profiles   # a copy of every profile: read once
    if len(sections) != 1:
        return None
    profiles = sections[0]
    K = len(profiles)
    rows: list[float] = []   # per joint: 7 phase durations, then p, v, a (8 each), j (7), 0
    B = np.zeros((K, 5, 2))
    Bd = np.zeros(K)
    for k, p in enumerate(profiles):
        if p.accel.duration > 0.0:
            return None
        rows += p.t + p.p + p.v + p.a + p.j
        rows.append(0.0)
        brake = p.brake   # each attribute read copies it: once (most moves have none)
        if brake.duration > 0.0:
            Bd[k] = brake.duration
            B[k] = (brake.t, brake.p, brake.v, brake.a, brake.j)
    flat = np.array(rows, dtype=float).reshape(K, 39)
    T = np.cumsum(flat[:, :7], axis=1)
    P = np.ascontiguousarray(flat[:, 7:].reshape(K, 4, 8))

    def sample(ts: Array) -> tuple[Array, Array, Array]:
        return _states(np.asarray(ts, dtype=float).reshape(-1), T, P, B, Bd)
    return sample


@njit(cache=True, nogil=True)
def _states(ts, T, P, B, Bd):  # pragma: no cover - compiled
    """States at ts (N,): T (K, 7) the phases' end times, P (K, 4, 8) each phase's start
    position, velocity, acceleration and jerk (the eighth: after the end), B (K, 5, 2) the
    brake pieces' durations, positions, velocities, accelerations and jerks, Bd (K,) the
    brake's duration (as ``Trajectory.at_time``'s state_to_integrate_from)."""
    N, K = ts.shape[0], T.shape[0]
    q, qd, qdd = np.empty((N, K)), np.empty((N, K)), np.empty((N, K))
    for n in range(N):
        for k in range(K):
            t = ts[n]
            if Bd[k] > 0.0 and t < Bd[k]:
                i = 0 if t < B[k, 0, 0] else 1
                if i > 0:
                    t -= B[k, 0, 0]
                p0, v0, a0, j = B[k, 1, i], B[k, 2, i], B[k, 3, i], B[k, 4, i]
            else:
                if Bd[k] > 0.0:
                    t -= Bd[k]
                i = 7
                for m in range(7):
                    if t < T[k, m]:
                        i = m
                        break
                if i > 0:
                    t -= T[k, i - 1]
                p0, v0, a0, j = P[k, 0, i], P[k, 1, i], P[k, 2, i], P[k, 3, i]
            q[n, k] = p0 + t * (v0 + t * (a0 / 2.0 + t * j / 6.0))
            qd[n, k] = v0 + t * (a0 + t * j / 2.0)
            qdd[n, k] = a0 + t * j
    return q, qd, qdd
