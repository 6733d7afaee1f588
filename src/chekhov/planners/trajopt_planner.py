"""TrajOpt as a planner: a straight-line seed (the paper's baseline), or any planner's path as
the seed (the paper's Table II combinations)."""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.trajectory_distances import TrajectoryDistances
from chekhov.errors import ChekhovError, IKError
from chekhov.planners.base import Planner, PlannerBase, PlanResult
from chekhov.planners.query import PlanQuery
from chekhov.planners.status import PlanStatus, Stage, StageReport
from chekhov.robot.goal import Goal
from chekhov.trajopt.config import TrajOptConfig
from chekhov.trajopt.problem import build_trajopt, straight_line_seed
from chekhov.trajopt.result import TrajOptResult
from chekhov.trajopt.solver import solve_trajopt
from chekhov.world import World

Array = NDArray[np.float64]


class TrajOptPlanner(PlannerBase):
    """TrajOpt from a straight line of ``config.n_waypoints`` waypoints (default 30) to the
    collision-free IK solution of the goal pose nearest the start; the goal stays a pose
    constraint during the optimisation."""

    def __init__(self, world: World, config: TrajOptConfig | None = None,
                 name: str = "TrajOpt") -> None:
        self.world = world
        self.config = config if config is not None else TrajOptConfig()
        self.name = name
        self._distances = TrajectoryDistances(world.fast)
        world.goal_ik.warmup()   # its IK kernel compiles now, not in the first timed query

    def goal_configuration(self, q_start: Array, goal: Goal, n_solutions: int = 6,
                           deadline: float = math.inf) -> Array:
        """The goal configuration, or for a pose goal the collision-free IK solution nearest
        q_start among up to ``n_solutions`` (the world's goal resolver); nothing new starts
        after ``deadline`` (``perf_counter`` value, s). Raises ChekhovError when none is
        found."""
        if goal.q is not None:
            return goal.q
        try:
            return self.world.goal_ik.nearest(goal, q_start, n=n_solutions, deadline=deadline)
        except IKError as e:
            raise ChekhovError(f"goal pose: {e}") from e

    def _plan(self, query: PlanQuery) -> PlanResult:
        t0, q_start, goal = query.t0, query.q_start, query.goal
        try:
            q_goal = self.goal_configuration(q_start, goal, deadline=query.deadline)
        except ChekhovError as e:
            t_ik = time.perf_counter() - t0
            return PlanResult(False, None, PlanStatus.NO_IK, t_ik, info={"error": str(e)},
                              stages=(StageReport(Stage.IK, PlanStatus.NO_IK, t_ik,
                                                  detail={"error": str(e)}),))
        t_ik = time.perf_counter() - t0
        seed = straight_line_seed(q_start, q_goal, self.config.n_waypoints)
        ik = StageReport(Stage.IK, PlanStatus.SOLVED, t_ik, q_goal[None])
        line = StageReport(Stage.STRAIGHT_LINE, PlanStatus.SOLVED, 0.0, seed)
        return _optimise(self.world, self.config, self._distances, q_start, goal, seed,
                         query.remaining(), t0, {"ik": t_ik}, (ik, line), Stage.STRAIGHT_LINE)


