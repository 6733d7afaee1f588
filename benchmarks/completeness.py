"""Does Roadmap + TrajOpt solve every case that RRTConnect solves? (issue 16), one JSON object
per scene and case family.

    python benchmarks/completeness.py --json                      # every built-in scene
    python benchmarks/completeness.py --scenes panda_cage --families empty_roadmap --cases 25

Families (deterministic per --seed):

* ``static``: random collision-free start; the goal, half the time (when the scene has
  objects with grasps) a pre-grasp pose with a free IK solution, else the end-effector pose
  of another random free configuration (every family picks goals so).
* ``dynamic``: the same with 6 random dynamic obstacles (boxes, spheres, cylinders of 4-12 cm)
  at the end-effector positions of random free configurations.
* ``boxed``: 3-5 boxes and spheres placed around the start configuration's end effector and
  elbow (4-9 cm from them, never touching the arm): the arm must work its way out.
* ``empty_roadmap``: the roadmap built in the scene emptied of its objects, and every object
  added as a dynamic obstacle (one roadmap reused while the world changes).

Each case is given to OMPL RRTConnect, to RRTConnect(deterministic) (ours: seeded,
node-bounded, a found path's edges certified lazily) and to Roadmap + TrajOpt with the same world,
the same --time-limit (s) and the same certification. Keys: scene, family, cases, time_limit_s,
rrtconnect_solved, roadmap_trajopt_solved, rrtconnect_only (solved by RRTConnect and not by
Roadmap + TrajOpt: the invariant says 0), roadmap_trajopt_only, neither (of those two),
repaired (answers whose seed came from the tree repair), rrtconnect_deterministic_solved,
rrtconnect_deterministic_only (solved by RRTConnect(deterministic) and not by Roadmap +
TrajOpt: 0 too), rrtconnect_median_ms / _p95_ms, rrtconnect_deterministic_median_ms / _p95_ms
and roadmap_trajopt_median_ms / _p95_ms (wall, solved cases), roadmap_trajopt_first_median_ms /
_p95_ms (its first certified answer), returned_collisions (per planner: answers the exact
checker rejects at 400 substeps per segment — a check four times denser than the
certification's; must be 0), statuses (Roadmap + TrajOpt's failures by status)."""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin

from chekhov import Goal, Shape, World, builtin_scenes, load_or_build_roadmap
from chekhov.cases import sample_free
from chekhov.planners.registry import make_planner
from chekhov.planners.status import Stage
from chekhov.roadmap.config import RoadmapConfig
from chekhov.roadmap.graph import Roadmap

FAMILIES = ("static", "dynamic", "boxed", "empty_roadmap")
Obstacles = dict[str, tuple[Shape, np.ndarray]]


def _shape(rng: np.random.Generator, i: int) -> Shape:
    kind = ("box", "sphere", "cylinder")[i % 3]
    s = rng.uniform(0.04, 0.12)
    return Shape(kind, {"box": (s, s, s), "sphere": (s / 2,), "cylinder": (s / 3, 2 * s)}[kind])


