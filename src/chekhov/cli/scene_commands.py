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
    """Load every scene, solve IK for each pre-grasp, check collisions, write pictures."""
    from chekhov.scene.io import builtin_scenes
    from chekhov.viewer.render import render_scene
    from chekhov.world import World

    out = Path(args.out)
    rng = np.random.default_rng(0)
    for name in builtin_scenes():
        t0 = time.perf_counter()
        world = World.load(name)
        fast = world.fast
        Q = world.robot.sample_uniform(rng, 20000)
        t1 = time.perf_counter()
        free = fast.valid(Q)
        t_fast = time.perf_counter() - t1
        reached, q_show = 0, None
        poses = [p for o in world.scene.objects for p in o.pregrasp_poses()]
        for _, T in poses:
            try:
                q = world.solve_ik(T, 1, rng=rng)[0]
            except ChekhovError:
                continue
            if world.exact.is_valid(q):
                reached += 1
                q_show = q if q_show is None else q_show
        png = render_scene(world, q=q_show if q_show is not None else np.zeros(7),
                           out=out / f"{name}.png")
        print(f"{name:20s} build {t1 - t0:5.2f} s  free {free.mean():5.1%} of random configs  "
              f"fast {len(Q) / t_fast:9.0f} checks/s  pre-grasps reached {reached}/{len(poses)}"
              f"  → {png}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add the scene commands to the top-level parser."""
    sub.add_parser("scenes", help="list the built-in scenes").set_defaults(func=_cmd_scenes)
    p = sub.add_parser("show", help="write a picture of a scene with the robot")
    p.add_argument("scene", help="built-in scene name or scene YAML file")
    p.add_argument("--q", type=float, nargs="+", help="joint values (rad), group order")
    p.add_argument("--out", default="scene.png", help="PNG file to write")
    p.set_defaults(func=_cmd_show)
    p = sub.add_parser("demo", help="main job: scenes, IK to every pre-grasp, checks, pictures")
    p.add_argument("--out", default="out/demo", help="folder for the pictures")
    p.set_defaults(func=_cmd_demo)