class SeededTrajOpt(PlannerBase):
    """Any planner's path as the seed of TrajOpt (resampled to ≤ ``config.max_step_rad``).

    The seed planner gets ``time_limit_s``; TrajOpt then gets its own ``config.time_limit_s``
    (the paper adds the two stages' times). ``last_seed_result`` holds the seed planner's
    result of the last ``plan`` call (the benchmark records it as the seed planner's run)."""

    def __init__(self, world: World, seed_planner: Planner,
                 config: TrajOptConfig | None = None) -> None:
        self.world = world
        self.seed_planner = seed_planner
        if isinstance(seed_planner, PlannerBase):
            seed_planner.timing = None   # its path is a seed: only the final answer is timed
        self.config = config if config is not None else TrajOptConfig()
        self.name = f"{seed_planner.name}+TrajOpt"
        self._distances = TrajectoryDistances(world.fast)
        self.last_seed_result: PlanResult | None = None

    def _budget_s(self, time_limit_s: float) -> float:
        return time_limit_s + self.config.time_limit_s

    def _plan(self, query: PlanQuery) -> PlanResult:
        t0, q_start, goal = query.t0, query.q_start, query.goal
        self.last_seed_result = None
        seeded = self.seed_planner.plan(q_start, goal,
                                        query.time_limit_s - self.config.time_limit_s)
        self.last_seed_result = seeded
        report = StageReport(Stage.SEED, seeded.status, seeded.time_s, seeded.path,
                             {"planner": self.seed_planner.name})
        if not seeded.success or seeded.path is None:
            return PlanResult(False, None, seeded.status, time.perf_counter() - t0,
                              timing_s={"seed": seeded.time_s}, info=dict(seeded.info),
                              stages=(report,), seed_from=Stage.SEED)
        # TrajOpt gets its own budget (config.time_limit_s), as in the paper, where the two
        # stages' times add up: optimal seed planners use all of time_limit_s
        return _optimise(self.world, self.config, self._distances, q_start, goal, seeded.path,
                         min(self.config.time_limit_s, query.remaining()), t0,
                         {"seed": seeded.time_s}, (report,), Stage.SEED)


def _optimise(world: World, config: TrajOptConfig, distances: TrajectoryDistances,
              q_start: Array, goal: Goal, seed: Array, time_limit_s: float, t0: float,
              timing: dict[str, float], stages: tuple[StageReport, ...], seed_from: Stage
              ) -> PlanResult:
    """Run TrajOpt on a seed for at most ``time_limit_s`` (s) and wrap the outcome as a
    PlanResult (after the reports of the ``stages`` before it)."""
    t = time.perf_counter()
    deadline = t + time_limit_s
    cfg = config.within(time_limit_s)
    try:
        problem = build_trajopt(world, q_start, goal, seed, cfg, distances)
    except ChekhovError as e:
        bad = StageReport(Stage.OPTIMISE, PlanStatus.BAD_PROBLEM, time.perf_counter() - t,
                          detail={"error": str(e)})
        return PlanResult(False, None, PlanStatus.BAD_PROBLEM, time.perf_counter() - t0,
                          info={"error": str(e)}, stages=(*stages, bad), seed_from=seed_from)
    r = solve_trajopt(problem, deadline)
    timing = {**timing, "optimise": r.optimise_s, "validate": r.timing_s["validate"]}
    status = trajopt_status(r.status, r.success)
    return PlanResult(
        success=r.success, path=r.trajectory if r.success else None,
        status=status, time_s=time.perf_counter() - t0,
        timing_s=timing, seed=problem.seed, certificate=r.certificate,
        info={"trajopt_status": r.status, "iterations": r.iterations,
              "trajopt_cpu_s": r.info["cpu_s"],
              "violations": r.violations, "trajectory": r.trajectory,
              "trajopt_timing_s": r.timing_s},
        stages=(*stages, optimise_report(r, time.perf_counter() - t)), seed_from=seed_from)


def trajopt_status(status: str, success: bool) -> PlanStatus:
    """The plan status of a TrajOpt run: SOLVED, or its failure (INFEASIBLE, COLLISION,
    TIMEOUT)."""
    return PlanStatus.SOLVED if success else PlanStatus.of(status)


def optimise_report(r: TrajOptResult, time_s: float, stage: Stage = Stage.OPTIMISE
                    ) -> StageReport:
    """The report of a TrajOpt run (``time_s``: s, with building its problem)."""
    return StageReport(stage, trajopt_status(r.status, r.success), time_s, r.trajectory,
                       {"trajopt_status": r.status, "iterations": r.iterations,
                        "valid": r.valid})
