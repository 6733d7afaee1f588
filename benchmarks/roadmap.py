"""Roadmap figures per built-in scene (issue 4): build, memory, seed query time, connection
failures, seed length; semantic sampling on and off; with random dynamic obstacles.

    python benchmarks/roadmap.py --json                 # all scenes, 500 cases each
    python benchmarks/roadmap.py --scenes shelf_boxes --cases 200

Cases: random collision-free start and goal configurations within the limits (fast and exact
checkers agree), the goal given as the end-effector pose of the goal configuration;
deterministic for a given --seed. One JSON object per scene; ``bench_scene`` returns it as a
dict so other planners' figures can be added. ``pregrasp_nodes``: the roadmap's pre-grasp nodes
(IK configurations of the scene's pre-grasp poses, in its largest component; 0 with semantic
sampling off).

``roadmap_trajopt`` (also under ``semantic_off`` and ``dynamic``) holds the Roadmap + TrajOpt
planner's figures on the same cases (ours: a 40 ms straight-line TrajOpt try, then the roadmap;
``roadmap_trajopt_paper``: every query seeded from the roadmap, the paper's planner):
failure_rate, median_ms, mean_ms, p95_ms (wall, whole
query including validation), median_cpu_ms / mean_cpu_ms (process CPU time: the one-core cost,
robust to other load), mean_path_length_rad, mean_roadmap_seed_length_rad,
mean_length_ratio_to_seed (roadmap-seeded answers only), roadmap_seeded_rate,
optimised_collision_rate (exact check before fallback),
fallback_rate and returned_collision_rate (must be 0).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: idle BLAS threads would only spin

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from chekhov.planners.base import path_length
from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
from chekhov.planners.roadmap_trajopt_config import RoadmapTrajOptConfig
from chekhov.roadmap.build import build_roadmap
from chekhov.roadmap.config import RoadmapConfig
from chekhov.roadmap.graph import Roadmap
from chekhov.roadmap.io import load_roadmap, save_roadmap
from chekhov.roadmap.seeder import RoadmapSeeder, SeederConfig
from chekhov.robot.goal import Goal
from chekhov.scene.io import builtin_scenes
from chekhov.scene.model import Shape
from chekhov.world import World


def random_free_configurations(world: World, n: int, rng: np.random.Generator) -> np.ndarray:
    """n configurations (n, K) within the limits, free for both the fast and exact checker."""
    out: list[np.ndarray] = []
    while len(out) < n:
        Q = world.robot.sample_uniform(rng, 4 * (n - len(out)) + 16)
        Q = Q[world.fast.valid(Q)]
        out += [q for q in Q if world.exact.is_valid(q)][: n - len(out)]
    return np.array(out)


def make_cases(world: World, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(starts (n, K), goal configurations (n, K)); goals are posed as their FK pose."""
    rng = np.random.default_rng(seed)
    Q = random_free_configurations(world, 2 * n, rng)
    return Q[:n], Q[n:]


def add_random_obstacles(world: World, n: int, seed: int, radius: float = 0.08) -> list[str]:
    """n dynamic spheres (radius m) at the end-effector positions of random free
    configurations: in the arm's workspace, in free space."""
    rng = np.random.default_rng(seed + 7)
    names = []
    for i, q in enumerate(random_free_configurations(world, n, rng)):
        T = np.eye(4)
        T[:3, 3] = world.robot.compute_ee_pose(q)[:3, 3]
        name = f"dyn_{i}"
        world.add_obstacle(name, Shape("sphere", (radius,)), T)
        names.append(name)
    return names


