"""``chekhov report DB --out DIR``: a Markdown report of a benchmark database with tables in the
layout of the paper's Tables I–IV (the paper's numbers beside ours), medians and 95th
percentiles, how each planner was configured and the time limit, and PNG plots
(:mod:`chekhov.bench.plots`). Every file is written atomically.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from chekhov.bench import paper_results as paper
from chekhov.bench import plots
from chekhov.bench.database import BenchDatabase
from chekhov.bench.files import write_text
from chekhov.bench.paper_claims import claims_section
from chekhov.bench.summary import (
    ROADMAP,
    PlannerStats,
    Stats,
    StatsKey,
    compute_stats,
    format_table,
    length_ratios,
    runtime_ratios,
    stats_label,
    summary_json,
    targets,
)
from chekhov.errors import ChekhovError

SAMPLING = ("RRTConnect", "RRT", "LazyPRM", "RRT*", "PRM*")


@dataclass(frozen=True)
class ReportFiles:
    """What :func:`write_report` wrote: the Markdown file, the summary JSON, the CSV export
    and the PNGs."""

    markdown: Path
    summary_json: Path
    csv: Path
    images: tuple[Path, ...]


def write_report(db_path: str | Path, out_dir: str | Path) -> ReportFiles:
    """Write ``report.md``, ``summary.json``, ``runs.csv`` and the PNGs into ``out_dir``."""
    db_path, out = Path(db_path), Path(out_dir)
    if not db_path.is_file():
        raise ChekhovError(f"{db_path}: no such benchmark database")
    with BenchDatabase(db_path) as db:
        rows = db.rows()
        if not rows:
            raise ChekhovError(f"{db_path}: the database holds no runs")
        roadmap_rows = db.rows(planners=[ROADMAP], paths=True)
        experiments = db.experiments()
        configs = db.planner_configs()
        csv_path = db.export_csv(out / "runs.csv")
    stats = compute_stats(rows)
    images = [plots.runtime_distribution(rows, stats, out / "runtime_distribution.png"),
              plots.failure_rate(stats, out / "failure_rate.png"),
              plots.path_length(stats, out / "path_length.png")]
    fig3 = plots.figure3(roadmap_rows, out / "figure3.png")
    if fig3 is not None:
        images.append(fig3)
    summary = summary_json(stats, {"database": str(db_path)})
    js = out / "summary.json"
    write_text(js, json.dumps(summary, indent=1) + "\n")
    md = out / "report.md"
    write_text(md, markdown(db_path, stats, experiments, configs, rows,
                             [p.name for p in images]))
    return ReportFiles(md, js, csv_path, tuple(images))


# --- Markdown ------------------------------------------------------------------------------
def markdown(db_path: Path, stats: Stats, experiments: list[dict[str, Any]],
             configs: list[dict[str, Any]], rows: list[dict[str, Any]],
             images: list[str]) -> str:
    """The report: how it was produced, the summary, the paper's Tables I–IV beside ours, its
    qualitative claims re-checked and its path lengths beside ours (:mod:`.paper_claims`), the
    plots (``images``: file names beside the report), failure kinds and the planners'
    settings (``configs``: plannerConfigs rows; ``rows``: the runs)."""
    cases = {k: max(s.cases for s in v.values()) for k, v in stats.items()}
    L = [*_introduction(db_path, experiments, cases),
         *_how_produced(db_path, stats, experiments, cases),
         "## Summary\n", _summary_table(stats), *_targets_section(stats),
         "\n" + _table_i(stats), "\n" + _table_ii(stats), "\n" + _table_iii(stats),
         "\n" + _table_iv(stats), "", *claims_section(stats, rows),
         "\n## Plots\n", *(f"![{n}]({n})\n" for n in images),
         *_failure_kinds(stats), *_configurations(configs, rows)]
    scenes = sorted({k.scene for k in stats})
    planners = plots.planner_order(sorted({n for v in stats.values() for n in v}))
    L.append(f"Planners in this report: {', '.join(planners)}. Scenes: {', '.join(scenes)}.\n")
    return "\n".join(L) + "\n"


def _introduction(db_path: Path, experiments: list[dict[str, Any]],
                  cases: dict[StatsKey, int]) -> list[str]:
    """Title, time limits, cases per scene and family (``cases``), the exact check."""
    limits = sorted({float(e["timelimit"]) for e in experiments})
    return [
        "# Chekhov benchmark report\n",
        f"Database `{db_path.name}`, report written {time.strftime('%Y-%m-%d %H:%M')}. "
        f"**Time limit per planning call: {', '.join(f'{x:g} s' for x in limits)}** "
        f"(the paper: {paper.PAPER_TIME_LIMIT_S:g} s). RRT* and PRM* optimise path length and "
        "run to the limit, as in the paper. Cases per scene: "
        + ", ".join(f"{stats_label(k, cases)} {n}" for k, n in sorted(cases.items()))
        + f" (the paper: {paper.PAPER_CASES}). Every returned path is re-checked by the runner "
        "with the exact checker (pinocchio + coal on the URDF geometry) at "
        f"{_substeps(experiments)} interpolated configurations per segment — the paper's "
        "continuous-time check — independently of the planner. Case families: "
        + ", ".join(sorted({k.family for k in cases})) + " (random: start and goal "
        "configurations uniform within the joint limits; tasks: from a pre-grasp or ready "
        "configuration to another object's pre-grasp pose or a place pose, issue 17); a "
        "scene's families stand side by side in every table.\n"]


def _how_produced(db_path: Path, stats: Stats, experiments: list[dict[str, Any]],
                  cases: dict[StatsKey, int]) -> list[str]:
    """The commands that reproduce the database, its experiments, how times were measured."""
    L = ["## How it was produced\n", "```"]
    files = {(e["name"], e.get("family") or "random"): str(e["case_source"]).split()[1]
             for e in experiments if str(e["case_source"]).startswith("file ")}
    for key, n in sorted(cases.items()):
        scene, limit, family = key
        ps = " ".join(f"'{p}'" for p in plots.planner_order(list(stats[key])))
        cf = (f" --case-file cases/{files[(scene, family)]}" if (scene, family) in files
              else "")
        fam = "" if family == "random" else f" --family {family}"
        L.append(f"chekhov bench --scenes {scene}{fam} --planners {ps} --cases {n} "
                 f"--time-limit {limit:g}{cf} --db {db_path.name}")
    L += [f"chekhov report {db_path.name} --out DIR", "```\n"]
    if files:
        L.append("Case files (`chekhov cases generate SCENE --n N --seed S`, with the paper's "
                 "solvability pass) are read from `cases/` beside this report.\n")
    L += [f"* experiment {e['id']} `{e['name']}` ({e.get('family') or 'random'} cases): "
          f"cases {e['case_source']}, limit "
          f"{e['timelimit']:g} s, motion-check resolution {e['resolution']:g} rad, "
          f"{e['version']}, host {e['hostname']} ({e['cpuinfo']}), started {e['date']}, "
          f"{e['totaltime']:.0f} s of planning and checking in all." for e in experiments]
    L.append("\nTimes are wall-clock seconds of `plan()` up to its certified answer (IK, "
             "seeding, optimisation and the planner's own validation included; the timing of "
             "the answer that follows, `info[\"time_parameterize_s\"]`, and the runner's exact "
             "check excluded), measured "
             "with several runs in parallel on a shared machine: compare ratios rather than "
             "absolute values. A failure is any run without a collision-free path "
             "(no path, or a path the exact check rejects), as in the paper.\n")
    return L


def _targets_section(stats: Stats) -> list[str]:
    """Roadmap+TrajOpt against the issue's targets, per scene (nothing without it)."""
    goals = {k: targets(v) for k, v in stats.items() if ROADMAP in v}
    if not goals:
        return []
    names = list(next(iter(goals.values())))
    L = ["\n### Roadmap+TrajOpt against the issue's targets\n",
         "| scene | " + " | ".join(n.replace("_", " ") for n in names) + " |",
         "|---|" + "---|" * len(names)]
    L += [f"| {_scene(key, stats)} | "
          + " | ".join("yes" if g[n] else "**no**" for n in names) + " |"
          for key, g in sorted(goals.items())]
    return L


