"""Scene commands: ``chekhov scenes``, ``chekhov show``, ``chekhov demo``."""

from __future__ import annotations

import argparse
import time
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from chekhov.cli import checks
from chekhov.errors import ChekhovError

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from chekhov.planners.result import PlanResult
    from chekhov.roadmap.graph import Roadmap
    from chekhov.world import World


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


def _load_path(path: str, dof: int) -> np.ndarray:
    """A trajectory (T, dof) from .npy, .npz (array "path", else the first) or a text file
    (one waypoint a row, comma or whitespace separated)."""
    p = Path(path)
    try:
        if p.suffix == ".npy":
            arr = np.load(p, allow_pickle=False)
        elif p.suffix == ".npz":
            with np.load(p, allow_pickle=False) as z:
                arr = z["path"] if "path" in z.files else z[z.files[0]]
        else:
            text = p.read_text()
            arr = np.loadtxt(p, delimiter="," if "," in text else None, ndmin=2)
        arr = np.atleast_2d(np.asarray(arr, dtype=float))
    except (OSError, ValueError, TypeError, IndexError, EOFError, zipfile.BadZipFile) as e:
        raise ChekhovError(f"--path {path}: cannot read a trajectory: {e}") from e
    if arr.ndim != 2 or arr.shape[1] != dof or len(arr) < 1:
        raise ChekhovError(f"--path {path}: expected waypoints of shape (T, {dof}) rad, "
                           f"got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ChekhovError(f"--path {path}: contains NaN or inf")
    return arr


ROADMAP_TRAJOPT = "Roadmap+TrajOpt"
SHOW_CACHED_CASES = 100
"""``show --case`` without ``--cases`` plans one of the first 100 cached cases of seed 0."""


def _check_show_args(args: argparse.Namespace) -> None:
    """Every argument of ``show`` that can be checked without loading the scene's world."""
    if args.path is not None and args.case is not None:
        raise ChekhovError("give --path or --case, not both")
    if args.case is None:
        for flag, value in (("--cases", args.cases), ("--planner", args.planner),
                            ("--roadmap", args.roadmap)):
            if value is not None:
                raise ChekhovError(f"{flag} is used only with --case N")
    from chekhov.bench.registry import uses_roadmap

    if args.case is not None:
        from chekhov.planners.registry import canonical_planner_name

        try:
            args.planner = canonical_planner_name(args.planner or ROADMAP_TRAJOPT)
        except ChekhovError as e:
            raise ChekhovError(f"--planner: {e}") from e
    if args.roadmap is not None and not uses_roadmap(args.planner):
        raise ChekhovError(f"--roadmap is used only by --planner {ROADMAP_TRAJOPT}, "
                           f"not {args.planner}")
    if args.case is not None and args.cases is None and args.case >= SHOW_CACHED_CASES:
        raise ChekhovError(f"--case {args.case}: without --cases the valid range is "
                           f"0..{SHOW_CACHED_CASES - 1} (cached cases of seed 0); for others, "
                           "write a case file (chekhov cases generate) and give --cases FILE")
    for flag, value in (("--path", args.path), ("--cases", args.cases),
                        ("--roadmap", args.roadmap)):
        if value is not None:
            checks.input_file(value, flag)
    if args.case is not None and args.cases is not None:
        from chekhov.cases import CaseSet

        n = len(CaseSet.load(args.cases))
        if args.case >= n:
            raise ChekhovError(f"--case {args.case}: --cases {args.cases} holds {n} cases, the "
                               f"valid range is 0..{n - 1}")
    checks.output_file(args.out, "--out")
    if Path(args.out).suffix.lower() != ".png":
        raise ChekhovError(f"--out {args.out}: the picture is a PNG: give a name ending in .png")
    if args.save_path is not None:
        if args.path is None and args.case is None:
            raise ChekhovError("--save-path needs a path to save: give --path or --case")
        if not args.save_path.endswith(".npy"):
            args.save_path += ".npy"  # as numpy.save names it
        checks.output_file(args.save_path, "--save-path")
    checks.distinct_outputs([("--path", args.path), ("--out", args.out),
                             ("--save-path", args.save_path)])


def _check_limits(world: World, Q: np.ndarray | None, arg: str) -> None:
    """Raise unless every row of ``Q`` (N, K) lies within the robot's joint limits (rad)."""
    if Q is None:
        return
    Q = np.atleast_2d(Q)
    inside = world.robot.within_limits(Q)
    if inside.all():
        return
    i = int(np.argmin(inside))
    r = world.robot
    bad = [f"{n} = {v:g} not in [{lo:g}, {hi:g}]" for n, v, lo, hi
           in zip(r.joint_names, Q[i], r.lower, r.upper, strict=True) if not lo <= v <= hi]
    where = f" (waypoint {i})" if len(Q) > 1 else ""
    raise ChekhovError(f"{arg}: outside the joint limits (rad){where}: {'; '.join(bad)}")


def _default_q(world: World) -> NDArray[np.float64]:
    """What ``show`` draws without --q: the robot's ready configuration (its SRDF's), else
    zero moved into the joint limits."""
    from chekhov._case_tasks import ready_configuration
    q = ready_configuration(world)
    return np.clip(np.zeros(world.robot.dof), world.robot.lower, world.robot.upper) \
        if q is None else q


def _cmd_show(args: argparse.Namespace) -> int:
    from chekhov.bench.files import write_file
    from chekhov.viewer.render import render_scene
    from chekhov.world import World

    _check_show_args(args)
    world = World.load(args.scene)
    q = _parse_q(args.q, world.robot.dof)
    _check_limits(world, q, "--q")
    path = seed = None
    note = ""
    if args.path is not None:
        path = _load_path(args.path, world.robot.dof)
        _check_limits(world, path, f"--path {args.path}")
        note = f", path of {len(path)} waypoints"
    elif args.case is not None:
        path, seed, note = _plan_case(world, args)
    if q is None and path is None:
        q = _default_q(world)
    out = render_scene(world, q=q, path=path, seed=seed, out=args.out, ghosts=args.ghosts,
                       title=args.title)
    if args.save_path and path is not None:
        drawn = path
        write_file(args.save_path, lambda f: np.save(f, drawn), mode="wb")
    shown = q if q is not None else path[0]  # type: ignore[index]
    free = world.is_free(shown)
    print(f"wrote {out} ({world.scene.name}, q {'free' if free else 'IN COLLISION'}{note})")
    return 0


def _plan_case(world: World, args: argparse.Namespace
               ) -> tuple[np.ndarray, np.ndarray | None, str]:
    """Plan case ``args.case`` with ``args.planner`` (a registry name, checked); (path, seed,
    a note for the output)."""
    from chekhov.cases import CaseSet, cached_cases
    from chekhov.planners.registry import make_planner
    from chekhov.roadmap.io import load_or_build_roadmap, load_roadmap

    cases = CaseSet.load(args.cases, world) if args.cases else cached_cases(
        world, max(20, args.case + 1))

    def roadmap() -> Roadmap:  # loaded only for the planners that use one
        return (load_roadmap(args.roadmap, world) if args.roadmap
                else load_or_build_roadmap(world))

    planner = make_planner(args.planner, world, roadmap)
    result = planner.plan(cases.q_start[args.case], cases.goal(args.case))
    if not result.success or result.path is None:
        raise ChekhovError(f"{args.planner} found no path for case {args.case}: "
                           f"{result.status}")
    timing = ", ".join(f"{k} {1e3 * v:.0f} ms" for k, v in result.timing_s.items())
    return result.path, seed_path(result), (f", {args.planner} case {args.case}: "
                                            f"{1e3 * result.time_s:.0f} ms ({timing}), "
                                            f"length {result.path_length:.2f} rad")


def seed_path(result: PlanResult) -> np.ndarray | None:
    """The seed a picture shows: the path of the stage the final optimisation started from
    when that was a route (the roadmap's, or another planner's), else ``result.seed`` (such as
    TrajOpt's straight line); (T', K) rad, or None."""
    from chekhov.planners.status import Stage

    report = result.seed_report
    if report is not None and report.stage in (Stage.ROADMAP_SEED, Stage.SEED) \
            and report.path is not None:
        return np.atleast_2d(np.asarray(report.path, dtype=float))
    return None if result.seed is None else np.atleast_2d(np.asarray(result.seed, dtype=float))


def _cmd_demo(args: argparse.Namespace) -> int:
    """The main job: per scene, load or build the roadmap, plan random cases with Roadmap +
    TrajOpt (every answer exactly checked), report timings, write a picture of one plan."""
    from chekhov.cases import generate_cases
    from chekhov.planners.base import path_length
    from chekhov.planners.registry import make_planner
    from chekhov.roadmap.io import load_or_build_roadmap
    from chekhov.scene.io import builtin_scenes
    from chekhov.viewer.render import render_scene
    from chekhov.world import World

    out = checks.output_dir(args.out, "--out")
    for name in builtin_scenes():
        world = World.load(name)
        t0 = time.perf_counter()
        roadmap = load_or_build_roadmap(world)
        t_map = time.perf_counter() - t0
        planner = make_planner("Roadmap+TrajOpt", world, roadmap)
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
        png = render_scene(world, q=shown[-1] if shown is not None else _default_q(world),
                           path=shown, out=out / f"{name}.png")
        n = len(cases.q_start)
        print(f"{name:20s} roadmap {roadmap.n_nodes} nodes ({t_map:4.1f} s)  solved {solved}/{n}"
              f"  exact-free {exact_ok}/{solved}  median {np.median(times):6.1f} ms  "
              f"mean {np.mean(times):6.1f} ms  length / roadmap seed "
              f"{np.mean(ratios) if ratios else float('nan'):.2f}  → {png}")
    return 0


def _register_show(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("show", help="write a picture of a scene with the robot")
    p.add_argument("scene", help="built-in scene name or scene YAML file")
    p.add_argument("--q", type=checks.finite_float, nargs="+",
                   help="joint values (rad), group order, within the joint limits")
    p.add_argument("--out", default="scene.png", metavar="FILE",
                   help="PNG file to write (default scene.png)")
    p.add_argument("--path", metavar="FILE",
                   help="trajectory to draw (robot ghosts along it): .npy, .npz or text, "
                        "(T, K) rad")
    p.add_argument("--case", type=checks.int_at_least(0), metavar="N",
                   help="plan this case (0-based; of --cases, else one of the first "
                        f"{SHOW_CACHED_CASES} cached cases) and draw the trajectory and its seed")
    p.add_argument("--cases", metavar="FILE", help="case file for --case")
    p.add_argument("--planner", default=None, metavar="NAME",
                   help=f"planner for --case, any of `chekhov bench`'s (TrajOpt, RRTConnect, "
                        f"LazyPRM+TrajOpt, …; default {ROADMAP_TRAJOPT})")
    p.add_argument("--roadmap", metavar="FILE",
                   help="roadmap file for --case (default: the cached one)")
    p.add_argument("--ghosts", type=checks.int_at_least(0, 200), default=6, metavar="N",
                   help="robot ghosts along the path (default 6)")
    p.add_argument("--title", help="picture title (default: the scene name)")
    p.add_argument("--save-path", metavar="FILE",
                   help="also save the drawn path as .npy (with --path or --case)")
    p.set_defaults(func=_cmd_show)


def register(sub: argparse._SubParsersAction) -> None:
    """Add the scene commands to the top-level parser."""
    sub.add_parser("scenes", help="list the built-in scenes").set_defaults(func=_cmd_scenes)
    _register_show(sub)
    p = sub.add_parser("demo", help="main job: roadmaps, Roadmap + TrajOpt plans, pictures")
    p.add_argument("--out", default="out/demo", metavar="DIR",
                   help="folder for the pictures (default out/demo)")
    p.add_argument("--cases", type=checks.int_at_least(1, 10_000), default=20, metavar="N",
                   help="random cases per scene (default 20)")
    p.set_defaults(func=_cmd_demo)
