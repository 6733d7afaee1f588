"""The paper's planner: a Chekhov roadmap seed, resampled to ≤ 0.16 rad, shortened and smoothed
by TrajOpt, validated exactly. It never returns a trajectory the exact checker rejects."""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.distance_terms import TrajectoryDistances
from chekhov.errors import ChekhovError
from chekhov.planners.base import PlanResult, resample_path
from chekhov.planners.shortcut import shortcut_path
from chekhov.roadmap.graph import Roadmap
from chekhov.roadmap.seeder import RoadmapSeeder, SeederConfig
from chekhov.robot.goal import Goal
from chekhov.trajopt.config import TrajOptConfig
from chekhov.trajopt.problem import build_trajopt
from chekhov.trajopt.solver import solve_trajopt, validate_path
from chekhov.world import World

Array = NDArray[np.float64]


class RoadmapTrajOpt:
    """Roadmap + TrajOpt (Dai et al.): seed from the roadmap against the world's current
    obstacles (dynamic ones included), optimise, check exactly at 100 substeps per segment.

    With ``shortcut`` (default) the roadmap path is first shortcut greedily with the fast
    checker (waypoints a free straight motion can skip are dropped), so TrajOpt starts close
    to its optimum; ``info["roadmap_seed"]`` keeps the roadmap's own path.

    When the optimised trajectory fails the exact check, the (exactly checked) seed is returned
    with ``info["fallback_to_seed"] = True``; when that fails too, the result is a failure
    with status "collision". ``time_s`` includes the validation.
    """

    def __init__(self, world: World, roadmap: Roadmap, config: TrajOptConfig | None = None,
                 seeder_config: SeederConfig | None = None, name: str = "Roadmap+TrajOpt",
                 shortcut: bool = True) -> None:
        self.world = world
        self.roadmap = roadmap
        self.config = config if config is not None else TrajOptConfig()
        self.seeder = RoadmapSeeder(world, roadmap, seeder_config)
        self.name = name
        self.shortcut = shortcut
        self._distances = TrajectoryDistances(world.fast)

    def plan(self, q_start: Array, goal: Goal, time_limit_s: float = 10.0) -> PlanResult:
        t0 = time.perf_counter()
        s = self.seeder.seed(np.asarray(q_start, dtype=float), goal)
        timing = {"seed": s.timing_s.get("total", time.perf_counter() - t0)}
        if not s.success or s.path is None:
            return PlanResult(False, None, s.status, time.perf_counter() - t0, timing,
                              info={"seed_info": s.info})
        t1 = time.perf_counter()
        short = shortcut_path(self.world.fast, s.path) if self.shortcut else s.path
        timing["shortcut"] = time.perf_counter() - t1
        seed = resample_path(short, self.config.max_step_rad)
        if len(seed) < 2:
            seed = np.vstack([seed, seed])
        cfg = self.config
        try:
            problem = build_trajopt(self.world, q_start, goal, seed, cfg, self._distances)
        except ChekhovError as e:
            return PlanResult(False, None, "bad_problem", time.perf_counter() - t0, timing,
                              seed=seed, info={"error": str(e)})
        r = solve_trajopt(problem)
        timing["optimise"] = r.optimise_s
        timing["validate"] = r.timing_s["validate"]
        info: dict[str, object] = {"roadmap_seed": s.path, "trajopt_status": r.status,
                                   "iterations": r.iterations,
                                   "trajopt_cpu_s": r.info["cpu_s"],
                                   "trajectory": r.trajectory, "seed_info": s.info,
                                   "optimised_valid": r.valid, "fallback_to_seed": False,
                                   "trajopt_timing_s": r.timing_s}
        if r.success:
            return PlanResult(True, r.trajectory, "solved", time.perf_counter() - t0, timing,
                              seed=seed, info=info)
        t1 = time.perf_counter()
        seed_ok = validate_path(self.world, seed, "exact" if cfg.validate == "none" else
                                cfg.validate, cfg.substeps)
        timing["validate"] += time.perf_counter() - t1
        if seed_ok:
            info["fallback_to_seed"] = True
            return PlanResult(True, seed, "solved", time.perf_counter() - t0, timing,
                              seed=seed, info=info)
        return PlanResult(False, None, "collision", time.perf_counter() - t0, timing, seed=seed,
                          info=info)
