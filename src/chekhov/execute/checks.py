"""The executive's collision checks of its own motions: :class:`MotionChecks`.

A motion is checked against the obstacles the executive last predicted (a frame's sweep,
``predicted_obstacles``), which it hands over as ``seen``: the fast checker holds them already
(the executive sets them on every frame); the exact checker is given them only when a check
needs it (4 ms against the fast checker's 0.3). Each exact decision has a wall-clock budget
(``ExecutorConfig.check_budget_s``): cut, it answers the safe way — not free — and counts in
``Counters.undecided_checks``. Units: s, rad.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.path_check import exact_path_decision
from chekhov.execute.interface import Counters, ExecutorConfig
from chekhov.execute.motion import Bounds, Motion
from chekhov.execute.obstacles import Obstacles
from chekhov.world import World

Array = NDArray[np.float64]

MAX_SUBSTEP_RAD = 0.02
"""rad: :meth:`MotionChecks.free` decides a motion's samples at most this far apart."""


class MotionChecks:
    """Checks of the executive's motions in ``world`` (sampled every ``check_dt_s`` of
    ``config``), counting cut decisions in ``counters``."""

    def __init__(self, world: World, config: ExecutorConfig, bounds: Bounds,
                 counters: Counters) -> None:
        self.world, self.config, self.bounds, self.counters = world, config, bounds, counters
        self._exact_has: Obstacles | None = None

    def first_conflict(self, motion: Motion, t: float, seen: Obstacles) -> float | None:
        """The first time (s) from t at which ``motion`` is in collision with the fast
        checker's obstacles (``seen``: it never calls free what the exact one calls in
        collision, and the exact decision confirms its first alarm), or None."""
        if t >= motion.t_end:
            ts, Q = np.array([t]), motion.sample(t).q[None]
        else:
            ts, Q = motion.positions(t, motion.t_end, self.config.check_dt_s)
        ok = self.world.fast.valid(Q)
        if ok.all():
            return None
        i = int(np.argmin(ok))
        if self.exact_free(Q[i:], 1, seen):
            return None
        return float(ts[i])

    def free(self, motion: Motion, t: float, seen: Obstacles, until: float = math.inf
             ) -> bool:
        """Whether ``motion`` from t (to ``until``, s) is within the joint limits (no further
        out than its start, when that is out) and free of ``seen`` (the exact decision at the
        check step, and at ≤ :data:`MAX_SUBSTEP_RAD` steps)."""
        _, Q = motion.positions(t, min(motion.t_end, until), self.config.check_dt_s)
        lo, hi = self.bounds
        excess = float(max(np.max(lo - Q[0]), np.max(Q[0] - hi), 0.0))   # a start outside
        if not self.world.robot.within_limits(Q, tol=excess + 1e-9).all():
            return False
        step = float(np.abs(np.diff(Q, axis=0)).max(initial=0.0))
        return self.exact_free(Q, max(1, math.ceil(step / MAX_SUBSTEP_RAD)), seen)

    def exact_free(self, Q: Array, substeps: int, seen: Obstacles) -> bool:
        """The exact decision on the polyline Q (N, K) rad at ``substeps`` against ``seen``;
        False (the safe answer) when it takes longer than ``check_budget_s``."""
        if self._exact_has is not seen:
            self.world.exact.set_obstacles(seen)
            self._exact_has = seen
        budget = self.config.check_budget_s
        deadline = math.inf if budget is None else time.perf_counter() + budget
        valid = exact_path_decision(self.world.fast, self.world.exact, Q, substeps,
                                    deadline).valid
        if valid is None:
            self.counters.undecided_checks += 1
        return bool(valid)

    def forget_exact(self) -> None:
        """The exact checker's obstacles may have been changed by someone else (an inline
        worker planning in this world): set them again at the next exact check."""
        self._exact_has = None
