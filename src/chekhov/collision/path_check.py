"""The exact checker's decision on a whole path, fast, and the certificate it leaves.

The conservative fast checker screens every configuration at ``substeps`` per segment, and coal
looks only where it raises an alarm. Since the fast checker's spheres contain the robot's
collision geometry (fast free ⇒ exact free), the path is exactly free iff coal finds every
flagged stretch free. A passed check returns a :class:`PathCertificate` bound to the path's
bytes, the substeps and the checkers' obstacle version, so that a later certification of the
very same path in the very same world (``chekhov.planners.certify``) need not run it again.
"""

from __future__ import annotations

import hashlib
import math
import time
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.exact import ExactChecker, densify
from chekhov.collision.fast import FastChecker

Array = NDArray[np.float64]

CHUNK_SEGMENTS = 2
"""Segments screened per fast-checker call: the deadline is looked at between calls."""
EXACT_WINDOW = 4
"""Configurations coal checks from an alarm before the fast walk resumes (and the deadline is
looked at again)."""


@dataclass(frozen=True)
class PathCertificate:
    """Proof that :func:`exact_path_decision` passed a path.

    Attributes:
        digest: SHA-1 of the path's float64 bytes and shape.
        substeps: interpolated configurations per segment that were checked.
        obstacles_version: the fast checker's ``obstacles_version`` at the check.
    """

    digest: bytes
    substeps: int
    obstacles_version: int

    def covers(self, path: Array, substeps: int, fast: FastChecker) -> bool:
        """Whether this certificate is for ``path`` at exactly ``substeps`` (a denser check
        does not contain a sparser one's configurations) in ``fast``'s world as it is now."""
        return (self.substeps == substeps and self.obstacles_version == fast.obstacles_version
                and self.digest == path_digest(path))


class PathDecision(NamedTuple):
    """valid: True / False, or None when the deadline passed first; certificate when True."""

    valid: bool | None
    certificate: PathCertificate | None


def path_digest(path: Array) -> bytes:
    P = np.ascontiguousarray(path, dtype=np.float64)
    return hashlib.sha1(P.tobytes() + str(P.shape).encode()).digest()


def exact_path_decision(fast: FastChecker, exact: ExactChecker, path: Array,
                        substeps: int = 100, deadline: float = math.inf) -> PathDecision:
    """Whether every waypoint of ``path`` (T, K) rad and ``substeps`` interpolated
    configurations per segment are collision-free by the exact checker's decision, or None
    when ``deadline`` (a ``time.perf_counter()`` value, s) passed before the decision.

    The fast checker walks :data:`CHUNK_SEGMENTS` segments at a time with clearance
    certificates; from each configuration it flags, coal checks
    the next :data:`EXACT_WINDOW` configurations of that segment, and the fast walk resumes
    after them.
    """
    P = np.ascontiguousarray(path, dtype=np.float64)
    last = len(P) - 1
    for a in range(0, max(last, 1), CHUNK_SEGMENTS):
        if time.perf_counter() > deadline:
            return PathDecision(None, None)
        ok = _chunk_free(fast, exact, P[a:min(a + CHUNK_SEGMENTS, last) + 1], substeps,
                         deadline)
        if ok is not True:
            return PathDecision(ok, None)
    return PathDecision(True, PathCertificate(path_digest(P), int(substeps),
                                              fast.obstacles_version))


def _chunk_free(fast: FastChecker, exact: ExactChecker, P: Array, substeps: int,
                deadline: float) -> bool | None:
    """:func:`exact_path_decision` on a few segments P (t, K)."""
    dense: Array | None = None
    n = substeps + 1
    i = fast.first_dense_collision(P, substeps)
    while i is not None:
        if time.perf_counter() > deadline:
            return None
        if dense is None:
            dense = densify(P, substeps)
        # coal, configuration by configuration, over a window, at most to the segment's far
        # end (conservative advancement's first distances cost more than a few collision
        # tests: a window of 4 near contact took 4.7 ms that way on the Panda, 0.4 ms so)
        end = min(len(dense), (i // n + 1) * n + 1, i + EXACT_WINDOW)
        if exact.first_collision_brute(dense[i:end]) is not None:
            return False
        if end >= len(dense):
            return True
        i = fast.first_dense_collision(P, substeps, start=end)
    return True
