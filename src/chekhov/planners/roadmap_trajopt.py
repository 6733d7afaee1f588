"""The paper's planner, anytime: a Chekhov roadmap seed (or, when obstacles cut the roadmap, a
tree that connects into it), shortcut and certified — the first answer — then shortened and
smoothed by TrajOpt while time is left. It never returns a path the exact checker rejects."""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.route_check import PassedRuns, route_decision
from chekhov.collision.trajectory_distances import TrajectoryDistances
from chekhov.errors import ChekhovError
from chekhov.planners.anytime import AnytimeRun
from chekhov.planners.base import PlannerBase, PlanResult, path_length, resample_path
from chekhov.planners.query import PlanQuery
from chekhov.planners.roadmap_trajopt_config import RoadmapTrajOptConfig
from chekhov.planners.shortcut import partial_shortcut, shortcut_path
from chekhov.planners.status import PlanStatus, Stage, scalar_items
from chekhov.planners.trajopt_planner import optimise_report
from chekhov.roadmap.graph import Roadmap
from chekhov.roadmap.seeder import RoadmapSeeder, SeedResult
from chekhov.robot.goal import Goal
from chekhov.trajopt.problem import build_trajopt, straight_line_seed
from chekhov.trajopt.result import TrajOptResult
from chekhov.trajopt.solver import solve_trajopt
from chekhov.world import World

Array = NDArray[np.float64]