def _failure_kinds(stats: Stats) -> list[str]:
    """Runs by outcome, per scene and planner."""
    L = ["## Failure kinds\n", "| scene | planner | runs by outcome |", "|---|---|---|"]
    for key, per in sorted(stats.items()):
        for pname in plots.planner_order(list(per)):
            L.append(f"| {_scene(key, stats)} | {pname} | "
                     + ", ".join(f"{k} {v}" for k, v in per[pname].statuses.items()) + " |")
    return L


def _configurations(configs: list[dict[str, Any]], rows: list[dict[str, Any]]) -> list[str]:
    """How each planner was configured: the common setup, shared seed runs, and the
    settings of every planner that has runs."""
    L = ["\n## How each planner was configured\n",
         "All planners check states and motions with the same fast checker (robot spheres "
         "against the scene's primitives) at the same joint-space resolution; goals are the "
         "goal pose (5 mm / 0.05 rad), reached through IK solutions. OMPL planners keep OMPL's "
         "own defaults (range, goal bias, rewiring); approximate OMPL solutions count as "
         "failures. X+TrajOpt gives X's path, resampled to ≤ 0.16 rad, to TrajOpt as its seed "
         "(the paper's Table II); TrajOpt's validation re-checks its trajectory exactly, and a "
         "rejected trajectory is a failure. Roadmap+TrajOpt falls back to its exactly checked "
         "seed when TrajOpt's trajectory is rejected. The planner's time limit bounds IK and "
         "the search; TrajOpt stages run under TrajOpt's own limit (in the settings) capped "
         "by what is left of it for X+TrajOpt; Roadmap+TrajOpt's seeder has its own caps.\n"]
    # the database's info column: the stored record of a shared seed run
    shared = sum(1 for r in rows if "seed_stage_of" in (r.get("info") or {}))
    if shared:
        L.append(f"{shared} runs of a sampling-based planner X are the seed stage of "
                 "X+TrajOpt's run on the same case (`chekhov bench` default; "
                 "`--no-share-seed-runs` runs them apart): the same planner with the same seed "
                 "and limit, so its outcome is what a separate run would give, at half the "
                 "cost for RRT* and PRM*, which run to the limit. Their `info` says "
                 "`seed_stage_of`.\n")
    used = {r["plannerid"] for r in rows}
    L += [f"* **{c['name']}** (plannerConfigs.id {c['id']}): `{_short(c['settings'])}`"
          for c in configs if c["id"] in used]
    L.append("\nFull settings: `SELECT name, settings FROM plannerConfigs` in the database.\n")
    return L