def _at(p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def random_obstacles(world: World, rng: np.random.Generator, n: int) -> Obstacles:
    """n shapes at the end-effector positions of random free configurations."""
    Q = sample_free(world, rng, n)
    return {f"dyn{i}": (_shape(rng, i), _at(world.robot.compute_ee_pose(q)[:3, 3]))
            for i, q in enumerate(Q)}


def boxing_obstacles(world: World, rng: np.random.Generator, q: np.ndarray) -> Obstacles:
    """3-5 shapes 4-9 cm from the end effector and elbow of q, around them."""
    robot = world.robot
    ee = robot.compute_ee_pose(q)[:3, 3]
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    elbow = np.array(data.oMi[robot.dof // 2 + 1].translation)
    out: Obstacles = {}
    for i in range(int(rng.integers(3, 6))):
        centre = ee if i % 2 == 0 else elbow
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        shape = _shape(rng, i)
        reach = float(np.max(shape.half_extents))
        out[f"box{i}"] = (shape, _at(centre + u * (reach + rng.uniform(0.04, 0.09) + 0.06)))
    return out


def pick_goal(world: World, rng: np.random.Generator, q1: np.ndarray,
              pregrasps: list[np.ndarray]) -> Goal:
    """Half the time (when the scene has any) a pre-grasp pose with a free IK solution in the
    world as it is now, else the end-effector pose of q1."""
    if pregrasps and rng.random() < 0.5:
        for i in rng.permutation(len(pregrasps))[:8]:
            goal = Goal.pose(pregrasps[int(i)])
            found = world.goal_ik.resolve(goal, n=1)
            if len(found) and world.exact.is_valid(found.Q[0]):
                return goal
    return Goal.pose(world.robot.compute_ee_pose(q1))


def make_case(world: World, family: str, rng: np.random.Generator,
              pregrasps: list[np.ndarray]) -> tuple[np.ndarray, Goal, Obstacles]:
    """(start, goal, dynamic obstacles) with the start and goal configurations free in the
    world with those obstacles (exact checker)."""
    for _ in range(200):
        q0, q1 = sample_free(world, rng, 2)
        obstacles: Obstacles = {}
        if family == "dynamic":
            obstacles = random_obstacles(world, rng, 6)
        elif family == "boxed":
            obstacles = boxing_obstacles(world, rng, q0)
        world.set_obstacles(obstacles)
        ok = world.is_free(q0) and world.is_free(q1)
        goal = pick_goal(world, rng, q1, pregrasps) if ok else None
        world.set_obstacles({})
        if goal is not None:
            return q0, goal, obstacles
    raise RuntimeError(f"{world.scene.name}/{family}: no free case in 200 tries")


def family_world(scene: str, family: str, cache: Path, config: RoadmapConfig | None = None
                 ) -> tuple[World, Roadmap, Obstacles]:
    """The planning world, its roadmap (``config``, default the default) and the obstacles
    every case adds."""
    world = World.load(scene)
    if family != "empty_roadmap":
        return world, load_or_build_roadmap(world, config, cache / f"{scene}.npz"), {}
    empty = World(replace(world.scene, name=f"{scene}_empty", objects=()), world.robot)
    fixed = {f"scene_{o.name}": (o.shape, o.T_world_obj()) for o in world.scene.objects}
    return empty, load_or_build_roadmap(empty, config, cache / f"{scene}_empty.npz"), fixed


def run_family(scene: str, family: str, n: int, time_limit: float, seed: int, cache: Path,
               config: RoadmapConfig | None = None) -> dict[str, object]:
    world, roadmap, fixed = family_world(scene, family, cache, config)
    rng = np.random.default_rng([seed, FAMILIES.index(family)])
    pregrasps = [T for o in World.load(scene).scene.objects for _, T in o.pregrasp_poses()]
    cases = []
    world.set_obstacles(fixed)
    for _ in range(n):
        q0, goal, extra = make_case(world, family, rng, pregrasps) if not fixed else (
            *_fixed_case(world, rng, pregrasps), {})
        cases.append((q0, goal, {**fixed, **extra}))
    world.set_obstacles({})
    planners = {"rrtconnect": make_planner("RRTConnect", world, seed=seed),
                "rrtconnect_deterministic": make_planner("RRTConnect(deterministic)", world,
                                                         seed=seed),
                "roadmap_trajopt": make_planner("Roadmap+TrajOpt", world, roadmap)}
    solved = {k: np.zeros(n, dtype=bool) for k in planners}
    times: dict[str, list[float]] = {k: [] for k in planners}
    first: list[float] = []
    statuses: dict[str, int] = {}
    collisions = {k: 0 for k in planners}
    repaired = 0
    for i, (q0, goal, obstacles) in enumerate(cases):
        world.set_obstacles(obstacles)
        for name, planner in planners.items():
            r = planner.plan(q0, goal, time_limit)
            if r.success and r.path is not None:
                solved[name][i] = True
                times[name].append(r.time_s * 1e3)
                if not world.exact.path_valid(r.path, substeps=400):
                    collisions[name] += 1
                    print(f"{scene}/{family} case {i}: {name}'s path collides at 400 "
                          f"substeps", file=sys.stderr)
                if name == "roadmap_trajopt":
                    repaired += r.seed_from == Stage.REPAIR
                    first.append(r.first_solution_s * 1e3)
            elif name == "roadmap_trajopt":
                statuses[str(r.status)] = statuses.get(str(r.status), 0) + 1
        world.set_obstacles({})
    a, b = solved["rrtconnect"], solved["roadmap_trajopt"]
    c = solved["rrtconnect_deterministic"]
    out: dict[str, object] = {
        "scene": scene, "family": family, "cases": n, "time_limit_s": time_limit,
        "rrtconnect_solved": int(a.sum()), "roadmap_trajopt_solved": int(b.sum()),
        "rrtconnect_only": int((a & ~b).sum()), "roadmap_trajopt_only": int((b & ~a).sum()),
        "neither": int((~a & ~b).sum()), "repaired": repaired,
        "rrtconnect_deterministic_solved": int(c.sum()),
        "rrtconnect_deterministic_only": int((c & ~b).sum())}
    for name, t in times.items():
        out[f"{name}_median_ms"] = round(float(np.median(t)), 2) if t else None
        out[f"{name}_p95_ms"] = round(float(np.percentile(t, 95)), 2) if t else None
    out["roadmap_trajopt_first_median_ms"] = round(float(np.median(first)), 2) if first else None
    out["roadmap_trajopt_first_p95_ms"] = (round(float(np.percentile(first, 95)), 2)
                                           if first else None)
    out["returned_collisions"] = collisions
    out["statuses"] = statuses
    return out


def _fixed_case(world: World, rng: np.random.Generator, pregrasps: list[np.ndarray]
                ) -> tuple[np.ndarray, Goal]:
    """A free start and a goal (:func:`pick_goal`) in the world as it is now."""
    q0, q1 = sample_free(world, rng, 2)
    return q0, pick_goal(world, rng, q1, pregrasps)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenes", nargs="+", default=builtin_scenes())
    ap.add_argument("--families", nargs="+", choices=FAMILIES, default=list(FAMILIES))
    ap.add_argument("--cases", type=int, default=20)
    ap.add_argument("--time-limit", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cache", type=Path, default=Path(".cache/completeness"))
    ap.add_argument("--json", action="store_true", help="one JSON object per line")
    args = ap.parse_args(argv)
    args.cache.mkdir(parents=True, exist_ok=True)
    for scene in args.scenes:
        for family in args.families:
            r = run_family(scene, family, args.cases, args.time_limit, args.seed, args.cache)
            print(json.dumps(r) if args.json else r, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
