"""TrajOpt figures (issue 3), one JSON object per scene.

    python benchmarks/trajopt.py [--json] [--scenes tabletop_pole shelf_boxes] [--cases 200]

Cases: ``chekhov.bench.cases.cached_cases`` (seed 0): random start and goal configurations
free by both checkers; the planner gets the start and the goal *pose*.

Keys per scene:
- straight-line TrajOpt (T = 30, to the collision-free IK solution nearest the start, goal kept
  as a pose constraint): ``failure_rate``, ``median_ms``, ``mean_ms`` (optimisation only),
  ``ik_median_ms``, ``validate_median_ms`` (the exact check at 100 substeps),
  ``mean_path_length_rad`` (solved cases), ``collision_rate`` (returned paths the exact
  checker rejects: 0 by construction), ``status_counts``;
  ``median_cpu_ms`` / ``mean_cpu_ms`` (process CPU time of the optimisation: the one-core
  cost, robust to other load on a shared machine);
- ``waypoint_series``: T = 10 … 60 → median / mean optimisation ms and failure rate;
- collision-free seeds of 20–40 waypoints (start → a random free via configuration → goal
  configuration, both legs free, resampled to ≤ 0.16 rad): ``free_seed_median_ms``,
  ``free_seed_mean_ms``, ``free_seed_waypoints_median``, ``free_seed_collision_rate`` (exact
  check of the optimised output before any fallback), ``free_seed_length_ratio`` (optimised
  length / seed length).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: idle BLAS threads would only spin

import argparse
import json

import numpy as np

from chekhov import World
from chekhov.bench.cases import cached_cases
from chekhov.planners.base import path_length, resample_path
from chekhov.planners.trajopt_planner import TrajOptPlanner
from chekhov.robot.goal import Goal
from chekhov.trajopt.config import TrajOptConfig
from chekhov.trajopt.problem import build_trajopt
from chekhov.trajopt.solver import solve_trajopt


def _stats(ms: list[float]) -> tuple[float, float]:
    return (float(np.median(ms)), float(np.mean(ms))) if ms else (float("nan"),) * 2


def straight_line(world: World, cases, n_waypoints: int) -> dict[str, object]:
    planner = TrajOptPlanner(world, TrajOptConfig(n_waypoints=n_waypoints))
    opt, cpu, ik, val, lengths, statuses = [], [], [], [], [], []
    collisions = 0
    for i in range(len(cases.q_start)):
        r = planner.plan(cases.q_start[i], cases.goal(i))
        statuses.append(str(r.info.get("trajopt_status", r.status)))
        if "optimise" in r.timing_s:
            opt.append(1e3 * r.timing_s["optimise"])
            cpu.append(1e3 * float(r.info["trajopt_cpu_s"]))
            val.append(1e3 * r.timing_s["validate"])
        ik.append(1e3 * r.timing_s.get("ik", 0.0))
        if r.success and r.path is not None:
            lengths.append(path_length(r.path))
            collisions += not world.exact.path_valid(r.path, substeps=100)
    med, mean = _stats(opt)
    n = len(cases.q_start)
    return {"failure_rate": 1 - len(lengths) / n, "median_ms": med, "mean_ms": mean,
            "median_cpu_ms": _stats(cpu)[0], "mean_cpu_ms": _stats(cpu)[1],
            "ik_median_ms": float(np.median(ik)), "validate_median_ms": _stats(val)[0],
            "mean_path_length_rad": float(np.mean(lengths)) if lengths else float("nan"),
            "collision_rate": collisions / n,
            "status_counts": {s: statuses.count(s) for s in sorted(set(statuses))}}


def free_seeds(world: World, cases, rng: np.random.Generator, n: int
               ) -> list[tuple[np.ndarray, np.ndarray]]:
    """(q_start, seed) pairs: collision-free two-leg seeds of 20-40 waypoints."""
    out = []
    fast = world.fast
    for i in range(len(cases.q_start)):
        qs, qg = cases.q_start[i], cases.q_goal[i]
        for _ in range(200):
            via = world.robot.sample_uniform(rng, 1)[0]
            via = qs + (via - qs) * rng.uniform(0.2, 0.6)
            seed = resample_path(np.vstack([qs, via, qg]), 0.16)
            if 20 <= len(seed) <= 40 and fast.path_valid(seed, 0.01):
                out.append((qs, seed))
                break
        if len(out) >= n:
            break
    return out


def bench_scene(name: str, n_cases: int, n_series: int) -> dict[str, object]:
    world = World.load(name)
    cases = cached_cases(world, n_cases, seed=0)
    TrajOptPlanner(world).plan(cases.q_start[0], cases.goal(0))  # compile the kernels
    out: dict[str, object] = {"scene": name, "cases": n_cases}
    out.update(straight_line(world, cases, 30))
    series = {}
    for T in (10, 20, 30, 40, 50, 60):
        s = straight_line(world, cases.head(n_series), T)
        series[T] = {"median_ms": s["median_ms"], "mean_ms": s["mean_ms"],
                     "failure_rate": s["failure_rate"]}
    out["waypoint_series"] = series
    seeds = free_seeds(world, cases, np.random.default_rng(1), n_series)
    cfg = TrajOptConfig(validate="none")
    opt, cpu, ratio = [], [], []
    bad = 0
    for qs, seed in seeds:
        goal = Goal.configuration(seed[-1])
        r = solve_trajopt(build_trajopt(world, qs, goal, seed, cfg))
        opt.append(1e3 * r.optimise_s)
        cpu.append(1e3 * float(r.info["cpu_s"]))  # type: ignore[arg-type]
        ratio.append(r.path_length / path_length(seed))
        bad += not world.exact.path_valid(r.trajectory, substeps=100)
    med, mean = _stats(opt)
    out.update({"free_seeds": len(seeds), "free_seed_median_ms": med, "free_seed_mean_ms": mean,
                "free_seed_median_cpu_ms": _stats(cpu)[0],
                "free_seed_waypoints_median": float(np.median([len(s) for _, s in seeds])),
                "free_seed_collision_rate": bad / max(1, len(seeds)),
                "free_seed_length_ratio": float(np.mean(ratio)) if ratio else float("nan")})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", action="store_true", help="one JSON object per line")
    ap.add_argument("--scenes", nargs="+", default=["tabletop_pole", "shelf_boxes"])
    ap.add_argument("--cases", type=int, default=200)
    ap.add_argument("--series-cases", type=int, default=50)
    args = ap.parse_args()
    for name in args.scenes:
        r = bench_scene(name, args.cases, args.series_cases)
        if args.json:
            print(json.dumps(r), flush=True)
        else:
            print(f"{name}: " + ", ".join(f"{k} {v}" for k, v in r.items()), flush=True)



if __name__ == "__main__":
    main()