def _substeps(experiments: list[dict[str, Any]]) -> str:
    return "/".join(sorted({str(e["exact_substeps"]) for e in experiments}))


def _short(settings: str, limit: int = 600) -> str:
    return settings if len(settings) <= limit else settings[:limit] + " …"


def _scene(key: StatsKey, stats: Stats) -> str:
    return stats_label(key, stats)


def _pc(x: float | None) -> str:
    return "—" if x is None or not math.isfinite(x) else f"{100 * x:.2f}%"


def _s(x: float | None, prec: int = 3) -> str:
    return "—" if x is None or not math.isfinite(x) else f"{x:.{prec}f}"


def _both(ours: str, theirs: str) -> str:
    return f"{ours} ({theirs})"


def _summary_table(stats: Stats) -> str:
    L = ["| scene | planner | cases | failure rate | mean / median / p95 runtime (s) | "
         "median / p95 first solution (s) | mean / median path length (rad) | "
         "mean / median motion duration (s) | collision "
         "rate (exact) | Roadmap+TrajOpt runtime ratio mean / median | Roadmap+TrajOpt "
         "length ratio, common cases |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]
    for key, per in sorted(stats.items()):
        rat = runtime_ratios(per)
        lrat = length_ratios(per)
        for n in plots.planner_order(list(per)):
            s = per[n]
            r = rat.get(n)
            L.append(f"| {_scene(key, stats)} | {n} | {s.cases} | "
                     f"{_pc(s.failure_rate)} | {_s(s.mean_runtime_s)} / "
                     f"{_s(s.median_runtime_s)} / {_s(s.p95_runtime_s)} | "
                     f"{_s(s.median_first_solution_s)} / {_s(s.p95_first_solution_s)} | "
                     f"{_s(s.mean_path_length_rad, 2)} / {_s(s.median_path_length_rad, 2)} | "
                     f"{_s(s.mean_duration_s, 2)} / {_s(s.median_duration_s, 2)} | "
                     f"{_pc(s.collision_rate)} | "
                     + (f"{_s(r['mean'])} / {_s(r['median'])}" if r else "—") + " | "
                     + _s(lrat.get(n), 3) + " |")
    L.append("\nRuntime ratio < 1: Roadmap+TrajOpt is faster than that planner. Length ratio: "
             "Roadmap+TrajOpt's mean path length over that planner's on the cases both "
             "solved (the mean path length column averages each planner's own solved cases, "
             "which favours planners that fail the hard ones).\n")
    L.append("```\n" + format_table(stats) + "\n```")
    return "\n".join(L)


def _rows_for(stats: Stats, names: tuple[str, ...],
              line: Callable[[StatsKey, str, PlannerStats], str]) -> list[str]:
    out = []
    for key, per in sorted(stats.items()):
        for n in names:
            if n in per:
                out.append(line(key, n, per[n]))
    if not out:
        out.append(f"\n(No runs of {', '.join(names)} in this database.)")
    return out


def _table_i(stats: Stats) -> str:
    L = ["## Table I — stand-alone planners\n",
         "Layout of the paper's Table I; the paper's value in parentheses (— where it has "
         "none: it reports 'tabletop with a pole' and 'shelf with boxes' only, and its 'RRT' "
         "is OpenRAVE's bidirectional BasicRRT, our RRTConnect). Paper: 5000 cases, 300 s.\n",
         "| Environment | Planner | Failure rate | Average runtime (s) | Median runtime (s) | "
         "p95 runtime (s) | Average path length (rad) | Median path length (rad) |",
         "|---|---|---|---|---|---|---|---|"]

    def line(key: StatsKey, n: str, s: PlannerStats) -> str:
        scene = key.scene
        p = paper.TABLE_I.get(scene, {}).get(paper.PAPER_PLANNER.get(n, ""))
        return (f"| {_env(key, stats)} | {_pname(n)} | "
                f"{_both(_pc(s.failure_rate), _pc(p[0]) if p else '—')} | "
                f"{_both(_s(s.mean_runtime_s), _s(p[1], 2) if p else '—')} | "
                f"{_s(s.median_runtime_s)} | {_s(s.p95_runtime_s)} | "
                f"{_both(_s(s.mean_path_length_rad, 2), _s(p[2], 2) if p else '—')} | "
                f"{_s(s.median_path_length_rad, 2)} |")

    return "\n".join(L + _rows_for(stats, (*SAMPLING, "TrajOpt"), line))


def _table_ii(stats: Stats) -> str:
    L = ["## Table II — sampling-based seed + TrajOpt\n",
         "Layout of the paper's Table II. Collision rate: among runs whose seed planner found "
         "a path, the share whose TrajOpt trajectory was rejected (colliding by the exact "
         "check, or infeasible) — the paper's TrajOpt outputs in collision. Our combined "
         "planner returns no path then (a failure), so the exact collision rate of *returned* "
         "paths is given separately.\n",
         "| Environment | Seed planner | Average TrajOpt runtime (s) | Average runtime (s) | "
         "Median runtime (s) | p95 runtime (s) | Average path length (rad) | Collision rate | "
         "Seed failure rate | Failure rate | Returned paths in collision |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]

    def line(key: StatsKey, n: str, s: PlannerStats) -> str:
        scene = key.scene
        seed = n.removesuffix("+TrajOpt")
        p = paper.TABLE_II.get(scene, {}).get(paper.PAPER_PLANNER.get(seed, ""))
        return (f"| {_env(key, stats)} | {_pname(seed)} | "
                f"{_both(_s(s.mean_trajopt_time_s), _s(p[0], 2) if p else '—')} | "
                f"{_both(_s(s.mean_runtime_s), _s(p[1], 2) if p else '—')} | "
                f"{_s(s.median_runtime_s)} | {_s(s.p95_runtime_s)} | "
                f"{_both(_s(s.mean_path_length_rad, 2), _s(p[2], 2) if p else '—')} | "
                f"{_both(_pc(s.trajopt_rejection_rate), _pc(p[3]) if p else '—')} | "
                f"{_pc(s.seed_failure_rate)} | {_pc(s.failure_rate)} | "
                f"{_pc(s.collision_rate)} |")

    return "\n".join(L + _rows_for(stats, tuple(f"{x}+TrajOpt" for x in SAMPLING), line))


def _table_iii(stats: Stats) -> str:
    L = ["## Table III — the roadmap alone (Roadmap+TrajOpt's seed stage)\n",
         "Layout of the paper's Table III, from the seed stage of the Roadmap+TrajOpt runs: "
         "failure = no roadmap path (no IK solution, or no connection of start or goal to the "
         "roadmap); runtime = the seed stage (IK, connection, cached shortest path); path "
         "length = the roadmap's path before shortcutting. Best average: the shortest mean "
         "path length of the stand-alone sampling-based planners in that scene.\n",
         "| Environment | Failure rate | Average runtime (s) | Median runtime (s) | "
         "p95 runtime (s) | Average path length (rad) | Best average (rad) |",
         "|---|---|---|---|---|---|---|"]
    for key, per in sorted(stats.items()):
        s = per.get(ROADMAP)
        if s is None:
            continue
        p = paper.TABLE_III.get(key.scene)
        best = [per[n].mean_path_length_rad for n in SAMPLING
                if n in per and math.isfinite(per[n].mean_path_length_rad)]
        L.append(f"| {_env(key, stats)} | "
                 f"{_both(_pc(s.seed_failure_rate), _pc(p[0]) if p else '—')} | "
                 f"{_both(_s(s.mean_seed_time_s), _s(p[1], 2) if p else '—')} | "
                 f"{_s(s.median_seed_time_s)} | {_s(s.p95_seed_time_s)} | "
                 f"{_both(_s(s.mean_seed_length_rad, 2), _s(p[2], 2) if p else '—')} | "
                 f"{_both(_s(min(best), 2) if best else '—', _s(p[3], 2) if p else '—')} |")
    return "\n".join(L)


def _table_iv(stats: Stats) -> str:
    L = ["## Table IV — TrajOpt seeded by sampling-based planners and by the roadmap\n",
         "Layout of the paper's Table IV. TrajOpt runtime: everything after the seed stage "
         "(for Roadmap+TrajOpt: shortcut, TrajOpt, validation). Collision rate as in Table II "
         "(for Roadmap+TrajOpt: TrajOpt's trajectory rejected; it then returns its checked "
         "seed, see the fallback column).\n",
         "| Environment | Seed planner | Average TrajOpt runtime (s) | Average seed length "
         "(rad) | Average runtime (s) | Median runtime (s) | p95 runtime (s) | Average path "
         "length (rad) | Collision rate | Failure rate | Fallback to seed |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]

    def line(key: StatsKey, n: str, s: PlannerStats) -> str:
        scene = key.scene
        seed = n.removesuffix("+TrajOpt")
        seed = "Roadmap+TrajOpt" if n == ROADMAP else seed
        p = paper.TABLE_IV.get(scene, {}).get(paper.PAPER_PLANNER.get(seed, ""))
        return (f"| {_env(key, stats)} | "
                f"{'Roadmap' if n == ROADMAP else _pname(seed)} | "
                f"{_both(_s(s.mean_trajopt_time_s), _s(p[0], 2) if p else '—')} | "
                f"{_both(_s(s.mean_seed_length_rad, 2), _s(p[1], 2) if p else '—')} | "
                f"{_both(_s(s.mean_runtime_s), _s(p[2], 2) if p else '—')} | "
                f"{_s(s.median_runtime_s)} | {_s(s.p95_runtime_s)} | "
                f"{_both(_s(s.mean_path_length_rad, 2), _s(p[3], 2) if p else '—')} | "
                f"{_both(_pc(s.trajopt_rejection_rate), _pc(p[4]) if p else '—')} | "
                f"{_pc(s.failure_rate)} | {_pc(s.fallback_rate)} |")

    names = ("RRTConnect+TrajOpt", "LazyPRM+TrajOpt", "RRT*+TrajOpt", ROADMAP)
    return "\n".join(L + _rows_for(stats, names, line))


def _env(key: StatsKey, stats: Stats) -> str:
    """The paper's title of the scene, with the time limit and family as in
    :func:`stats_label`."""
    label = stats_label(key, stats)
    return paper.SCENE_TITLES.get(key.scene, key.scene) + label[len(key.scene):]


def _pname(n: str) -> str:
    return "RRTConnect (paper: RRT)" if n == "RRTConnect" else n
