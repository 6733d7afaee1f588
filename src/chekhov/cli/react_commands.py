"""The reactive executive's scenario benchmark: ``chekhov react``.

    chekhov react [--scenes SCENE...] [--episodes N] [--seed S] [--planners NAME...]
                  [--budget-ms MS] [--free-compute | --compute-scale X] [--json] [--out FILE]

Per scene: pick-and-place episodes (moves between objects' pre-grasp poses) on a simulated
100 Hz clock, each with a person's forearm sweeping across (0.3-1.0 m/s, seen at 30 Hz with
40 ms latency), a goal change and a kick; the executed motion is checked afterwards with the
exact checker against each obstacle's true pose (``chekhov.execute``). The executive's own
compute is charged on the simulated clock: a step that runs past its 10 ms tick misses ticks,
the arm goes on along the motion it had, and the step's reactions count from the first
command after it (``--free-compute``: every step takes no time, as before 2026-11-27;
``--compute-scale X``: each step counts X times its wall time, as on a machine X times slower,
e.g. a robot's onboard computer; the executive's wall-clock budgets are not scaled).

Output: with ``--json`` one JSON object per scene and planner on stdout (keys: scene,
planner, episodes, success_rate — goal reached within tolerance before the deadline, among
the episodes whose undisturbed run reaches it (reachable_episodes) —, forearm_episodes (those
whose script has a forearm: none when 50 draws left no way out), collision_episodes,
unavoidable_collision_episodes, min_clearance_m and p5_clearance_m (over episodes' minimum
distance to the moving obstacles), reaction_latency_ms_p50/_p95/_p99 (disturbance observed →
first answering motion commanded: a rejoin, a hold short of the conflict, a brake, a dodge
or a new plan), resolve_latency_ms_p50/_p95/_p99 (→ a motion to the goal that answers it),
replans_per_episode, safe_stops, dodges, holds, swerves (kicked arms whose every smooth
move ran into something within a tick or two, sent on a sudden constant-acceleration swerve),
immediate_ms_max (the longest a kicked arm's immediate motion took to choose; the loop
commands it from the next tick), time_to_goal_ratio (median, against the
episode's task alone: its goal changes, no forearm, no kick), limit_violations,
overrun_steps (steps over a tick), undecided_checks (exact checks cut by their budget,
answered safe), lag_rejoins (joins back onto a motion after one), compute_charged,
compute_scale); else a table. ``--out`` also writes the JSON lines to a file (atomically).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import IO

from chekhov.cli import checks
from chekhov.errors import ChekhovError

DEFAULT_SCENES = ("tabletop_pole", "tabletop_container", "shelf_boxes", "kitchen",
                  "panda_table_shelf", "panda_cage")


def _check(args: argparse.Namespace) -> None:
    from chekhov.planners.registry import canonical_planner_name
    from chekhov.scene.io import load_scene

    for entry in args.scenes:
        try:
            load_scene(entry)
        except ChekhovError as e:
            raise type(e)(f"--scenes: {e}") from e
    names = []
    for given in args.planners:
        try:
            names.append(canonical_planner_name(given))
        except ChekhovError as e:
            raise ChekhovError(f"--planners: {e}") from e
    args.planners = names
    if args.free_compute and args.compute_scale != 1.0:
        raise ChekhovError("--compute-scale: has no effect with --free-compute (there every "
                           "step takes no time)")
    if args.out is not None:
        args.out = checks.output_file(args.out, "--out")


def _cmd_react(args: argparse.Namespace) -> int:
    from chekhov.execute.benchmark import ReactConfig, react_scene
    from chekhov.execute.interface import ExecutorConfig
    from chekhov.execute.simulate import SimConfig
    from chekhov.world import World

    _check(args)
    config = ReactConfig(episodes=args.episodes, seed=args.seed, planners=tuple(args.planners),
                         executor=replace(ExecutorConfig(),
                                          planning_budget_s=args.budget_ms / 1000,
                                          search_budget_s=None if args.free_compute else
                                          ExecutorConfig().search_budget_s),
                         sim=SimConfig(charge_compute=not args.free_compute,
                                       compute_scale=args.compute_scale))
    t0 = time.perf_counter()

    def progress(message: str) -> None:
        print(f"[{time.perf_counter() - t0:6.0f} s] {message}", file=sys.stderr, flush=True)

    lines: list[str] = []
    for entry in args.scenes:
        for row in react_scene(World.load(entry), config, progress):
            lines.append(json.dumps(row))
            print(lines[-1] if args.json else _table_row(row), flush=True)
        if args.out is not None:     # rewritten after each scene: a stopped run keeps them
            _write_lines(args.out, lines)
    return 0


def _write_lines(path: Path, lines: list[str]) -> None:
    from chekhov.atomic import write_atomic
    text = "\n".join(lines) + "\n"

    def write(f: IO[str]) -> None:
        f.write(text)
    write_atomic(path, write, "w")


def _table_row(row: dict[str, object]) -> str:
    def f(key: str, fmt: str = "{:.3g}") -> str:
        v = row.get(key)
        return "-" if v is None else fmt.format(v)
    return (f"{row['scene']:<20} {row['planner']:<16} success {f('success_rate', '{:.0%}')} "
            f"collisions {row['collision_episodes']} min clearance {f('min_clearance_m')} m "
            f"reaction p50/p95/p99 {f('reaction_latency_ms_p50')}/"
            f"{f('reaction_latency_ms_p95')}/{f('reaction_latency_ms_p99')} ms "
            f"replans/episode {f('replans_per_episode')} limit violations "
            f"{row['limit_violations']}")


def register(sub: argparse._SubParsersAction) -> None:
    r = sub.add_parser("react", help="the reactive executive's scenario benchmark",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    r.add_argument("--scenes", nargs="+", metavar="SCENE", default=list(DEFAULT_SCENES),
                   help="built-in scene names or scene YAML files (default: all six)")
    r.add_argument("--episodes", type=checks.int_at_least(1, 100_000), default=20,
                   help="episodes per scene (default 20)")
    r.add_argument("--seed", type=checks.SEED, default=0, help="episode stream (default 0)")
    r.add_argument("--planners", nargs="+", metavar="NAME", default=["Roadmap+TrajOpt"],
                   help="the executive's planner(s), each on the same episodes "
                        "(default Roadmap+TrajOpt; e.g. also TrajOpt)")
    r.add_argument("--budget-ms", type=checks.int_at_least(10, 5000), default=50,
                   help="a replan's budget, ms (default 50)")
    r.add_argument("--free-compute", action="store_true",
                   help="do not charge the executive's own compute on the simulated clock, "
                        "nor bound its searches in wall time (deterministic but optimistic)")
    r.add_argument("--compute-scale", type=checks.number_in(0.0, 100.0, "a factor"),
                   default=1.0, metavar="X",
                   help="count each step's compute X times its wall time, as on a machine X "
                        "times slower (default 1; > 0, at most 100)")
    r.add_argument("--json", action="store_true", help="one JSON object per line")
    r.add_argument("--out", metavar="FILE", help="also write the JSON lines here")
    r.set_defaults(func=_cmd_react)
