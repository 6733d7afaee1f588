"""Arms nobody here developed on: one JSON object per arm and scene.

    python benchmarks/arms.py [--json] [--arms ur5 xarm7 z1 so100 ur10 jaco tiago pr2]
                              [--scenes tabletop_pole] [--queries 30] [--pose-queries 20]
                              [--time-limit 2]

Each arm comes from the ``example-robot-data`` package (its URDF, and its SRDF where the package
has one), mounted at :data:`BASE_XYZ` (on the pole's table, where Baxter's scenes have room for
it; TIAGo and the PR2 on the floor beside the table) in the built-in scene, with the default roadmap
(built, or loaded from the cache). Queries join exactly free random configurations (seeded):
``--queries`` to a configuration goal and ``--pose-queries`` to its end-effector pose.
Roadmap + TrajOpt and RRTConnect + simplify (OMPL, the fast checker as its validity test) plan
each after a warm-up, and every answer is checked again by the exact checker at 100 substeps
(an answer that fails counts as ``exact_failures``: must be 0).

Keys: arm, scene, dof, roadmap_s (build or load), nodes, exact_free (share of random
configurations the exact checker finds free), fast_false_alarm (share of those the fast checker
calls colliding), fast_false_free (configurations it calls free that the exact checker does not:
must be 0), then per planner and query kind (``rt`` / ``rrtc``, ``_pose``): statuses, median_ms,
p95_ms, mean_length_rad, exact_failures. Wall times of this machine: compare within one run.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: idle BLAS threads would only spin

import argparse
import json
import time
from collections import Counter
from typing import Any, NamedTuple

import numpy as np

from chekhov import Goal, OmplPlanner, Robot, World, load_or_build_roadmap, load_scene
from chekhov.planners.base import PlannerBase, path_length
from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
from chekhov.robot.description import example_robot_data_dir

BASE_XYZ = (0.35, 0.25, 0.76)
"""m, world: where each arm's base is put (facing +x)."""


class Arm(NamedTuple):
    """An arm of example-robot-data: URDF and SRDF (paths under ``robots/``), planned joints,
    end-effector frame, and where its base goes (m, world; facing +x)."""

    urdf: str
    srdf: str | None
    joints: tuple[str, ...]
    ee_frame: str
    xyz: tuple[float, float, float] = BASE_XYZ


_UR = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
       "wrist_2_joint", "wrist_3_joint")
ARMS = {
    "ur5": Arm("ur_description/urdf/ur5_joint_limited_robot.urdf",
               "ur_description/srdf/ur5.srdf", _UR, "tool0"),
    "ur10": Arm("ur_description/urdf/ur10_robot.urdf", None, _UR, "tool0"),
    "xarm7": Arm("xarm_description/urdf/xarm7.urdf", "xarm_description/srdf/xarm7.srdf",
                 tuple(f"joint{i}" for i in range(1, 8)), "link_eef"),
    "z1": Arm("z1_description/urdf/z1.urdf", "z1_description/srdf/z1.srdf",
              tuple(f"joint{i}" for i in range(1, 7)), "gripperStator"),
    # Kinova Jaco 2: 6 joints, three of them continuous (planned over ±2π, the URDF's limits)
    "jaco": Arm("kinova_description/robots/kinova.urdf", "kinova_description/srdf/kinova.srdf",
                tuple(f"j2s6s200_joint_{i}" for i in range(1, 7)), "j2s6s200_end_effector"),
    "so100": Arm("so_arm_description/urdf/so100.urdf", None,
                 ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"),
                 "gripper"),
    # PAL TIAGo: a mobile manipulator's 7-joint arm, its base, torso (lift at 0) and head fixed
    # parts; no SRDF, and two pairs of its meshes overlap by design (robot.self_pairs). On
    # the floor beside the table, not on it
    "tiago": Arm("tiago_description/robots/tiago.urdf", None,
                 tuple(f"arm_{i}_joint" for i in range(1, 8)), "arm_tool_link",
                 (0.1, 0.25, 0.0)),
    # Willow Garage PR2: the left arm (two continuous joints), the base, torso (lift at 0),
    # head and right arm fixed parts; its SRDF
    "pr2": Arm("pr2_description/urdf/pr2.urdf", "pr2_description/srdf/pr2.srdf",
               tuple(f"l_{j}_joint" for j in ("shoulder_pan", "shoulder_lift", "upper_arm_roll",
                                             "elbow_flex", "forearm_roll", "wrist_flex",
                                             "wrist_roll")), "l_gripper_tool_frame",
               (-0.05, 0.1, 0.0)),
}


