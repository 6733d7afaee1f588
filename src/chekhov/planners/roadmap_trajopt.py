"""The paper's planner: a Chekhov roadmap seed, resampled to ≤ 0.16 rad, shortened and smoothed
by TrajOpt, validated exactly. It never returns a trajectory the exact checker rejects."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.distance_terms import TrajectoryDistances
from chekhov.collision.path_check import PathCertificate
from chekhov.errors import ChekhovError
from chekhov.planners.base import PlannerBase, PlanResult, path_length, resample_path
from chekhov.planners.query import PlanQuery
from chekhov.planners.shortcut import shortcut_path
from chekhov.planners.status import PlanStatus, Stage, StageReport, scalar_items
from chekhov.planners.trajopt_planner import TrajOptPlanner, optimise_report
from chekhov.roadmap.graph import Roadmap
from chekhov.roadmap.seeder import RoadmapSeeder, SeederConfig, SeedResult
from chekhov.robot.goal import Goal
from chekhov.trajopt.config import TrajOptConfig
from chekhov.trajopt.problem import build_trajopt, straight_line_seed
from chekhov.trajopt.solver import solve_trajopt
from chekhov.world import World

Array = NDArray[np.float64]


@dataclass(frozen=True)
class RoadmapTrajOptConfig:
    """Roadmap + TrajOpt's settings (see :class:`RoadmapTrajOpt` for what each does).

    Attributes:
        trajopt: TrajOpt's settings. seeder: the roadmap queries' settings.
        shortcut: shortcut each roadmap route greedily before TrajOpt.
        straight_line_first: TrajOpt from a straight line first, for at most
            ``straight_line_time_s`` s (False: the paper's planner, every query from the
            roadmap).
        straight_line_fallback: when the roadmap cannot connect or dynamic obstacles cut every
            route, TrajOpt from a straight line for at most ``fallback_time_s`` s.
        goal_routes: routes through the roadmap (one per goal IK solution) shortcut and
            compared; TrajOpt starts from the shortest.
    """

    trajopt: TrajOptConfig = field(default_factory=TrajOptConfig)
    seeder: SeederConfig = field(default_factory=SeederConfig)
    shortcut: bool = True
    straight_line_first: bool = True
    straight_line_time_s: float = 0.04
    straight_line_fallback: bool = True
    fallback_time_s: float = 0.25
    goal_routes: int = 6

    def __post_init__(self) -> None:
        for name in ("straight_line_time_s", "fallback_time_s"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and v >= 0):
                raise ChekhovError(f"RoadmapTrajOptConfig.{name}: must be a number of s >= 0, "
                                   f"got {v!r}")
        if not (isinstance(self.goal_routes, int) and self.goal_routes >= 1):
            raise ChekhovError(f"RoadmapTrajOptConfig.goal_routes: must be an integer >= 1, "
                               f"got {self.goal_routes!r}")


class RoadmapTrajOpt(PlannerBase):
    """Roadmap + TrajOpt (Dai et al.): seed from the roadmap against the world's current
    obstacles (dynamic ones included), optimise, check exactly at 100 substeps per segment.
    Its settings are a frozen :class:`RoadmapTrajOptConfig` (``config``); the names below are
    its fields.

    ``straight_line_first`` (default; False gives the paper's planner): first give TrajOpt
    ``straight_line_time_s`` (40 ms) from a straight line to the collision-free IK solution
    nearest the start, and use the roadmap only when that does not succeed. Most queries are
    then answered in the time of the straight line with its short paths, and the roadmap
    rescues the rest (measured: pole median 7 ms, 0% failures, paths within 1% of
    straight-line TrajOpt's, whose failures are 13%). ``info["seed_kind"]`` says which.

    With ``shortcut`` (default) the roadmap path is first shortcut greedily with the fast
    checker (waypoints a free straight motion can skip are dropped), so TrajOpt starts close
    to its optimum; ``info["roadmap_seed"]`` keeps the roadmap's own path.

    A pose goal has several IK solutions, and the route to each is a different seed: up to
    ``goal_routes`` (default 6) of them are routed through
    the roadmap and shortcut, and TrajOpt starts from the shortest (``info["goal_routes"]``
    how many were found). Measured on the kitchen's 95 report cases that straight-line TrajOpt
    fails: mean length 6.26 rad from one route, 5.62 from six, in the same time.

    When the roadmap cannot connect the start or goal ("no_connection", the paper's roadmap
    failure) or dynamic obstacles cut every route ("no_path"), ``straight_line_fallback``
    (default) runs TrajOpt from a straight line to the goal configuration instead
    (``info["fallback"] = "straight_line"``, ``info["roadmap_status"]`` the roadmap's status),
    for at most ``fallback_time_s`` seconds of optimisation.

    When TrajOpt ends with the goal pose unmet (the collision terms pulled the end away: its
    IK solution lies close to an obstacle), it runs once more from the same seed with the
    seed's end configuration (an IK solution of the pose) as a joint goal
    (``info["joint_goal_retry"]`` its status). Measured on the kitchen's 500 cases, with
    ``TrajOptConfig.accept_exact_clear``: 16 of 16 such cases then succeed.

    ``time_limit_s`` bounds the optimisation: each TrajOpt run gets what is left of it (at
    most its own ``config.time_limit_s``), and a query whose seed arrives after it ends with
    status "timeout". Roadmap connection (its RRT at most ``SeederConfig.tree_time_s``) and the
    exact validation of a result are not cut short.

    When the optimised trajectory fails the exact check, the (exactly checked) seed is returned
    with ``info["fallback_to_seed"] = True``; when that fails too, the result is a failure
    with status "collision". ``time_s`` includes the validation.
    """

    def __init__(self, world: World, roadmap: Roadmap,
                 config: RoadmapTrajOptConfig | None = None, *,
                 name: str = "Roadmap+TrajOpt") -> None:
        self.world = world
        self.roadmap = roadmap
        self.config = config if config is not None else RoadmapTrajOptConfig()
        self.seeder = RoadmapSeeder(world, roadmap, self.config.seeder)
        self.name = name
        self._trajopt = self.config.trajopt
        self._line_planner = TrajOptPlanner(world, self._trajopt)
        self._distances = TrajectoryDistances(world.fast)

    def _plan(self, query: PlanQuery) -> PlanResult:
        run = _Run(query)
        if self.config.straight_line_first:
            first = self._straight_line_try(run)
            if first is not None and first.success:
                return first
        if query.expired():
            return self._result(run, False, None, PlanStatus.TIMEOUT)
        t_seed = time.perf_counter()
        found = self.seeder.seeds(query.q_start, query.goal, self.config.goal_routes,
                                  deadline=query.deadline)
        s = found[0]
        run.timing["seed"] = s.timing_s.get("total", time.perf_counter() - t_seed)
        run.stages.append(StageReport(
            Stage.ROADMAP_SEED, PlanStatus.of(s.status), run.timing["seed"], s.path,
            {"routes": sum(f.path is not None for f in found), **scalar_items(s.info)}))
        if not s.success or s.path is None:
            return self._no_seed(run, s)
        t1 = time.perf_counter()
        # every route of a successful query has a path; the shortest after shortcutting wins
        s, short = min(((f, self._shortcut(f.path, query)) for f in found
                        if f.path is not None), key=lambda route: path_length(route[1]))
        run.timing["shortcut"] = time.perf_counter() - t1
        run.stages.append(StageReport(Stage.SHORTCUT, PlanStatus.SOLVED,
                                      run.timing["shortcut"], short))
        seed = resample_path(short, self._trajopt.max_step_rad)
        if len(seed) < 2:
            seed = np.vstack([seed, seed])
        if query.expired():
            return self._result(run, False, None, PlanStatus.TIMEOUT, seed,
                                {"seed_info": s.info}, seed_from=Stage.ROADMAP_SEED)
        return self._optimise_seed(run, s, seed, len(found))

    def _shortcut(self, path: Array, query: PlanQuery) -> Array:
        return shortcut_path(self.world.fast, path, deadline=query.deadline) \
            if self.config.shortcut else path

    def _result(self, run: _Run, success: bool, path: Array | None, status: PlanStatus,
                seed: Array | None = None, info: dict[str, object] | None = None,
                certificate: PathCertificate | None = None,
                seed_from: Stage | None = None) -> PlanResult:
        return PlanResult(success, path, status, time.perf_counter() - run.query.t0,
                          run.timing, seed=seed, info=info if info is not None else {},
                          certificate=certificate, stages=tuple(run.stages),
                          seed_from=seed_from)

    def _straight_line_try(self, run: _Run) -> PlanResult | None:
        """TrajOpt from a straight line to the collision-free IK solution nearest the start,
        for at most ``straight_line_time_s``; None when there is no such IK solution."""
        query, t0 = run.query, run.query.t0
        try:
            q_goal = self._line_planner.goal_configuration(
                query.q_start, query.goal,
                deadline=min(query.deadline, t0 + self.config.straight_line_time_s))
        except ChekhovError as e:
            q_goal = None
            run.stages.append(StageReport(Stage.IK, PlanStatus.NO_IK, time.perf_counter() - t0,
                                          detail={"error": str(e)}))
        run.timing["straight_line"] = time.perf_counter() - t0
        budget = min(self.config.straight_line_time_s, query.remaining())
        result = None
        if q_goal is not None and budget > 0:
            result = self._straight_line(run, q_goal, None, {}, budget)
        run.timing["straight_line"] = time.perf_counter() - t0
        return result

    def _no_seed(self, run: _Run, s: SeedResult) -> PlanResult:
        """The roadmap had no seed: a bounded straight-line TrajOpt when it could not connect
        or dynamic obstacles cut its routes (``straight_line_fallback``), else the failure."""
        query, status = run.query, PlanStatus.of(s.status)
        if self.config.straight_line_fallback and status in (PlanStatus.NO_CONNECTION,
                                                      PlanStatus.NO_PATH):
            q_goal = self._goal_configuration(query)
            budget = min(self.config.fallback_time_s, query.remaining())
            if q_goal is not None and budget > 0:
                return self._straight_line(run, q_goal, status, s.info, budget)
        return self._result(run, False, None, status, info={"seed_info": s.info},
                            seed_from=Stage.ROADMAP_SEED)

    def _optimise_seed(self, run: _Run, s: SeedResult, seed: Array, n_routes: int
                       ) -> PlanResult:
        """TrajOpt from the roadmap seed (and once more towards the seed's end configuration
        when a pose goal was lost to the collision terms); the seed itself when the optimised
        trajectory fails the exact check."""
        query, goal = run.query, run.query.goal
        t = time.perf_counter()
        cfg = self._trajopt.within(query.remaining())
        try:
            problem = build_trajopt(self.world, query.q_start, goal, seed, cfg, self._distances)
        except ChekhovError as e:
            return self._result(run, False, None, PlanStatus.BAD_PROBLEM, seed,
                                {"error": str(e)}, seed_from=Stage.ROADMAP_SEED)
        r = solve_trajopt(problem, query.deadline)
        run.timing["optimise"] = r.optimise_s
        run.timing["validate"] = r.timing_s["validate"]
        run.stages.append(optimise_report(r, time.perf_counter() - t))
        retry = None
        if (r.status == "infeasible" and goal.is_pose and r.unmet() - {"collision_m"}
                and not query.expired()):
            # the goal pose lost to the collision terms (its IK solution is near an obstacle):
            # again, with the seed's own end configuration, an IK solution of the pose, as goal
            t = time.perf_counter()
            retry = solve_trajopt(build_trajopt(
                self.world, query.q_start, Goal.configuration(seed[-1]), seed,
                self._trajopt.within(query.remaining()), self._distances), query.deadline)
            run.timing["optimise"] += retry.optimise_s
            run.timing["validate"] += retry.timing_s["validate"]
            run.stages.append(optimise_report(retry, time.perf_counter() - t, Stage.RETRY))
            if retry.success:
                r = retry
        info: dict[str, object] = {"seed_kind": "roadmap", "roadmap_seed": s.path,
                                   "goal_routes": n_routes, "trajopt_status": r.status,
                                   "iterations": r.iterations,
                                   "trajopt_cpu_s": r.info["cpu_s"],
                                   "trajectory": r.trajectory, "seed_info": s.info,
                                   "optimised_valid": r.valid, "fallback_to_seed": not r.success,
                                   "trajopt_timing_s": r.timing_s,
                                   "joint_goal_retry": None if retry is None else retry.status}
        if r.success:
            return self._result(run, True, r.trajectory, PlanStatus.SOLVED, seed, info,
                                r.certificate, seed_from=Stage.ROADMAP_SEED)
        # the seed (fast-free, ends at an IK solution of the goal): the certification's exact
        # check decides whether it is an answer
        run.stages.append(StageReport(Stage.FALLBACK, PlanStatus.SOLVED, 0.0, seed,
                                      {"to": "seed"}))
        return self._result(run, True, seed, PlanStatus.SOLVED, seed, info,
                            seed_from=Stage.ROADMAP_SEED)

    def _goal_configuration(self, query: PlanQuery) -> Array | None:
        """The goal configuration, or the pose goal's IK solution nearest the start."""
        goal = query.goal
        if goal.q is not None:
            return goal.q
        assert goal.T_world_ee is not None
        Q, _ = self.seeder.goal_configurations(goal.T_world_ee, deadline=query.deadline,
                                               near=query.q_start)
        return Q[0] if len(Q) else None

    def _straight_line(self, run: _Run, q_goal: Array, roadmap_status: PlanStatus | None,
                       seed_info: dict[str, object], budget_s: float) -> PlanResult:
        """TrajOpt from a straight line to q_goal for at most ``budget_s`` s of optimisation;
        never a colliding result (TrajOpt validates it). ``roadmap_status`` None marks the
        first attempt, before the roadmap; otherwise this is the fallback after it."""
        query = run.query
        stage = Stage.STRAIGHT_LINE if roadmap_status is None else Stage.FALLBACK
        fail = roadmap_status if roadmap_status is not None else PlanStatus.INFEASIBLE
        seed = straight_line_seed(query.q_start, q_goal, self._trajopt.n_waypoints)
        info: dict[str, object] = {
            "fallback": "straight_line" if roadmap_status else None,
            "seed_kind": "straight_line", "roadmap_status": roadmap_status or "",
            "seed_info": seed_info, "fallback_to_seed": False}
        t = time.perf_counter()
        try:
            cfg = self._trajopt.within(budget_s)
            problem = build_trajopt(self.world, query.q_start, query.goal, seed, cfg,
                                    self._distances)
        except ChekhovError as e:
            run.stages.append(StageReport(stage, PlanStatus.BAD_PROBLEM,
                                          time.perf_counter() - t, detail={"error": str(e)}))
            return self._result(run, False, None, fail, info={**info, "error": str(e)})
        r = solve_trajopt(problem, query.deadline)
        run.timing["optimise"] = r.optimise_s
        run.timing["validate"] = r.timing_s["validate"]
        run.stages.append(optimise_report(r, time.perf_counter() - t, stage))
        info.update({"trajopt_status": r.status, "iterations": r.iterations,
                     "trajopt_cpu_s": r.info["cpu_s"], "trajectory": r.trajectory,
                     "roadmap_seed": problem.seed, "optimised_valid": r.valid,
                     "trajopt_timing_s": r.timing_s})
        return self._result(run, r.success, r.trajectory if r.success else None,
                            PlanStatus.SOLVED if r.success else fail, problem.seed, info,
                            r.certificate, seed_from=stage)


class _Run:
    """One call's query, its timing breakdown (s) and its stage reports so far."""

    def __init__(self, query: PlanQuery) -> None:
        self.query = query
        self.timing: dict[str, float] = {}
        self.stages: list[StageReport] = []

