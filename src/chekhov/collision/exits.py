"""A way out of the fast checker's false alarm: :func:`exact_exit`.

The fast checker's answer "in collision" is conservative (spheres, then the hulls of mesh
parts): a configuration it rejects may be exactly free — a UR5 mounted level with a table
has its upper arm's hull touch the tabletop while the mesh is clear, in 2% of the exactly
free configurations. Everything built on the fast checker (roadmap connections, the repair
tree, shortcuts) then refuses such a start or goal, although the planners' own end check
(the exact checker) accepts it. :func:`exact_exit` finds a nearby configuration the fast
checker accepts, joined to the end by a straight motion that the exact checker's path
decision (``path_check.exact_path_decision``) proves free: a planner plans from (or to) that
exit and adds the short certified motion. Units: rad.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.exact import ExactChecker
from chekhov.collision.fast import FastChecker
from chekhov.collision.path_check import exact_path_decision

Array = NDArray[np.float64]

EXIT_RADII_RAD = (0.02, 0.05, 0.1, 0.2, 0.4)
"""rad (joint-space L2): the distances at which exits are looked for, nearest first."""
EXIT_DIRECTIONS = 32
"""Random directions tried at each radius (the same ones every call: seeded)."""
EXIT_EXACT_TRIES = 4
"""Fast-free candidates at each radius whose motion gets the exact decision, at most."""
EXIT_SUBSTEPS = 100
"""Samples of the exit motion (the paper's check of a segment)."""


def exact_exit(fast: FastChecker, exact: ExactChecker, q: Array, lower: Array, upper: Array,
               deadline: float = math.inf) -> Array | None:
    """q (K,) itself when the fast checker finds it free; else the nearest configuration
    found (:data:`EXIT_RADII_RAD`, :data:`EXIT_DIRECTIONS`) within the limits ``lower`` /
    ``upper`` (K,) that the fast checker finds free and whose straight motion from q the
    exact decision proves free; None when there is none, or ``deadline``
    (``time.perf_counter()`` value, s) passed first."""
    q = np.asarray(q, dtype=float)
    if fast.is_valid(q):
        return q
    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(EXIT_DIRECTIONS, len(q)))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    for radius in EXIT_RADII_RAD:
        C = np.clip(q + radius * dirs, lower, upper)
        free = C[fast.valid(C)]
        order = np.argsort(np.linalg.norm(free - q, axis=1))
        for c in free[order[:EXIT_EXACT_TRIES]]:
            valid = exact_path_decision(fast, exact, np.vstack([q, c]), EXIT_SUBSTEPS,
                                        deadline).valid
            if valid is None:
                return None
            if valid:
                return c
    return None