def run_queries(world: World, roadmap: Roadmap, starts: np.ndarray, goals: np.ndarray,
                seeder_config: SeederConfig) -> dict[str, object]:
    seeder = RoadmapSeeder(world, roadmap, seeder_config)
    T_goals = world.robot.compute_ee_poses(goals)
    total, no_ik, ik, lengths = [], [], [], []
    status: dict[str, int] = {}
    bridged = invalid = 0
    for q0, T in zip(starts, T_goals, strict=True):
        r = seeder.seed(q0, Goal.pose(T))
        status[r.status] = status.get(r.status, 0) + 1
        total.append(r.timing_s["total"])
        ik.append(r.timing_s["ik"])
        no_ik.append(r.timing_s["total"] - r.timing_s["ik"])
        if r.success:
            assert r.path is not None
            lengths.append(r.length_rad)
            if not world.fast.path_valid(r.path, seeder.resolution):
                invalid += 1
            if "direct" not in (r.info["start_connection"], r.info["goal_connection"]) or (
                    r.info["start_connection"] != r.info["goal_connection"]):
                bridged += 1
    n = len(starts)
    ms = 1e3
    no_conn = status.get("no_connection", 0)
    return {
        "cases": n,
        "query_seed_median_ms": round(float(np.median(total)) * ms, 3),
        "query_seed_p95_ms": round(float(np.percentile(total, 95)) * ms, 3),
        "query_seed_mean_ms": round(float(np.mean(total)) * ms, 3),
        "query_seed_without_ik_median_ms": round(float(np.median(no_ik)) * ms, 3),
        "goal_ik_median_ms": round(float(np.median(ik)) * ms, 3),
        "connect_failure_rate": round(no_conn / n, 4),
        "direct_connect_failure_rate": round((no_conn + bridged) / n, 4),
        "no_ik_rate": round(status.get("no_ik", 0) / n, 4),
        "failure_rate": round(1 - status.get("solved", 0) / n, 4),
        "seed_mean_length_rad": round(float(np.mean(lengths)), 3) if lengths else None,
        "seed_invalid_paths": invalid,
        "status": status,
    }


def run_planner(world: World, roadmap: Roadmap, starts: np.ndarray, goals: np.ndarray,
                seeder_config: SeederConfig, straight_line_first: bool = True
                ) -> dict[str, object]:
    """Roadmap + TrajOpt on the cases: wall and CPU time of whole queries (seed, shortcut,
    TrajOpt, validation), path lengths, and collisions by the exact checker at 100 substeps:
    of the optimised trajectories before any fallback, and of what was returned (must be 0)."""
    planner = RoadmapTrajOpt(world, roadmap, RoadmapTrajOptConfig(
        seeder=seeder_config, straight_line_first=straight_line_first))
    T_goals = world.robot.compute_ee_poses(goals)
    planner.plan(starts[0], Goal.pose(T_goals[0]))  # load compiled kernels
    wall, cpu, lengths, seed_lengths, ratios = [], [], [], [], []
    roadmap_seeded = 0
    optimised_bad = returned_bad = optimised = fallbacks = 0
    for q0, T in zip(starts, T_goals, strict=True):
        c0 = time.process_time()
        r = planner.plan(q0, Goal.pose(T))
        cpu.append(time.process_time() - c0)
        wall.append(r.time_s)
        traj = r.info.get("trajectory")
        traj_ok = None
        if traj is not None:
            optimised += 1
            traj_ok = world.exact.path_valid(np.asarray(traj), substeps=100)
            optimised_bad += not traj_ok
        if r.success and r.path is not None:
            fallbacks += bool(r.info.get("fallback_to_seed"))
            same = traj is not None and np.array_equal(np.asarray(traj), r.path)
            ok = traj_ok if same else world.exact.path_valid(r.path, substeps=100)
            returned_bad += not ok
            lengths.append(r.path_length)
            if r.info.get("seed_kind") == "roadmap":
                roadmap_seeded += 1
                seed_len = path_length(np.asarray(r.info["roadmap_seed"]))
                seed_lengths.append(seed_len)
                ratios.append(r.path_length / seed_len)
    n = len(starts)
    ms = 1e3
    return {
        "failure_rate": round(1 - len(lengths) / n, 4),
        "median_ms": round(float(np.median(wall)) * ms, 2),
        "mean_ms": round(float(np.mean(wall)) * ms, 2),
        "p95_ms": round(float(np.percentile(wall, 95)) * ms, 2),
        "median_cpu_ms": round(float(np.median(cpu)) * ms, 2),
        "mean_cpu_ms": round(float(np.mean(cpu)) * ms, 2),
        "mean_path_length_rad": round(float(np.mean(lengths)), 3) if lengths else None,
        "mean_roadmap_seed_length_rad": round(float(np.mean(seed_lengths)), 3)
        if seed_lengths else None,
        "mean_length_ratio_to_seed": round(float(np.mean(ratios)), 3) if ratios else None,
        "roadmap_seeded_rate": round(roadmap_seeded / n, 4),
        "optimised_collision_rate": round(optimised_bad / max(1, optimised), 4),
        "fallback_rate": round(fallbacks / n, 4),
        "returned_collision_rate": round(returned_bad / n, 4),
    }


