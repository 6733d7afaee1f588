"""The exact decision on a path some of whose segments passed it before: :func:`route_decision`.

A roadmap's edges pass :func:`~chekhov.collision.path_check.motion_certified` when it is built
(``RoadmapConfig.certify_edges``): each edge, resampled and checked at the certification's
substeps, with the motion between its samples proved free. A route through the roadmap
holds those edges as its segments, so in the world the roadmap was built for (its scene and
robot, no dynamic obstacle since) they need not be checked again. What an edge's own check
leaves out is its two ends' *cells*: :func:`exact_path_decision
<chekhov.collision.path_check.exact_path_decision>` proves the motion over the half-steps on
either side of each sample, except at a path's first and last configurations, which it only
tests (a start or a goal may lie very near an object). So here

* every run of segments not known to pass is decided as a path of its own (its resampled
  waypoints, the certification's substeps), and
* every waypoint where a known segment meets another segment — a roadmap node inside the
  route — gets its cell decided: the three samples around it (the samples next to it at the
  certification's spacing on either side, and itself) as a path of their own with no
  substeps, so that its cell is the one the whole path's decision would have proved
  (:func:`~chekhov.collision.path_check.cells_free`: all of a route's together).

When all of them pass, the certificate is the one :func:`exact_path_decision` would have given
the whole resampled path. Measured against it in ``tests/test_route_check.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.exact import ExactChecker
from chekhov.collision.fast import FastChecker
from chekhov.collision.path_check import (
    CERTIFY_MAX_SEGMENT_RAD,
    CERTIFY_SUBSTEPS,
    PathCertificate,
    PathDecision,
    cells_free,
    exact_path_decision,
    path_digest,
)
from chekhov.paths import resample_counts, resample_path, segment_runs

Array = NDArray[np.float64]


class PassedRuns:
    """Runs of unknown segments that passed their decision in the world's current obstacles,
    by the digest of their samples, so that the same run is not decided again: a
    pick-and-place start recurs, and so does its connection to the roadmap (kept by the
    connector until the obstacles change) — on panda_cage through a tree beside the bars,
    30-47 ms to decide, 26 of 500 task cases over 20 ms. Forgotten when the fast checker's
    ``obstacles_version`` changes; at most ``capacity`` kept."""

    def __init__(self, capacity: int = 256) -> None:
        self.capacity = capacity
        self._digests: set[bytes] = set()
        self._version = -1

    def _current(self, fast: FastChecker) -> set[bytes]:
        if fast.obstacles_version != self._version:
            self._digests, self._version = set(), fast.obstacles_version
        return self._digests

    def has(self, fast: FastChecker, samples: Array) -> bool:
        """Whether the run ``samples`` (N, K) rad passed in ``fast``'s world as it is now."""
        return path_digest(samples) in self._current(fast)

    def add(self, fast: FastChecker, samples: Array) -> None:
        kept = self._current(fast)
        if len(kept) >= self.capacity:
            kept.clear()
        kept.add(path_digest(samples))


def route_decision(fast: FastChecker, exact: ExactChecker, path: Array,
                   known_free: NDArray[np.bool_], deadline: float = math.inf,
                   passed: PassedRuns | None = None) -> PathDecision:
    """:func:`~chekhov.collision.path_check.exact_path_decision` on ``path`` (T, K) rad resampled
    at :data:`CERTIFY_MAX_SEGMENT_RAD`, at :data:`CERTIFY_SUBSTEPS`, where the segments
    marked in ``known_free`` (T - 1,) passed :func:`motion_certified
    <chekhov.collision.path_check.motion_certified>` in this very world (the caller's
    promise; module docstring). The certificate names the resampled path, with
    ``resampled_from`` the path. valid None: ``deadline`` (``time.perf_counter()`` s) passed.
    ``passed``: runs decided before in this world, skipped (and the runs that pass now
    added)."""
    P = np.ascontiguousarray(path, dtype=np.float64)
    known = np.asarray(known_free, dtype=bool)
    if len(P) < 2 or known.shape != (len(P) - 1,):
        raise ValueError(f"known_free must be ({max(len(P) - 1, 0)},), got {known.shape}")
    D = resample_path(P, CERTIFY_MAX_SEGMENT_RAD)
    counts = resample_counts(P, CERTIFY_MAX_SEGMENT_RAD)
    if (counts == 0).any():     # a repeated waypoint: the whole path decided, as it is
        known = np.zeros_like(known)
    at = np.concatenate([[0], np.cumsum(counts)])     # P's waypoints in D
    for a, b in segment_runs(~known):             # waypoints a … b of P, joined by unknown segments
        run = D[at[a]:at[b] + 1]
        if passed is not None and passed.has(fast, run):
            continue
        valid = exact_path_decision(fast, exact, run, CERTIFY_SUBSTEPS, deadline).valid
        if valid is not True:
            return PathDecision(valid, None)
        if passed is not None:
            passed.add(fast, run)
    ends = [k for k in range(1, len(P) - 1) if known[k - 1] or known[k]]
    if ends:                               # the cells where a known segment ends
        valid = cells_free(fast, exact, np.stack([_cell(D, int(at[k])) for k in ends]),
                           deadline)
        if valid is not True:
            return PathDecision(valid, None)
    return PathDecision(True, PathCertificate(path_digest(D), CERTIFY_SUBSTEPS,
                                              fast.obstacles_version,
                                              resampled_from=path_digest(P)))


def _cell(D: Array, j: int) -> Array:
    """Sample j of the resampled path D and the samples on either side of it at the
    certification's spacing ((3, K)): the path whose decision proves j's cell."""
    q = D[j]
    n = CERTIFY_SUBSTEPS + 1
    return np.stack([q + (D[j - 1] - q) / n, q, q + (D[j + 1] - q) / n])
