"""Case commands: ``chekhov cases generate`` and ``chekhov cases info``.

    chekhov cases generate SCENE --n 5000 --seed S [--family random|tasks] [--out FILE]
                           [--solvability-limit S | --no-solvability] [--planners NAME...]
    chekhov cases info FILE [--scene SCENE]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from chekhov.cli import checks
from chekhov.errors import ChekhovError

MAX_CASES = 1_000_000


def _check_generate_args(args: argparse.Namespace) -> Path:
    """Check the scene, the planners and the output file before any work; returns the output
    path (default ``SCENE-sSEED-nN.npz``; ``SCENE-tasks-sSEED-nN.npz`` for the tasks
    family). Fills in the solvability defaults."""
    from chekhov.planners.registry import canonical_planner_name
    from chekhov.scene.io import load_scene

    scene = load_scene(args.scene)
    if args.no_solvability:
        for flag, value in (("--planners", args.planners),
                            ("--solvability-limit", args.solvability_limit)):
            if value is not None:
                raise ChekhovError(f"{flag} sets the solvability pass: not with --no-solvability")
    from chekhov.bench.solvability import DEFAULT_PLANNER, TIMED_LIMIT_S

    if args.solvability_limit is None:
        args.solvability_limit = math.inf if not args.planners else TIMED_LIMIT_S
    names: list[str] = []
    for given in args.planners or [DEFAULT_PLANNER]:
        try:
            name = canonical_planner_name(given)
        except ChekhovError as e:
            raise ChekhovError(f"--planners: {e}") from e
        if name in names:
            raise ChekhovError(f"--planners: {name} is listed twice in {args.planners}")
        names.append(name)
    args.planners = names
    family = "" if args.family == "random" else f"-{args.family}"
    out = args.out if args.out else f"{scene.name}{family}-s{args.seed}-n{args.n}.npz"
    return checks.output_file(out, "--out")


def _cmd_generate(args: argparse.Namespace) -> int:
    from chekhov.bench.solvability import solvability_pass
    from chekhov.cases import generate_cases
    from chekhov.planners.registry import make_planner
    from chekhov.roadmap.io import load_or_build_roadmap
    from chekhov.world import World

    out = _check_generate_args(args)
    world = World.load(args.scene)
    t0 = time.perf_counter()
    cases = generate_cases(world, args.n, args.seed, args.family)
    print(f"generated {len(cases)} cases of family {args.family} for '{world.scene.name}' "
          f"(seed {args.seed}) in {time.perf_counter() - t0:.1f} s")
    if not args.no_solvability:
        planners = [make_planner(name, world, lambda: load_or_build_roadmap(world),
                                 seed=args.seed) for name in args.planners]

        def progress(done: int, total: int) -> None:
            if sys.stderr.isatty() and (done % 10 == 0 or done == total):
                print(f"\rsolvability pass {done}/{total}", end="", file=sys.stderr, flush=True)

        rep = solvability_pass(world, cases, planners, args.solvability_limit,
                               progress=progress)
        if sys.stderr.isatty():
            print(file=sys.stderr)
        cases = rep.cases
        print(f"solvability pass ({rep.cases.solvability}): "
              f"{rep.replaced} replacement(s) for {len(rep.replaced_indices)} case(s)"
              + (f", {len(rep.unsolved_indices)} still unsolved" if rep.unsolved_indices else "")
              + f", {rep.time_s:.1f} s")
    cases.save(out)
    print(f"wrote {out}")
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    from chekhov.cases import CaseSet
    from chekhov.world import World

    checks.input_file(args.file, "case file")
    world = World.load(args.scene) if args.scene else None
    cases = CaseSet.load(args.file, world)
    meta = cases.meta()
    d = np.linalg.norm(cases.q_goal - cases.q_start, axis=1)
    print(f"{args.file}: {meta['format']} version {meta['version']}")
    print(f"  scene      {cases.scene} (content hash {cases.scene_hash[:12]})"
          + (" — matches" if world is not None else ""))
    print(f"  robot      {cases.robot} ({cases.dof} joints: {', '.join(cases.joint_names)})")
    print(f"  cases      {len(cases)} (seed {cases.seed}, {cases.replaced} replaced by "
          "solvability passes)")
    print(f"  family     {cases.family}")
    print(f"  solvability {cases.solvability or 'none recorded'}")
    if cases.family == "tasks":
        ready = sum(1 for x in cases.start_labels if x == "ready")
        place = sum(1 for x in cases.goal_labels if x.startswith("place:"))
        print(f"  starts     {ready} at the ready configuration, {len(cases) - ready} at "
              "pre-grasps")
        print(f"  goals      {len(cases) - place} pre-grasp poses, {place} place poses")
    print(f"  start→goal joint distance (rad): min {d.min():.2f}  median {np.median(d):.2f}  "
          f"max {d.max():.2f}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("cases", help="generate and inspect planning test cases")
    csub = p.add_subparsers(dest="cases_command", required=True)
    g = csub.add_parser("generate", help="start/goal cases for a scene (deterministic for a "
                        "seed), with the paper's solvability pass")
    g.add_argument("scene", help="built-in scene name or scene YAML file")
    g.add_argument("--n", type=checks.int_at_least(1, MAX_CASES), default=5000,
                   help="number of cases (default 5000)")
    g.add_argument("--seed", type=checks.SEED, default=0,
                   help=f"seed of the cases, 0..{checks.SEED_MAX} (default 0)")
    g.add_argument("--family", choices=checks.CASE_FAMILIES, default="random",
                   help="random: start and goal configurations uniform within the joint "
                        "limits (the paper's, default); tasks: from a pre-grasp (or the ready) "
                        "configuration to another object's pre-grasp or a place pose")
    g.add_argument("--out", metavar="FILE", help="output .npz (default SCENE-sSEED-nN.npz, "
                   "SCENE-tasks-sSEED-nN.npz for --family tasks)")
    g.add_argument("--solvability-limit", type=checks.positive_seconds, metavar="S",
                   help="time limit per planner and case of the solvability pass, s > 0 "
                        "(default: none for the default planner, whose node budget bounds "
                        "it and whose answers are the same on every machine; 1 s for "
                        "--planners)")
    g.add_argument("--planners", nargs="+", metavar="NAME",
                   help="planners of the solvability pass, registry names as for `chekhov "
                        "bench` (default RRTConnect(deterministic): seeded, node-bounded, "
                        "reproducible)")
    g.add_argument("--no-solvability", action="store_true",
                   help="skip the solvability pass (the cases are then exactly "
                        "generate_cases(n, seed, family))")
    g.set_defaults(func=_cmd_generate)
    i = csub.add_parser("info", help="summary of a case file")
    i.add_argument("file", metavar="FILE", help="case file (.npz)")
    i.add_argument("--scene", metavar="SCENE",
                   help="also check that the file belongs to this scene")
    i.set_defaults(func=_cmd_info)
