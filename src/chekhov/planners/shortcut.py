"""Greedy shortcutting of a waypoint path with batched motion checks."""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.fast import FastChecker

Array = NDArray[np.float64]


def shortcut_path(fast: FastChecker, path: Array, resolution: float = 0.02,
                  deadline: float = math.inf, *, clearance_m: float = 0.0) -> Array:
    """The path (T, K) with every waypoint skipped that a straight, collision-free motion can
    jump over: from each kept waypoint, go to the farthest later waypoint it sees (free at
    ``resolution``, rad, with ``clearance_m``: ``FastChecker.motions_valid``). The result's
    waypoints are a subsequence of the input's, its new segments are free at ``resolution``,
    and it is never longer (the path's own segments are assumed free, as a planner's are).
    After ``deadline`` (a ``time.perf_counter()`` value, s) the rest of the path is kept as
    it is."""
    P = np.atleast_2d(np.asarray(path, dtype=float))
    keep = [0]
    i = 0
    while i < len(P) - 1:
        j = _farthest_jump(fast, P, i, resolution, deadline, clearance_m)
        keep.append(j)
        i = j
    return P[keep]


def _farthest_jump(fast: FastChecker, P: Array, i: int, resolution: float,
                   deadline: float, clearance_m: float) -> int:
    """The farthest waypoint after i of P (T, K) that a straight motion from P[i] reaches
    free at ``resolution``, i + 1 when none is (or the deadline has passed): the candidates
    farthest first in one call that stops at the first free one. (Screening them at 0.1 rad
    first, then confirming, as before: 12-20% slower on the shortcuts of 40 task cases'
    routes in shelf_boxes and panda_cage, the same paths; bisection order finds a blocked
    motion's collision early anyway.)"""
    later = np.arange(len(P) - 1, i + 1, -1)
    start = np.repeat(P[i:i + 1], len(later), axis=0)
    found = fast.first_free_motion(start, P[later], resolution, deadline,
                                   clearance_m=clearance_m)
    return i + 1 if found is None else int(later[found])


def partial_shortcut(fast: FastChecker, path: Array, rng: np.random.Generator, *,
                     rounds: int = 8, pairs: int = 16, resolution: float = 0.02,
                     deadline: float = math.inf, clearance_m: float = 0.0) -> Array:
    """Shortcuts between points anywhere on the path, not only its waypoints (OMPL's
    ``shortcutPath``): each round draws ``pairs`` random pairs of points along the path (T, K),
    checks their straight motions in one batch at ``resolution`` rad (with ``clearance_m``:
    ``FastChecker.motions_valid``), and splices in the free one that saves the most length.
    The ends stay; the result is never longer, and its new segments are free at
    ``resolution``. No round starts after ``deadline`` (``time.perf_counter()`` value, s)."""
    P = np.atleast_2d(np.asarray(path, dtype=float))
    for _ in range(rounds):
        if len(P) < 3 or time.perf_counter() >= deadline:
            break
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
        S = np.sort(rng.uniform(0.0, cum[-1], size=(pairs, 2)), axis=1)
        i = np.clip(np.searchsorted(cum, S, side="right") - 1, 0, len(P) - 2)
        keep = i[:, 0] < i[:, 1]           # on one segment the path is already straight
        if not keep.any():
            continue
        S, i = S[keep], i[keep]
        seg = np.maximum(cum[i + 1] - cum[i], 1e-12)
        t = (S - cum[i]) / seg
        A = P[i[:, 0]] + t[:, :1] * (P[i[:, 0] + 1] - P[i[:, 0]])
        B = P[i[:, 1]] + t[:, 1:] * (P[i[:, 1] + 1] - P[i[:, 1]])
        saved = (S[:, 1] - S[:, 0]) - np.linalg.norm(B - A, axis=1)
        k = _most_saving_free(fast, A, B, saved, resolution, deadline, clearance_m)
        if k < 0:
            continue
        P = np.vstack([P[: i[k, 0] + 1], A[k], B[k], P[i[k, 1] + 1:]])
        steps = np.abs(np.diff(P, axis=0)).max(axis=1)
        P = P[np.concatenate([[True], steps > 1e-12])]   # drop repeated points
    return P


def _most_saving_free(fast: FastChecker, A: Array, B: Array, saved: Array,
                      resolution: float, deadline: float = math.inf,
                      clearance_m: float = 0.0) -> int:
    """Index of the free motion A[i] → B[i] (n, K) that saves the most (``saved`` (n,) rad,
    more than 1e-6; the first such index on ties), or -1 — also when ``deadline``
    (``time.perf_counter()`` value, s) passes before one is found. The motions are checked
    in that order, in one compiled call, so those after the answer are never checked
    (measured on 80 Panda paths, 16 pairs a round, when they were checked one call each:
    partial_shortcut took 51-57% less time than when it checked all 16 in one batch)."""
    order = np.argsort(-saved, kind="stable")
    order = order[saved[order] > 1e-6]
    found = fast.first_free_motion(A[order], B[order], resolution, deadline,
                                   clearance_m=clearance_m)
    return -1 if found is None else int(order[found])
