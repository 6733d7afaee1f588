"""Benchmark commands: ``chekhov bench`` and ``chekhov report``.

    chekhov bench [--scenes SCENE...] [--planners NAME...] [--family random|tasks|both]
                  [--cases N] [--time-limit S]
                  [--db FILE] [--workers W] [--executor local|ray] [--address A]
                  [--summary-json FILE] [--csv FILE] [--case-seed S] [--case-file FILE...]
                  [--report DIR] [--no-share-seed-runs] [--no-progress]
    chekhov report DB --out DIR
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from chekhov.bench.config import DEFAULT_TIME_LIMIT_S, EXECUTORS
from chekhov.cli import checks
from chekhov.errors import ChekhovError

if TYPE_CHECKING:
    from chekhov.bench.config import BenchConfig

MAX_CASES = 1_000_000
# --family → the case families run
FAMILY_CHOICES = {"random": ("random",), "tasks": ("tasks",), "both": checks.CASE_FAMILIES}


def _check_scenes(names: list[str] | None) -> dict[str, str]:
    """``--scenes`` entry → the scene's name, each scene file read and checked (default: the
    built-in scenes)."""
    from chekhov.scene.io import builtin_scenes, load_scene

    out: dict[str, str] = {}
    for entry in names or builtin_scenes():
        try:
            name = load_scene(entry).name
        except ChekhovError as e:
            raise type(e)(f"--scenes: {e}") from e
        twin = next((e for e, n in out.items() if n == name), None)
        if twin is not None:
            raise ChekhovError(f"--scenes: scene '{name}' is listed twice ({twin}, {entry})")
        out[entry] = name
    return out


def _check_case_files(files: list[str] | None, scenes: dict[str, str],
                      families: tuple[str, ...] = ("random",)) -> tuple[tuple[str, str], ...]:
    """(``--scenes`` entry, case file) of each ``--case-file``, matched by the scene it was
    made for; at most one per scene and case family, of a family in ``families``."""
    from chekhov.cases import CaseSet

    entry_of = {name: entry for entry, name in scenes.items()}
    out: dict[tuple[str, str], str] = {}
    for f in files or []:
        checks.input_file(f, "--case-file")
        cases = CaseSet.load(f)
        scene, family = cases.scene, cases.family
        entry = entry_of.get(scene)
        if entry is None:
            raise ChekhovError(f"--case-file {f}: cases of scene '{scene}', which is not in "
                               f"--scenes {list(scenes)}")
        if family not in families:
            raise ChekhovError(f"--case-file {f}: cases of family '{family}', which --family "
                               f"does not run ({', '.join(families)})")
        if (entry, family) in out:
            raise ChekhovError(f"--case-file {f}: a second case file for scene '{scene}' "
                               f"and family '{family}' (first: {out[(entry, family)]})")
        out[(entry, family)] = str(f)
    return tuple((entry, f) for (entry, _), f in out.items())


def _check_outputs(args: argparse.Namespace) -> None:
    """Every file the command writes, checked before the database is created."""
    checks.sqlite_file(args.db, "--db", must_exist=False)
    for flag, value in (("--csv", args.csv), ("--summary-json", args.summary_json)):
        if value is not None:
            checks.output_file(value, flag)
    report = []
    if args.report is not None:
        d = checks.output_dir(args.report, "--report")
        report = [("--report", d / n) for n in ("report.md", "summary.json", "runs.csv")]
    checks.distinct_outputs([("--db", args.db), ("--csv", args.csv),
                             ("--summary-json", args.summary_json), *report])


def _check_bench_args(args: argparse.Namespace) -> BenchConfig:
    """The benchmark's settings, every argument checked before any file is created."""
    from chekhov.bench.config import BenchConfig
    from chekhov.bench.registry import expand_planner_names

    scenes = _check_scenes(args.scenes)
    try:
        planners = expand_planner_names(args.planners)
    except ChekhovError as e:
        raise type(e)(f"--planners: {e}") from e
    if args.executor == "ray" and importlib.util.find_spec("ray") is None:
        raise ChekhovError("--executor ray needs Ray: pip install 'chekhov[ray]'")
    families = FAMILY_CHOICES[args.family]
    case_files = _check_case_files(args.case_file, scenes, families)
    config = BenchConfig(scenes=tuple(scenes), planners=planners, families=families,
                         n_cases=args.cases, time_limit_s=args.time_limit,
                         case_seed=args.case_seed, case_files=case_files,
                         workers=args.workers, executor=args.executor, address=args.address,
                         share_seed_runs=not args.no_share_seed_runs)
    _check_outputs(args)
    return config


