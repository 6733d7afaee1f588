"""Time parameterisation figures: one JSON object per scene and TOPP-RA solver.

    python benchmarks/timing.py [--json] [--scenes ...] [--family tasks] [--cases 40]
                                [--case-seed 3] [--repeats 2]

The paths are Roadmap + TrajOpt's answers to the scene's cached cases (``cached_cases``,
planned once, untimed); each is then timed as ``plan()`` times it
(``chekhov.planners.timed.timed_trajectory``: toppra along the blended polyline, the arcs
checked exactly, ruckig when refused), with TOPP-RA solved by the compiled kernel
(``toppra_solver="compiled"``) and by the toppra package (``"library"``), the two alternating
``--repeats`` times over all paths (machines are noisy: compare within one run).

Keys: scene, family, solver, paths, ``median_ms`` / ``mean_ms`` / ``p95_ms`` (wall time of
``timed_trajectory``), ``toppra_median_ms`` (``time_parameterize`` alone: TOPP-RA, knots, the
limit check, without the exact check of the arcs), ``median_duration_s`` (the motions'),
``kept_toppra`` (answers timed by toppra, not the ruckig fallback).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: idle BLAS threads would only spin

import argparse
import json
import time
from typing import Any

import numpy as np

from chekhov import TimingConfig, World, builtin_scenes, load_or_build_roadmap, time_parameterize
from chekhov.cases import cached_cases
from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
from chekhov.planners.timed import timed_trajectory
from chekhov.timing import joint_limits

SOLVERS = ("compiled", "library")


def answers(world: World, family: str, n: int, seed: int) -> list[np.ndarray]:
    """Roadmap + TrajOpt's certified paths for the scene's cached cases (untimed)."""
    planner = RoadmapTrajOpt(world, load_or_build_roadmap(world))
    planner.timing = None
    cases = cached_cases(world, n, seed=seed, family=family)
    found = (planner.plan(cases.q_start[i], cases.goal(i), 2.0).path for i in range(len(cases)))
    return [p for p in found if p is not None]


def bench_scene(scene: str, family: str, n: int, seed: int, repeats: int
                ) -> list[dict[str, Any]]:
    world = World.load(scene)
    paths = answers(world, family, n, seed)
    limits = joint_limits(world.robot.velocity_limit, TimingConfig())
    wall: dict[str, list[float]] = {s: [] for s in SOLVERS}
    alone: dict[str, list[float]] = {s: [] for s in SOLVERS}
    duration: dict[str, list[float]] = {s: [] for s in SOLVERS}
    kept = dict.fromkeys(SOLVERS, 0)
    for solver in SOLVERS:                      # load compiled kernels and libraries
        timed_trajectory(world, paths[0], TimingConfig(toppra_solver=solver))
    for r in range(repeats):
        for solver in SOLVERS:
            config = TimingConfig(toppra_solver=solver)
            for path in paths:
                t = time.perf_counter()
                timed = timed_trajectory(world, path, config)
                wall[solver].append(time.perf_counter() - t)
                t = time.perf_counter()
                time_parameterize(path, world.robot.joint_names, limits, config)
                alone[solver].append(time.perf_counter() - t)
                if r == 0:
                    duration[solver].append(timed.trajectory.duration)
                    kept[solver] += timed.method == "toppra"
    return [{"scene": scene, "family": family, "solver": s, "paths": len(paths),
             "median_ms": round(1e3 * float(np.median(wall[s])), 2),
             "mean_ms": round(1e3 * float(np.mean(wall[s])), 2),
             "p95_ms": round(1e3 * float(np.percentile(wall[s], 95)), 2),
             "toppra_median_ms": round(1e3 * float(np.median(alone[s])), 2),
             "median_duration_s": round(float(np.median(duration[s])), 3),
             "kept_toppra": kept[s]} for s in SOLVERS]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="*", default=list(builtin_scenes()))
    ap.add_argument("--family", choices=["random", "tasks"], default="tasks")
    ap.add_argument("--cases", type=int, default=40)
    ap.add_argument("--case-seed", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--json", action="store_true", help="JSON lines only")
    args = ap.parse_args()
    for scene in args.scenes:
        for row in bench_scene(scene, args.family, args.cases, args.case_seed, args.repeats):
            print(json.dumps(row) if args.json else
                  "  ".join(f"{k}={v}" for k, v in row.items()), flush=True)


if __name__ == "__main__":
    main()
