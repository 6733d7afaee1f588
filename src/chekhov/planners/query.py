"""A planning query, checked once for every planner: the start, the goal and the time limit.

Every planner's ``plan(q_start, goal, time_limit_s)`` goes through :func:`make_query` (see
:class:`chekhov.planners.base.PlannerBase`): malformed input raises
:class:`~chekhov.errors.PlanningInputError` naming the argument, whatever the planner.

Joint limits: a start or goal configuration more than :data:`LIMIT_TOLERANCE_RAD` outside the
robot's joint limits is an error; one within it (encoder noise, a value written with fewer
digits) is clamped onto the limit and the query says so (``clamped``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from chekhov.errors import PlanningInputError, RobotError
from chekhov.robot.goal import Goal
from chekhov.robot.robot import Robot

if TYPE_CHECKING:
    from chekhov.planners.result import Solution

Array = NDArray[np.float64]

LIMIT_TOLERANCE_RAD = 1e-6
"""rad: how far outside a joint limit a start or goal configuration is clamped, not refused."""


@dataclass(frozen=True, eq=False)
class PlanQuery:
    """A checked query.

    Attributes:
        q_start: (K,) rad, within the joint limits.
        goal: the goal; a configuration goal's ``q`` within the joint limits.
        time_limit_s: s, >= 0 (inf: no limit; 0: answer "timeout" at once).
        t0: ``time.perf_counter()`` when the query was made (s).
        clamped: which of "start" / "goal" were clamped onto the limits (within the tolerance).
        on_solution: called with each certified :class:`~chekhov.planners.result.Solution`
            as the planner finds it (``plan(..., on_solution=...)``); None: not called.
    """

    q_start: Array
    goal: Goal
    time_limit_s: float
    t0: float
    clamped: tuple[str, ...] = ()
    on_solution: Callable[[Solution], None] | None = None

    @property
    def deadline(self) -> float:
        """``time.perf_counter()`` value (s) by which the answer is due."""
        return self.t0 + self.time_limit_s

    def remaining(self) -> float:
        """Seconds left before the deadline (negative when past it)."""
        return self.deadline - time.perf_counter()

    def expired(self) -> bool:
        return time.perf_counter() >= self.deadline


def make_query(robot: Robot, q_start: object, goal: object, time_limit_s: object) -> PlanQuery:
    """Check a planning query for ``robot``; raises :class:`PlanningInputError` naming the
    argument (wrong length, non-finite, outside the joint limits, not a :class:`Goal`, a
    time limit that is NaN or negative)."""
    t0 = time.perf_counter()
    limit = _time_limit(time_limit_s)
    if not isinstance(goal, Goal):
        raise PlanningInputError(f"goal: expected a chekhov.Goal, got {type(goal).__name__}")
    clamped: list[str] = []
    q0 = _configuration(robot, q_start, "start configuration (q_start)")
    if not robot.within_limits(q0)[0]:
        clamped.append("start")
        q0 = np.clip(q0, robot.lower, robot.upper)
    if goal.q is not None:
        qg = _configuration(robot, goal.q, "goal configuration (goal.q)")
        if not robot.within_limits(qg)[0]:
            clamped.append("goal")
            goal = replace(goal, q=np.clip(qg, robot.lower, robot.upper))
    return PlanQuery(q0, goal, limit, t0, tuple(clamped))


def _time_limit(value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise PlanningInputError(f"time_limit_s: expected a number of seconds, got {value!r}")
    limit = float(value)
    if math.isnan(limit) or limit < 0:
        raise PlanningInputError(
            f"time_limit_s: expected a number of seconds >= 0 (inf for none), got {limit}")
    return limit


def _configuration(robot: Robot, q: object, what: str) -> Array:
    """q as (K,) float, finite, within the limits up to :data:`LIMIT_TOLERANCE_RAD`."""
    try:
        arr = np.asarray(q, dtype=float)
    except (TypeError, ValueError) as e:
        raise PlanningInputError(f"{what}: not a vector of numbers: {e}") from None
    if arr.shape != (robot.dof,):
        raise PlanningInputError(
            f"{what}: expected {robot.dof} joint values ({', '.join(robot.joint_names)}), "
            f"got {arr.size} (shape {arr.shape})")
    try:
        robot.check_configuration(arr, what)
    except RobotError as e:
        raise PlanningInputError(str(e)) from None
    over = np.maximum(robot.lower - arr, arr - robot.upper)
    bad = np.flatnonzero(over > LIMIT_TOLERANCE_RAD)
    if len(bad):
        j = int(bad[np.argmax(over[bad])])
        raise PlanningInputError(
            f"{what}: joint {robot.joint_names[j]} = {arr[j]:.6g} rad is outside its limits "
            f"[{robot.lower[j]:.6g}, {robot.upper[j]:.6g}] by {over[j]:.3g} rad"
            + (f" ({len(bad)} joints outside)" if len(bad) > 1 else ""))
    return arr