def _cmd_bench(args: argparse.Namespace) -> int:
    from chekhov.bench.database import BenchDatabase
    from chekhov.bench.files import write_text
    from chekhov.bench.runner import run_benchmark
    from chekhov.bench.summary import compute_stats, format_table, summary_json

    config = _check_bench_args(args)
    print(f"bench: {len(config.scenes)} scene(s) × {len(config.families)} case family(ies) "
          f"({', '.join(config.families)}) × {len(config.planners)} planner(s) × "
          f"{config.n_cases} case(s), time limit {config.time_limit_s:g} s per plan, "
          f"executor {config.executor}, database {args.db}", file=sys.stderr)
    out = run_benchmark(config, args.db, progress=not args.no_progress)
    print(f"bench: {out.ran} run(s) done, {out.skipped} already in {args.db}, "
          f"{out.time_s:.1f} s", file=sys.stderr)
    with BenchDatabase(args.db) as db:
        rows = db.rows([eid for _, eid in out.experiment_ids], list(config.planners),
                       config.n_cases)
        if args.csv:
            db.export_csv(args.csv)
    stats = compute_stats(rows)
    print(format_table(stats))
    if args.summary_json:
        doc = summary_json(stats, {"database": str(args.db),
                                   "time_limit_s": config.time_limit_s,
                                   "cases_per_scene": config.n_cases,
                                   "case_families": list(config.families),
                                   "planners": list(config.planners),
                                   "executor": config.executor,
                                   # planners running at once: times on a machine with fewer
                                   # cores than this share them
                                   "workers": config.local_workers if config.executor == "local"
                                   else config.workers})
        write_text(args.summary_json, json.dumps(doc, indent=1) + "\n")
        print(f"wrote {args.summary_json}", file=sys.stderr)
    if args.report:
        from chekhov.bench.report import write_report
        files = write_report(args.db, args.report)
        print(f"wrote {files.markdown}", file=sys.stderr)
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from chekhov.bench.report import write_report

    checks.sqlite_file(args.db, "DB", must_exist=True)
    out = checks.output_dir(args.out, "--out")
    checks.distinct_outputs([("DB", args.db), *(("--out", out / n) for n in
                                                 ("report.md", "summary.json", "runs.csv"))])
    files = write_report(args.db, args.out)
    print(f"wrote {files.markdown}, {files.summary_json.name}, {files.csv.name} and "
          f"{len(files.images)} PNG(s) in {Path(args.out)}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    from chekhov.bench.registry import GROUPS, PLANNER_NAMES

    b = sub.add_parser(
        "bench", help="run planners on the same cases of each scene into a results database",
        description="Run every selected planner on the same cases of every scene; each run's "
        "outcome, timing, path and exact collision check go to an SQLite database in OMPL's "
        "benchmark layout. Resumable: runs already in the database are skipped.")
    b.add_argument("--scenes", nargs="+", metavar="SCENE",
                   help="built-in scene names or scene files (default: all built-in scenes)")
    b.add_argument("--planners", nargs="+", default=["all"], metavar="NAME",
                   help=f"planners ({', '.join(PLANNER_NAMES)}) or groups "
                        f"({', '.join(f'{k}: {len(v)}' for k, v in GROUPS.items())}); "
                        "default all")
    b.add_argument("--family", choices=tuple(FAMILY_CHOICES), default="random",
                   help="case family: random (start and goal uniform within the joint limits, "
                        "the paper's; default), tasks (pre-grasp or ready configuration to "
                        "another object's pre-grasp or a place pose) or both, each its own "
                        "experiment")
    b.add_argument("--cases", type=checks.int_at_least(1, MAX_CASES), default=20, metavar="N",
                   help="cases per scene and family (default 20)")
    b.add_argument("--time-limit", type=checks.positive_seconds, default=DEFAULT_TIME_LIMIT_S,
                   metavar="S",
                   help=f"time limit of every plan call, s (default {DEFAULT_TIME_LIMIT_S:g}; "
                        "the paper: 300)")
    b.add_argument("--db", default="bench.db", metavar="FILE",
                   help="results database (created or resumed; default bench.db)")
    b.add_argument("--workers", type=checks.WORKERS, metavar="W",
                   help="worker processes / Ray actors (default: CPU count / cluster CPUs)")
    b.add_argument("--executor", choices=EXECUTORS, default="local",
                   help="local processes (default) or a Ray cluster")
    b.add_argument("--address", metavar="ADDR",
                   help="Ray cluster address (with --executor ray; default: a local Ray)")
    b.add_argument("--summary-json", metavar="FILE",
                   help="write per scene and planner statistics and runtime ratios as JSON")
    b.add_argument("--csv", metavar="FILE", help="also export every run of the database as CSV")
    b.add_argument("--case-seed", type=checks.SEED, default=0, metavar="S",
                   help=f"seed of generated cases, 0..{checks.SEED_MAX} (default 0)")
    b.add_argument("--case-file", nargs="+", metavar="FILE",
                   help="case files (chekhov cases generate) to use instead of generated "
                        "cases, one per scene and family")
    b.add_argument("--report", metavar="DIR", help="also write the report into DIR")
    b.add_argument("--no-share-seed-runs", action="store_true",
                   help="run X alone separately from X+TrajOpt (default: X's run is the seed "
                        "stage of X+TrajOpt's run on the same case)")
    b.add_argument("--no-progress", action="store_true", help="no progress bar")
    b.set_defaults(func=_cmd_bench)
    r = sub.add_parser("report", help="Markdown report with the paper's tables and PNG plots "
                       "from a benchmark database")
    r.add_argument("db", metavar="DB", help="benchmark database (chekhov bench --db)")
    r.add_argument("--out", required=True, metavar="DIR", help="output folder")
    r.set_defaults(func=_cmd_report)
