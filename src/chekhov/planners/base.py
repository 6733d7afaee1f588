"""The planner interface every planner implements, the base class that checks every query and
certifies every answer in one place, and goal IK helpers."""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from chekhov.world import World

from chekhov._heap import settle_heap
from chekhov.collision.exits import exact_exit
from chekhov.errors import TrajectoryError
from chekhov.paths import path_length, resample_path
from chekhov.planners.certify import certify
from chekhov.planners.query import PlanQuery, make_query
from chekhov.planners.result import PlanResult, Solution
from chekhov.planners.status import PlanStatus, Stage
from chekhov.planners.timed import timed_trajectory
from chekhov.robot.goal import Goal
from chekhov.timing import TimingConfig

Array = NDArray[np.float64]

TIMING_RESERVE_S = 0.05
"""s of the time limit that must be left for ``plan()`` to time its answer (toppra and the
exact re-check of the timed trajectory take 7-32 ms on the built-in scenes' answers)."""

CERTIFY_RESERVE = 0.1
"""Share of the remaining time a sampling planner's search keeps back for certifying its path
(:func:`search_deadline`)."""
CERTIFY_RESERVE_MAX_S = 0.05

__all__ = [
    "PlanResult",
    "Planner",
    "PlannerBase",
    "path_length",
    "resample_path",
    "search_deadline",
    "solve_goal_ik",
]


class Planner(Protocol):
    """A motion planner for one world (robot + scene + checkers)."""

    name: str

    def plan(self, q_start: Array, goal: Goal, time_limit_s: float = 10.0, *,
             on_solution: Callable[[Solution], None] | None = None) -> PlanResult:
        """Plan from q_start (K,) to the goal within time_limit_s seconds; ``on_solution``
        gets each certified answer as it is found."""
        ...