def roadmap_for(world: World, config: RoadmapConfig, cache: Path | None
                ) -> tuple[Roadmap, float]:
    """(roadmap, build s): built now, or loaded from --cache when present (build s as saved)."""
    if cache is not None:
        tag = (f"{world.scene.name}-{config.n_nodes}-{int(config.semantic)}-"
               f"{config.n_wrist_nodes}-{config.seed}.npz")
        path = cache / tag
        if path.is_file():
            rm = load_roadmap(path, world)
            if rm.config == config:
                return rm, rm.meta.build_s
        rm = build_roadmap(world, config)
        save_roadmap(rm, path)
        return rm, rm.meta.build_s
    t = time.perf_counter()
    rm = build_roadmap(world, config)
    return rm, time.perf_counter() - t


def roadmap_figures(rm: Roadmap, build_s: float) -> dict[str, object]:
    return {"build_s": round(build_s, 2), "nodes": rm.n_nodes, "edges": rm.n_edges,
            "dropped_nodes": rm.meta.dropped_nodes, "node_counts": rm.meta.node_counts,
            "pregrasp_nodes": rm.meta.node_counts.get("pregrasp", 0),
            "roadmap_bytes": rm.nbytes, "kpaths_bytes": rm.kpaths_nbytes}


def bench_scene(name: str, n_cases: int = 500, seed: int = 0, config: RoadmapConfig | None = None,
                seeder_config: SeederConfig | None = None, n_obstacles: int = 2,
                cache: Path | None = None) -> dict[str, object]:
    """All roadmap figures of one scene, as a dict."""
    config = config or RoadmapConfig(seed=seed)
    seeder_config = seeder_config or SeederConfig()
    world = World.load(name)
    starts, goals = make_cases(world, n_cases, seed)
    out: dict[str, object] = {"scene": name}
    rm, build_s = roadmap_for(world, config, cache)
    out.update(roadmap_figures(rm, build_s))
    out.update(run_queries(world, rm, starts, goals, seeder_config))
    out["roadmap_trajopt"] = run_planner(world, rm, starts, goals, seeder_config)
    out["roadmap_trajopt_paper"] = run_planner(world, rm, starts, goals, seeder_config,
                                               straight_line_first=False)
    rm_off, build_off = roadmap_for(world, replace(config, semantic=False), cache)
    out["semantic_off"] = {**roadmap_figures(rm_off, build_off),
                           **run_queries(world, rm_off, starts, goals, seeder_config),
                           "roadmap_trajopt": run_planner(world, rm_off, starts, goals,
                                                          seeder_config)}
    if n_obstacles:
        add_random_obstacles(world, n_obstacles, seed)
        keep = world.fast.valid(starts) & world.fast.valid(goals)
        keep &= np.array([world.exact.is_valid(a) and world.exact.is_valid(b)
                          for a, b in zip(starts, goals, strict=True)])
        out["dynamic"] = {"obstacles": n_obstacles,
                          **run_queries(world, rm, starts[keep], goals[keep], seeder_config),
                          "roadmap_trajopt": run_planner(world, rm, starts[keep], goals[keep],
                                                         seeder_config)}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", action="store_true", help="one JSON object per scene")
    ap.add_argument("--scenes", nargs="+", default=None)
    ap.add_argument("--cases", type=int, default=500)
    ap.add_argument("--nodes", type=int, default=1000)
    ap.add_argument("--wrist-nodes", type=int, default=RoadmapConfig().n_wrist_nodes)
    ap.add_argument("--obstacles", type=int, default=2, help="random dynamic spheres")
    ap.add_argument("--no-bridges", action="store_true",
                    help="direct connections only (the paper's scheme)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cache", type=Path, default=None,
                    help="folder to reuse built roadmaps from (build_s then as saved)")
    args = ap.parse_args(argv)
    config = RoadmapConfig(n_nodes=args.nodes, n_wrist_nodes=args.wrist_nodes, seed=args.seed)
    sc = SeederConfig(bridges=not args.no_bridges)
    for name in args.scenes or builtin_scenes():
        fig = bench_scene(name, args.cases, args.seed, config, sc, args.obstacles, args.cache)
        if args.json:
            print(json.dumps(fig), flush=True)
        else:
            print(f"{name}: {fig}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
