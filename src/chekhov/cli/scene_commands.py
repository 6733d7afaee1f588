"""Scene commands: ``chekhov scenes``, ``chekhov show``, ``chekhov demo``."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from chekhov.errors import ChekhovError


def _cmd_scenes(args: argparse.Namespace) -> int:
    from chekhov.scene.io import builtin_scenes, load_scene

    for name in builtin_scenes():
        s = load_scene(name)
        n_grasp = sum(len(o.grasps) for o in s.objects)
        n_art = sum(o.articulation is not None for o in s.objects)
        print(f"{name:20s} {len(s.objects):3d} objects  {n_grasp:2d} grasps  {n_art} articulated  "
              f"{len(s.regions)} regions  — {s.description}")
    return 0


def _parse_q(values: list[float] | None, dof: int) -> np.ndarray | None:
    if values is None:
        return None
    if len(values) != dof:
        raise ChekhovError(f"--q: expected {dof} joint values, got {len(values)}")
    return np.asarray(values, dtype=float)


def _cmd_show(args: argparse.Namespace) -> int:
    from chekhov.viewer.render import render_scene
    from chekhov.world import World

    world = World.load(args.scene)
    q = _parse_q(args.q, world.robot.dof)
    if q is None:
        q = np.zeros(world.robot.dof)
    out = render_scene(world, q=q, out=args.out)
    free = world.is_free(q)
    print(f"wrote {out} ({world.scene.name}, q {'free' if free else 'IN COLLISION'})")
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    """The main job: per scene, load or build the roadmap, plan random cases with Roadmap +
    TrajOpt (every answer exactly checked), report timings, write a picture of one plan."""
    from chekhov.bench.cases import generate_cases
    from chekhov.planners.base import path_length
    from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
    from chekhov.roadmap.io import load_or_build_roadmap
    from chekhov.scene.io import builtin_scenes
    from chekhov.viewer.render import render_scene
    from chekhov.world import World

    out = Path(args.out)
    for name in builtin_scenes():
        world = World.load(name)
        t0 = time.perf_counter()
        roadmap = load_or_build_roadmap(world)
        t_map = time.perf_counter() - t0
        planner = RoadmapTrajOpt(world, roadmap)
        cases = generate_cases(world, args.cases, seed=0)
        planner.plan(cases.q_start[0], cases.goal(0))  # load compiled kernels
        times, ratios, solved, exact_ok, shown = [], [], 0, 0, None
        for i in range(len(cases.q_start)):
            r = planner.plan(cases.q_start[i], cases.goal(i))
            times.append(1e3 * r.time_s)
            if r.success and r.path is not None:
                solved += 1
                exact_ok += world.exact.path_valid(r.path, substeps=100)
                ratios.append(r.path_length / path_length(np.asarray(r.info["roadmap_seed"])))
                shown = r.path if shown is None else shown
        png = render_scene(world, q=shown[-1] if shown is not None else np.zeros(7),
                           path=shown, out=out / f"{name}.png")
        n = len(cases.q_start)
        print(f"{name:20s} roadmap {roadmap.n_nodes} nodes ({t_map:4.1f} s)  solved {solved}/{n}"
              f"  exact-free {exact_ok}/{solved}  median {np.median(times):6.1f} ms  "
              f"mean {np.mean(times):6.1f} ms  length / roadmap seed "
              f"{np.mean(ratios) if ratios else float('nan'):.2f}  → {png}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add the scene commands to the top-level parser."""
    sub.add_parser("scenes", help="list the built-in scenes").set_defaults(func=_cmd_scenes)
    p = sub.add_parser("show", help="write a picture of a scene with the robot")
    p.add_argument("scene", help="built-in scene name or scene YAML file")
    p.add_argument("--q", type=float, nargs="+", help="joint values (rad), group order")
    p.add_argument("--out", default="scene.png", help="PNG file to write")
    p.set_defaults(func=_cmd_show)
    p = sub.add_parser("demo", help="main job: roadmaps, Roadmap + TrajOpt plans, pictures")
    p.add_argument("--out", default="out/demo", help="folder for the pictures")
    p.add_argument("--cases", type=int, default=20, help="random cases per scene")
    p.set_defaults(func=_cmd_demo)