class RoadmapTrajOpt(PlannerBase):
    """Roadmap + TrajOpt (Dai et al.), anytime. Its settings are a frozen
    :class:`RoadmapTrajOptConfig` (``config``); the names below are its fields.

    1. **First answer.** Routes through the roadmap against the world's current obstacles
       (dynamic ones included) to up to ``goal_routes`` goal IK solutions; each is shortcut
       (``shortcut``: waypoints a free straight motion can skip are dropped) and the
       shortest is certified (exact check at 100 substeps; a fast-free path needs no coal
       call) and offered as the first solution (``plan(..., on_solution=...)`` hears of it).
       When the roadmap cannot connect the start or goal ("no_connection") or obstacles cut
       every route ("no_path"), ``repair`` grows a bidirectional tree that connects into the
       roadmap (:mod:`chekhov.roadmap.repair`) until the time limit: the query fails only
       when time runs out.
    2. **Improvements**, ending ``improve_time_s`` after the first answer (or
       ``improve_time_scale`` times the first answer's own time, when longer) and never later
       than :data:`FINISH_RESERVE_S` plus the first answer's checks' time before the
       offers' deadline (what follows them — certifying the waiting candidate, the final check —
       must fit), each offered and kept when certified and shorter: routes to more goal IK
       solutions (``goal_routes``), shortcuts between any two points (``simplify_rounds``),
       TrajOpt from a straight line to the IK solution nearest the start
       (``straight_line_first``; only when the first answer is longer than
       ``straight_line_ratio`` times the line and at most ``straight_line_max_blocked`` of it
       collides, or when there is no answer, then for up to ``fallback_time_s``), else
       TrajOpt from the simplified seed (towards the seed's own end configuration instead
       of the goal pose when the sphere model cannot clear that configuration, or once more
       towards it when the goal pose lost to the collision terms).

    ``result.solutions`` lists every certified answer with the time it came
    (``result.first_solution_s``); ``result.seed_from`` is the stage of the final answer's
    seed; ``info["seed_kind"]`` says which ("roadmap", "repair", "straight_line") and
    ``info["fallback_to_seed"]`` whether the answer is the shortcut seed although TrajOpt
    ran. ``straight_line_first=False`` is the paper's planner: every answer from the roadmap.
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
        self._distances = TrajectoryDistances(world.fast)
        self._passed_runs = PassedRuns()

    def _plan(self, query: PlanQuery) -> PlanResult:
        run = AnytimeRun(self.world, query)
        seed, seed_from, failure = self._first_answer(run)
        if failure in (PlanStatus.NO_IK, PlanStatus.INVALID_START, PlanStatus.INVALID_GOAL):
            return run.result(failure, seed_from=seed_from)
        self._improve(run, seed, seed_from)
        if run.best is None and query.expired():
            failure = PlanStatus.TIMEOUT
        best = run.best
        if best is not None and best.stage in (Stage.STRAIGHT_LINE, Stage.FALLBACK):
            seed_from = best.stage
        return run.result(failure, {"seed_kind": _KINDS.get(seed_from, "straight_line")},
                          seed_from=seed_from)

    # --- first answer ---------------------------------------------------------------------
    def _first_answer(self, run: AnytimeRun) -> tuple[Array | None, Stage | None, PlanStatus]:
        """(seed, the stage it came from, the roadmap's status): the shortcut roadmap (or
        repair) path, offered; (None, None, why) when there is none."""
        query = run.query
        t = time.perf_counter()
        # a first answer to improve on: the route cheapest to certify (ending at a roadmap node
        # of the goal's pose, when there is one); without improvements, the shortest
        found = self.seeder.seeds(query.q_start, query.goal, 1, deadline=query.deadline,
                                  goal_nodes_first=self.config.improve_time_s > 0)
        s = found[0]
        run.timing["seed"] = s.timing_s.get("total", time.perf_counter() - t)
        status = PlanStatus.of(s.status)
        run.report(Stage.ROADMAP_SEED, status, run.timing["seed"], s.path,
                   {"routes": sum(f.path is not None for f in found), **scalar_items(s.info)})
        paths = [f.path for f in found if f.path is not None]
        stage = Stage.ROADMAP_SEED
        if not paths and self.config.repair and status in _REPAIRABLE and not query.expired():
            paths, stage = self._repair(run), Stage.REPAIR
        if not paths:
            return None, None, status
        if stage is Stage.ROADMAP_SEED and self.config.improve_time_s > 0:
            self._offer_route(run, s)
        # with the route as the answer, the shortcut must leave the final check its time;
        # without, it ends by the offers' deadline, past which its path could not be
        # certified (it ran to the limit, and 3 ms queries that then failed returned 0.1-0.4
        # ms late: benchmarks/deadline.py)
        stop = run.offer_deadline - (0.0 if run.best is None else FINISH_RESERVE_S)
        t = time.perf_counter()
        seed = min((self._shortcut(run, p, stop) for p in paths), key=path_length)
        run.timing["shortcut"] = time.perf_counter() - t
        run.report(Stage.SHORTCUT, PlanStatus.SOLVED, run.timing["shortcut"], seed)
        run.offer(seed, Stage.SHORTCUT, seed=seed,
                  info={"roadmap_seed": paths[0], "fallback_to_seed": False})
        return seed, stage, status

    def _offer_route(self, run: AnytimeRun, route: SeedResult) -> None:
        """The roadmap's route itself, offered first when its edges need no check (they
        passed the certification's own when the roadmap was built, and no dynamic obstacle
        is in the world): only its connections to the roadmap and the cells at its nodes are
        decided (``collision.route_check``), so a certified answer comes before the
        shortcut, which then improves on it. Not with ``improve_time_s`` 0 (the executive's
        replans): the shortcut route is then the answer, and the route's check would only
        add to it."""
        assert route.path is not None
        t = time.perf_counter()
        known = self.seeder.certified_segments(route.path, route.node_path)
        if known.any():
            decision = route_decision(self.world.fast, self.world.exact, route.path, known,
                                      run.offer_deadline, self._passed_runs)
            if decision.certificate is not None:
                run.offer(route.path, Stage.ROADMAP_SEED, seed=route.path,
                          certificate=decision.certificate,
                          info={"roadmap_seed": route.path, "fallback_to_seed": False})
        run.timing["route_check"] = time.perf_counter() - t

    def _repair(self, run: AnytimeRun) -> list[Array]:
        """The tree repair's path (a list of one), or an empty list."""
        query = run.query
        Q_goal = self._goal_configurations(query, self.config.seeder.repair.goal_roots)
        if len(Q_goal) == 0:
            return []
        reserve = min(0.05, self.config.repair_reserve * query.remaining())
        r = self.seeder.repair(query.q_start, Q_goal, query.deadline - reserve)
        run.timing["repair"] = r.time_s
        outcome = PlanStatus.SOLVED if r.success else (
            PlanStatus.TIMEOUT if r.status == "timeout" else PlanStatus.NO_PATH)
        run.report(Stage.REPAIR, outcome, r.time_s, r.path, scalar_items(r.info))
        return [] if r.path is None else [r.path]

    def _shortcut(self, run: AnytimeRun, path: Array, stop: float | None = None) -> Array:
        """``path`` shortcut (when ``shortcut`` is on) until ``stop`` (perf_counter s; the
        query's deadline by default). A route shortcut before in this query, to the end, is
        not shortcut again (the shortcut is deterministic, the world the same): the routes
        stage's routes often include the first answer's (48 of 362 shortcuts of 60
        shelf_boxes task cases, 0.56 of 4.4 ms a case)."""
        if not self.config.shortcut:
            return path
        deadline = run.query.deadline if stop is None else stop
        key = path.tobytes()
        done = run.shortcuts.get(key)
        if done is not None:
            return done
        short = shortcut_path(self.world.fast, path, deadline=deadline,
                              clearance_m=self.config.shortcut_clearance_m)
        if time.perf_counter() < deadline:    # not cut short
            run.shortcuts[key] = short
        return short

    # --- improvements ---------------------------------------------------------------------
    def _improve(self, run: AnytimeRun, seed: Array | None, seed_from: Stage | None) -> None:
        """Straight-line TrajOpt when it promises a shorter path (or there is no seed), else
        TrajOpt from the seed; nothing starts ``improve_time_s`` after the first answer."""
        query, cfg = run.query, self.config
        # room for certifying a waiting candidate (as long as the first answer's checks took:
        # the route's and its offer's) and for the final check
        stop = run.offer_deadline - FINISH_RESERVE_S - run.timing.get("offers", 0.0) \
            - run.timing.get("route_check", 0.0)
        if run.best is not None:
            now = time.perf_counter()
            budget = 0.0 if cfg.improve_time_s == 0 else max(   # 0: no improvements
                cfg.improve_time_s, cfg.improve_time_scale * (now - query.t0))
            stop = min(stop, now + budget)
            run.certify_improvements_by(stop + budget)
        # each stage starts only before the stop (a stage looks at it between its steps, but
        # its first step, e.g. the goal's IK solutions, takes ~0.7 ms)
        if (seed is not None and seed_from is Stage.ROADMAP_SEED and cfg.goal_routes > 1
                and time.perf_counter() < stop):
            seed = self._more_routes(run, seed, stop)
        if seed is not None and cfg.simplify_rounds > 0 and time.perf_counter() < stop:
            seed = self._simplify(run, seed, stop)
        line_ok = False
        q_line = self._line_goal(run, seed) if time.perf_counter() < stop else None
        if q_line is not None:
            budget = cfg.straight_line_time_s if seed is not None else cfg.fallback_time_s
            stage = Stage.STRAIGHT_LINE if seed is not None else Stage.FALLBACK
            line = straight_line_seed(query.q_start, q_line, self._trajopt.n_waypoints)
            line_ok = self._optimise(run, line, stage,
                                     min(stop, time.perf_counter() + budget), "straight_line")
        if seed is not None and not line_ok and time.perf_counter() < stop:
            seed = resample_path(seed, self._trajopt.max_step_rad)
            if len(seed) < 2:
                seed = np.vstack([seed, seed])
            assert seed_from is not None
            goal = self._seed_goal(run, seed)
            if goal is not None:
                self._optimise(run, seed, Stage.OPTIMISE, stop, _KINDS[seed_from], goal=goal,
                               retry=True, abandon=True)

    def _more_routes(self, run: AnytimeRun, seed: Array, stop: float) -> Array:
        """Routes to up to ``goal_routes`` goal IK solutions (the roadmap's validity cache
        keeps what the first route checked), shortcut; the shortest is offered and becomes
        the seed when it is shorter."""
        query = run.query
        t = time.perf_counter()
        # no path to an end is shorter than the straight line to it, so an end whose line is
        # no shorter than the answer so far is neither connected nor routed (the seeder
        # prunes it), and a route whose line is no shorter than the best so far is not
        # shortcut (measured with the first answer as the bound: 30-55% of the routes of 40
        # task cases in each of three scenes, 25-38% of the stage's shortcut time). Asking
        # for the routes in two rounds, the bound tightened by the first round's shortcuts
        # before more ends are connected, saved nothing (80 task cases in four scenes).
        # A goal end that connects to the roadmap neither directly nor by a bridge is left
        # out (no tree, no wide search: ``last_resorts``): such a tree ran until the stop in
        # 4 of 720 cases (60 a scene and family, 2026-11-30), taking the stage's whole
        # budget, so that TrajOpt never ran; it won none of them.
        bound = run.shortest_rad
        found = self.seeder.seeds(query.q_start, query.goal, self.config.goal_routes,
                                  deadline=stop, shorter_than_rad=bound - 1e-9,
                                  last_resorts=False)
        # every route (with more goal IK solutions the first may differ from the first
        # answer's), nearest end first
        routes = sorted((f.path for f in found if f.path is not None), key=_line_length)
        best, shortcut = None, 0
        for route in routes:
            if _line_length(route) >= bound - 1e-9:
                break
            path = self._shortcut(run, route, stop)
            shortcut += 1
            if path_length(path) < bound - 1e-9:
                best, bound = path, path_length(path)
        pruned = bool(found[0].info.get("pruned", False))
        run.report(Stage.ROUTES, PlanStatus.SOLVED if routes or pruned else
                   PlanStatus.of(found[0].status), time.perf_counter() - t, best,
                   {"routes": len(routes), "routes_shortcut": shortcut, "pruned": pruned})
        if best is not None and path_length(best) < path_length(seed) - 1e-9:
            run.offer(best, Stage.ROUTES, seed=best, info={"roadmap_seed": best})
            return best
        return seed

    def _simplify(self, run: AnytimeRun, seed: Array, stop: float) -> Array:
        """Shortcuts between any two points of the seed (seeded per query: the same query,
        the same answer); offered, and the new seed, when shorter."""
        t = time.perf_counter()
        short = partial_shortcut(self.world.fast, seed,
                                 np.random.default_rng(self.config.seeder.seed),
                                 rounds=self.config.simplify_rounds, deadline=stop,
                                 clearance_m=self.config.shortcut_clearance_m)
        better = path_length(short) < path_length(seed) - 1e-9
        run.report(Stage.SIMPLIFY, PlanStatus.SOLVED, time.perf_counter() - t, short,
                   {"saved_rad": path_length(seed) - path_length(short)})
        if better and run.offer(short, Stage.SIMPLIFY, seed=short):
            return short
        return seed

    def _line_goal(self, run: AnytimeRun, seed: Array | None) -> Array | None:
        """The IK solution nearest the start when a straight-line TrajOpt is worth a try:
        it is on, and there is no seed (``straight_line_fallback``) or the seed is longer
        than ``straight_line_ratio`` times the line."""
        cfg, query = self.config, run.query
        if (not cfg.straight_line_first if seed is not None else not cfg.straight_line_fallback):
            return None
        t = time.perf_counter()
        Q = self._goal_configurations(query)
        run.timing["line_ik"] = time.perf_counter() - t
        if len(Q) == 0:
            return None
        if seed is not None and path_length(seed) <= cfg.straight_line_ratio * float(
                np.linalg.norm(Q[0] - query.q_start)):
            return None
        if seed is not None and self._blocked_fraction(query.q_start, Q[0]) \
                > cfg.straight_line_max_blocked:
            return None
        return Q[0]

    def _blocked_fraction(self, q0: Array, q1: Array) -> float:
        """The share of 64 configurations along the straight line q0 → q1 that the fast
        checker finds in collision (about 60 µs)."""
        t = np.linspace(0.0, 1.0, 64)[:, None]
        return 1.0 - float(self.world.fast.valid((1 - t) * q0 + t * q1).mean())

    def _optimise(self, run: AnytimeRun, seed: Array, stage: Stage, stop: float, kind: str,
                  *, goal: Goal | None = None, retry: bool = False,
                  abandon: bool = False) -> bool:
        """TrajOpt from ``seed`` towards ``goal`` (default: the query's) until ``stop``
        (perf_counter s); its result offered. With ``retry`` and a pose goal, once more
        towards the seed's end configuration when the pose lost to the collision terms.
        With ``abandon``, each run stops once it is ``abandon_ratio`` times longer than the
        answer so far. True when TrajOpt succeeded."""
        query = run.query
        goal = goal if goal is not None else query.goal
        above = self.config.abandon_ratio * run.shortest_rad if abandon else math.inf
        r = self._trajopt_run(run, seed, goal, stage, stop, above)
        if r is None:
            return False
        if (retry and r.status == "infeasible" and goal.is_pose
                and r.unmet() - {"collision_m"} and time.perf_counter() < stop):
            again = self._trajopt_run(run, seed, Goal.configuration(seed[-1]), Stage.RETRY,
                                      stop, above)
            r = again if again is not None and again.success else r
        info: dict[str, object] = {
            "seed_kind": kind, "roadmap_seed": seed, "trajopt_status": r.status,
            "trajopt_goal": "pose" if goal.is_pose else "configuration",
            "iterations": r.iterations, "trajectory": r.trajectory,
            "optimised_valid": r.valid, "trajopt_timing_s": r.timing_s,
            "fallback_to_seed": False}
        if r.success and run.offer(r.trajectory, stage, seed=seed, certificate=r.certificate,
                                   info=info):
            return True
        run.best_info.update({"trajopt_status": r.status, "trajectory": r.trajectory,
                              "optimised_valid": r.valid,
                              "fallback_to_seed": run.best is not None})
        return r.success

    def _seed_goal(self, run: AnytimeRun, seed: Array) -> Goal | None:
        """What TrajOpt from ``seed`` (T, K) rad, the answer so far, aims at: the query's
        goal, or the seed's end configuration when the sphere model cannot clear it
        (:meth:`_end_unclear`: the collision terms would pull the end off a pose goal); None
        when that is a configuration the seed reaches within ``min_length_gain`` of the
        straight line to it — no path there is shorter than the line."""
        goal = run.query.goal
        if goal.is_pose and self._end_unclear(seed[-1]):
            goal = Goal.configuration(seed[-1])
        if not goal.is_pose and path_length(seed) <= ((1 + self.config.min_length_gain)
                                                      * _line_length(seed)):
            run.best_info["trajopt_skipped"] = "the seed is as short as the line to its end"
            return None
        return goal

    def _end_unclear(self, q_end: Array) -> bool:
        """Whether TrajOpt's own terms at q_end (K,) rad (the sphere model; a self pair whose
        tabled gap bound clears the margin is none) are closer than its ``min_clearance_m``
        to something (an obstacle, a fixed part, itself). The collision
        terms then push the last waypoint off a pose goal that only q_end's neighbourhood
        reaches: on task cases that pose-goal TrajOpt ended "infeasible" in 29 of 33 such
        queries (Panda and Baxter shelves, kitchen), 20-70 ms each, before the retry towards
        q_end that succeeds."""
        cfg = self._trajopt
        d, _ = self._distances.waypoints(q_end[None], cfg.check_distance_m, 1,
                                         tabled_clear_m=cfg.min_clearance_m)
        return float(d.min()) < cfg.min_clearance_m

    def _trajopt_run(self, run: AnytimeRun, seed: Array, goal: Goal, stage: Stage,
                     stop: float, abandon_above_rad: float = math.inf
                     ) -> TrajOptResult | None:
        t = time.perf_counter()
        try:
            problem = build_trajopt(self.world, run.query.q_start, goal, seed,
                                    self._trajopt.within(stop - t), self._distances)
        except ChekhovError as e:
            run.report(stage, PlanStatus.BAD_PROBLEM, time.perf_counter() - t,
                       detail={"error": str(e)})
            return None
        r = solve_trajopt(problem, stop, abandon_above_rad=abandon_above_rad)
        run.timing["optimise"] = run.timing.get("optimise", 0.0) + r.optimise_s
        run.timing["validate"] = run.timing.get("validate", 0.0) + r.timing_s["validate"]
        run.stages.append(optimise_report(r, time.perf_counter() - t, stage))
        return r

    def _goal_configurations(self, query: PlanQuery, n: int | None = None) -> Array:
        """(n, K): the goal configuration, or up to n (default the seeder's ``n_goal_ik``) of
        the pose goal's IK solutions, nearest the start first (empty when there is none)."""
        goal = query.goal
        if goal.q is not None:
            return goal.q[None]
        assert goal.T_world_ee is not None
        Q, _ = self.seeder.goal_configurations(goal.T_world_ee, n, deadline=query.deadline,
                                               near=query.q_start)
        return Q


def _line_length(path: Array) -> float:
    """rad: the straight line's length from the path's first configuration to its last."""
    return float(np.linalg.norm(path[-1] - path[0]))


FINISH_RESERVE_S = 1e-3
"""s: the improvements stop this long (plus the first answer's certification time) before
the offers' deadline (``AnytimeRun.offer_deadline``, ``FINAL_CHECK_RESERVE_S`` before the
limit): after them comes the waiting candidate's certification, then the final check.
With none, 37-42 of 60 kitchen answers at a 10 ms limit came back 0.5-2.3 ms late
(``benchmarks/deadline.py``)."""
_REPAIRABLE = (PlanStatus.NO_CONNECTION, PlanStatus.NO_PATH)
_KINDS = {Stage.ROADMAP_SEED: "roadmap", Stage.REPAIR: "repair", None: ""}