class PlannerBase(ABC):
    """What every chekhov planner shares: :meth:`plan` checks the query
    (:func:`~chekhov.planners.query.make_query`: a located
    :class:`~chekhov.errors.PlanningInputError` for malformed input), answers "invalid_start" /
    "invalid_goal" for ends in collision (the exact checker's decision), runs the planner's
    :meth:`_plan` and certifies its answer (:func:`~chekhov.planners.certify.certify`: start,
    joint limits, goal tolerance, exact collision check at 100 substeps, deadline). A
    subclass implements :meth:`_plan` and sets ``name`` and ``world``."""

    name: str
    world: World
    timing: TimingConfig | None = TimingConfig()
    """How every success's path is timed (``PlanResult.trajectory``, a
    :class:`~chekhov.trajectory.JointTrajectory` checked exactly like the path): after
    certification, when at least :data:`TIMING_RESERVE_S` of the time limit is left, so that
    ``plan()`` still returns by its deadline. Otherwise, or when no parameterisation succeeds,
    the certified path is the answer without a trajectory and ``info["timing_error"]`` says
    why. None: never timed."""

    fast_free_ends: bool = False
    """Whether :meth:`_plan` needs ends the fast checker accepts (a sampling planner whose
    validity test it is): :meth:`plan` then plans between exits (:meth:`_plan_between_exits`)."""

    def plan(self, q_start: Array, goal: Goal, time_limit_s: float = 10.0, *,
             on_solution: Callable[[Solution], None] | None = None) -> PlanResult:
        """Plan from q_start (K,) rad to the goal within time_limit_s (s; inf for none).
        ``on_solution`` is called with each certified answer as it is found (an anytime
        planner's first path and each improvement; once for the others)."""
        query = make_query(self.world.robot, q_start, goal, time_limit_s)
        query = replace(query, time_limit_s=self._budget_s(query.time_limit_s),
                        on_solution=on_solution)
        bad_end = self._end_in_collision(query)
        if bad_end is not None:
            result = PlanResult(False, None, bad_end, 0.0,
                                info={"error": f"{bad_end.value[8:]} configuration in collision"})
        elif self.fast_free_ends:
            result = self._plan_between_exits(query)
        else:
            result = self._plan(query)
        result = certify(self.world, query, result)
        if result.success and result.path is not None and not result.solutions:
            found = Solution(result.path, result.time_s, result.seed_from or Stage.SEARCH,
                             path_length(result.path))
            result = replace(result, solutions=(found,))
            if on_solution is not None:
                on_solution(found)
        if self.timing is not None and result.success and result.path is not None:
            left = query.remaining()
            if left >= TIMING_RESERVE_S:
                result = self._timed(result, result.path, self.timing)
            else:
                result = replace(result, info={
                    **result.info, "timing_error": f"not timed: {left * 1e3:.0f} ms of the "
                    f"time limit left, timing needs {TIMING_RESERVE_S * 1e3:.0f}"})
        return result

    def _timed(self, result: PlanResult, path: Array, timing: TimingConfig) -> PlanResult:
        """``result`` with its timed trajectory; without one, and ``info["timing_error"]``
        saying why, when no parameterisation succeeded (the path stays the answer)."""
        t = time.perf_counter()
        try:
            timed = timed_trajectory(self.world, path, timing)
        except TrajectoryError as e:
            return replace(result, info={**result.info, "timing_error": str(e)})
        return replace(result, trajectory=timed.trajectory, info={
            **result.info, "timing_method": timed.method,
            "time_parameterize_s": time.perf_counter() - t})   # after time_s: not in timing_s

    def _plan_between_exits(self, query: PlanQuery) -> PlanResult:
        """:meth:`_plan` for a planner that needs ends the fast checker accepts
        (``fast_free_ends``): an end it rejects (exactly free: checked before) is replaced by
        its exit (:func:`~chekhov.collision.exits.exact_exit`, a nearby fast-free
        configuration joined to it by an exactly free motion), and the answer gets the end
        back; "no_connection" when an end has no exit."""
        w = self.world
        ends = [query.q_start] + ([] if query.goal.q is None else [query.goal.q])
        if w.fast.valid(np.array(ends)).all():
            return self._plan(query)
        exits = [exact_exit(w.fast, w.exact, q, w.robot.lower, w.robot.upper, query.deadline)
                 for q in ends]
        found = [e for e in exits if e is not None]
        if len(found) < len(ends):
            status = PlanStatus.TIMEOUT if query.expired() else PlanStatus.NO_CONNECTION
            return PlanResult(False, None, status, time.perf_counter() - query.t0, info={
                "error": "an end the fast checker rejects (the exact one accepts it) has no "
                         "exactly free way out"})
        goal = query.goal if len(found) == 1 else Goal.configuration(found[1])
        result = self._plan(replace(query, q_start=found[0], goal=goal))
        if result.path is None:
            return result
        path = np.vstack([query.q_start, result.path, *ends[1:]])
        keep = np.ones(len(path), dtype=bool)    # no repeated configuration where none exited
        keep[1:] = np.abs(np.diff(path, axis=0)).max(axis=1) > 0.0
        return replace(result, path=path[keep], info={**result.info, "exits": True})

    def warmup(self, *, seed: int = 0, time_limit_s: float = 1.0) -> float:
        """Do once what a first query would (compile or load the numba kernels, fill caches):
        plan between two random collision-free configurations (drawn with ``seed``) towards
        the second's end-effector pose, and discard the answer; then freeze the objects
        alive out of the garbage collector's way (:func:`chekhov._heap.settle_heap`: a full
        collection over them took 33-53 ms inside a timed call). Returns the time it took
        (s). Call it before timing a planner or before a robot must react."""
        t0 = time.perf_counter()
        robot = self.world.robot
        Q = robot.sample_uniform(np.random.default_rng(seed), 64)
        Q = Q[self.world.fast.valid(Q)]
        if len(Q) >= 2:
            self.plan(Q[0], Goal.pose(robot.compute_ee_pose(Q[1])), time_limit_s)
        settle_heap()
        return time.perf_counter() - t0

    @abstractmethod
    def _plan(self, query: PlanQuery) -> PlanResult:
        """Answer a checked query (its ``deadline`` is the promise to keep)."""

    def _budget_s(self, time_limit_s: float) -> float:
        """The whole call's time limit (s) for a ``time_limit_s`` argument (the same, unless a
        planner documents otherwise)."""
        return time_limit_s

    def _end_in_collision(self, query: PlanQuery) -> PlanStatus | None:
        """INVALID_START / INVALID_GOAL when that end configuration collides (the fast
        checker, confirmed by the exact one), else None."""
        ends = [(PlanStatus.INVALID_START, query.q_start)]
        if query.goal.q is not None:
            ends.append((PlanStatus.INVALID_GOAL, query.goal.q))
        for status, q in ends:
            if not self.world.fast.is_valid(q) and not self.world.exact.is_valid(q):
                return status
        return None


def solve_goal_ik(world: World, query: PlanQuery, n_ik: int, timing: dict[str, float],
                  info: dict[str, object]) -> Array | None:
    """Goal configurations (n, K) for a sampling planner's query: ``goal.q``, or up to ``n_ik``
    collision-free (fast checker) IK solutions of the goal pose from the world's goal
    resolver, nearest the start first. Records ``timing["ik"]`` (s) and
    ``info["ik_solutions"]`` (or ``info["error"]``); None when the goal has no IK solution
    before the deadline (the planner then answers "no_ik")."""
    t0 = query.t0
    if query.goal.q is not None:
        goals = query.goal.q[None, :]
    else:
        found = world.goal_ik.resolve(query.goal, n=n_ik, near=query.q_start,
                                      deadline=query.deadline)
        if len(found) == 0:
            timing["ik"] = time.perf_counter() - t0
            info["error"] = f"goal pose: {found.reason}"
            return None
        goals = found.Q
    timing["ik"] = time.perf_counter() - t0
    info["ik_solutions"] = len(goals)
    return goals


def search_deadline(query: PlanQuery, now: float) -> float:
    """The deadline (``time.perf_counter()`` s) a planner's search keeps at ``now``: the
    query's, less :data:`CERTIFY_RESERVE` of the time left (at most
    :data:`CERTIFY_RESERVE_MAX_S`), so that the certification of what it finds still ends by
    the query's deadline."""
    left = query.deadline - now
    return query.deadline - min(CERTIFY_RESERVE * left, CERTIFY_RESERVE_MAX_S)
