"""The planner interface every planner implements, its result, and path utilities."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from itertools import pairwise
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from chekhov.world import World

from chekhov.errors import IKError
from chekhov.robot.goal import Goal

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class PlanResult:
    """What a planner returns.

    Attributes:
        success: a path was found that the planner's own checks accept.
        path: waypoints (T, K), rad, first row the start; None on failure.
        status: short machine-readable reason, e.g. "solved", "timeout", "no_ik",
            "no_connection", "collision".
        time_s: wall time of ``plan`` (s).
        timing_s: breakdown of ``time_s`` by phase (s), e.g. {"ik": .., "seed": .., "optimise": ..}.
        seed: the seed path (T', K) an optimising planner started from, when there was one.
        info: anything else worth reporting (iterations, flags such as "fallback_to_seed").
    """

    success: bool
    path: Array | None
    status: str
    time_s: float
    timing_s: dict[str, float] = field(default_factory=dict)
    seed: Array | None = None
    info: dict[str, object] = field(default_factory=dict)

    @property
    def path_length(self) -> float:
        """Joint-space length of the path (rad): sum of segment L2 norms; nan without a path."""
        return path_length(self.path) if self.path is not None else float("nan")


class Planner(Protocol):
    """A motion planner for one world (robot + scene + checkers)."""

    name: str

    def plan(self, q_start: Array, goal: Goal, time_limit_s: float = 10.0) -> PlanResult:
        """Plan from q_start (K,) to the goal within time_limit_s seconds."""
        ...


def path_length(path: Array) -> float:
    """Sum of joint-space L2 segment lengths of a (T, K) path, rad."""
    P = np.asarray(path, dtype=float)
    return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum()) if len(P) > 1 else 0.0


def resample_path(path: Array, max_step: float = 0.16) -> Array:
    """The path (T, K) with each segment split evenly so that adjacent waypoints are at most
    ``max_step`` rad apart (joint-space L2, the paper's 0.16 rad pre-processing). Waypoints of
    the input are kept; repeated waypoints are dropped."""
    P = np.atleast_2d(np.asarray(path, dtype=float))
    out = [P[0]]
    for a, b in pairwise(P):
        d = float(np.linalg.norm(b - a))
        if d < 1e-12:
            continue
        n = int(np.ceil(d / max_step - 1e-9))
        for i in range(1, n + 1):
            out.append(a + (b - a) * (i / n))
    return np.array(out)


def goal_configurations(world: World, goal: Goal, n_ik: int, rng: np.random.Generator
                        ) -> Array:
    """Goal configurations (n, K): ``goal.q``, or up to ``n_ik`` collision-free (fast checker)
    IK solutions of ``goal.T_world_ee``. Raises :class:`IKError` when there is none."""
    if goal.q is not None:
        return world.robot.check_configuration(goal.q, "goal configuration")[None, :]
    assert goal.T_world_ee is not None
    return world.solve_ik(goal.T_world_ee, n_solutions=n_ik, rng=rng)


def solve_goal_ik(world: World, goal: Goal, n_ik: int, rng: np.random.Generator, t0: float,
                  timing: dict[str, float], info: dict[str, object]) -> Array | None:
    """:func:`goal_configurations` for a sampling planner's query started at ``t0``: records
    ``timing["ik"]`` (s) and ``info["ik_solutions"]`` (or ``info["error"]``); None when the
    goal has no IK solution (the planner then answers "no_ik")."""
    try:
        goals = goal_configurations(world, goal, n_ik, rng)
    except IKError as e:
        timing["ik"] = time.perf_counter() - t0
        info["error"] = str(e)
        return None
    timing["ik"] = time.perf_counter() - t0
    info["ik_solutions"] = len(goals)
    return goals