def make_world(arm: str, scene: str) -> World:
    """The arm at its ``Arm.xyz`` (default :data:`BASE_XYZ`) in the built-in scene."""
    a, share = ARMS[arm], example_robot_data_dir()
    T = np.eye(4)
    T[:3, 3] = a.xyz
    robot = Robot.from_urdf(share / "robots" / a.urdf, joints=list(a.joints),
                            ee_frame=a.ee_frame,
                            srdf=None if a.srdf is None else share / "robots" / a.srdf,
                            package_dirs=[share.parent], T_world_base=T)
    return World(load_scene(scene), robot)


def run_queries(world: World, planner: PlannerBase, pairs: list[tuple[np.ndarray, Goal]],
                limit_s: float) -> dict[str, Any]:
    """Plan each (start, goal); statuses, times (ms), mean length (rad), exact failures."""
    statuses: Counter[str] = Counter()
    times, lengths, failures = [], [], 0
    for q0, goal in pairs:
        r = planner.plan(q0, goal, limit_s)
        statuses[r.status.value] += 1
        times.append(r.time_s * 1e3)
        if r.success and r.path is not None:
            lengths.append(path_length(r.path))
            failures += not world.exact.path_valid(r.path, substeps=100)
    return {"statuses": dict(statuses), "median_ms": float(np.median(times)),
            "p95_ms": float(np.percentile(times, 95)),
            "mean_length_rad": float(np.mean(lengths)) if lengths else None,
            "exact_failures": failures}


def bench_arm(arm: str, scene: str, n: int, n_pose: int, limit_s: float) -> dict[str, Any]:
    world = make_world(arm, scene)
    robot = world.robot
    Q = robot.sample_uniform(np.random.default_rng(5), 3000)
    fast_ok, exact_ok = world.fast.valid(Q), world.exact.valid(Q)
    t = time.perf_counter()
    roadmap = load_or_build_roadmap(world)
    out: dict[str, Any] = {
        "arm": arm, "scene": scene, "dof": robot.dof,
        "roadmap_s": time.perf_counter() - t, "nodes": roadmap.n_nodes,
        "exact_free": float(exact_ok.mean()),
        "fast_false_alarm": float((~fast_ok & exact_ok).sum() / max(exact_ok.sum(), 1)),
        "fast_false_free": int((fast_ok & ~exact_ok).sum())}
    E = Q[exact_ok]
    k = max(n, n_pose)
    if len(E) < 2 * k:
        raise SystemExit(f"{arm} in {scene}: only {len(E)} exactly free configurations")
    planners: dict[str, PlannerBase] = {
        "rt": RoadmapTrajOpt(world, roadmap),
        "rrtc": OmplPlanner(world, "RRTConnect", simplify=True)}
    for name, planner in planners.items():
        planner.warmup()
        out[name] = run_queries(world, planner, [
            (E[2 * i], Goal.configuration(E[2 * i + 1])) for i in range(n)], limit_s)
        out[f"{name}_pose"] = run_queries(world, planner, [
            (E[2 * i], Goal.pose(robot.compute_ee_pose(E[2 * i + 1])))
            for i in range(n_pose)], limit_s)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--arms", nargs="+", default=list(ARMS), choices=list(ARMS))
    ap.add_argument("--scenes", nargs="+", default=["tabletop_pole"])
    ap.add_argument("--queries", type=int, default=30)
    ap.add_argument("--pose-queries", type=int, default=20)
    ap.add_argument("--time-limit", type=float, default=2.0)
    ap.add_argument("--json", action="store_true", help="one JSON object per line only")
    args = ap.parse_args()
    for scene in args.scenes:
        for arm in args.arms:
            r = bench_arm(arm, scene, args.queries, args.pose_queries, args.time_limit)
            if args.json:
                print(json.dumps(r), flush=True)
                continue
            print(f"{arm} in {scene} ({r['dof']} DOF): roadmap {r['roadmap_s']:.1f} s, "
                  f"fast false alarms {100 * r['fast_false_alarm']:.1f}%")
            for key in ("rt", "rt_pose", "rrtc", "rrtc_pose"):
                s = r[key]
                print(f"  {key:10s} {s['statuses']} median {s['median_ms']:.1f} ms, "
                      f"p95 {s['p95_ms']:.1f} ms, length {s['mean_length_rad']}, "
                      f"exact failures {s['exact_failures']}", flush=True)


if __name__ == "__main__":
    main()
