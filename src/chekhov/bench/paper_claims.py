"""The paper's qualitative claims re-checked on a benchmark run, and our mean path lengths beside
the paper's (issue 17). Each verdict is computed from the run's statistics; a claim whose
planners the run lacks is "not measured".

The claims (Dai et al., Sections IV-A to IV-C):

* ``straight_line_fails_most``: TrajOpt from a straight line fails more often than every other
  planner (Table I: "TrajOpt fails more frequently ... than any other planners").
* ``seed_fails_less``: with a collision-free seed (X+TrajOpt, Roadmap+TrajOpt) TrajOpt fails
  less than from a straight line (Section IV-B: "improves tremendously in terms of ... success
  rate").
* ``seed_runs_faster``: and its optimisation runs faster: the seeded planner's TrajOpt stage
  (everything after the seed) against straight-line TrajOpt's whole runtime ("when provided
  with a good seed, the TrajOpt runtime generally decreased").
* ``sampling_too_slow``: a sampling-based seed is too slow for reaction: X+TrajOpt's 95th
  percentile runtime exceeds the reactive executive's planning budget
  (:class:`chekhov.execute.executor.ExecutorConfig`, 50 ms). The paper's own bar for "fast
  reaction" (a mean under 1 s) is shown beside it.
* ``roadmap_wins``: Roadmap+TrajOpt has a lower mean runtime than every sampling-seeded
  planner (X+TrajOpt; the paper's variant of the roadmap planner, ``Roadmap+TrajOpt(paper)``,
  is a roadmap seed too, not a rival) and a failure rate of at most 2% (the paper's "success
  rate of above 98%").
* ``optimised_shorter``: Roadmap+TrajOpt's returned paths are at least 10% shorter than their
  roadmap seeds (Section IV-C: "on average more than 10% shorter than their corresponding seed
  trajectories"), on the runs whose answer came from a roadmap seed optimised by TrajOpt
  (``seed_kind`` "roadmap", no fallback to the seed): mean returned length over mean seed
  length on those runs. The database records each run's roadmap seed (before shortcutting)
  and its length.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any, NamedTuple

from chekhov.bench import paper_results as paper
from chekhov.bench.plots import planner_order
from chekhov.bench.summary import ROADMAP, PlannerStats, Stats, StatsKey
from chekhov.execute.interface import ExecutorConfig
from chekhov.planners.registry import seed_planner_name

REACTION_BUDGET_S = ExecutorConfig().planning_budget_s
"""s, the reactive executive's time for one replan: the budget a reacting planner must meet."""
PAPER_REACTIVE_MEAN_S = 1.0
"""s, the paper's bar for fast reaction ("average runtime of under 1 sec")."""
LOW_FAILURE = 0.02
"""The paper's "success rate of above 98%"."""
SHORTER_BY = 0.10
"""The paper's "more than 10% shorter than their corresponding seed trajectories"."""

YES, NO, PARTLY, NOT_MEASURED = "yes", "no", "partly", "not measured"


class Verdict(NamedTuple):
    """Whether a claim holds in one scene ("yes", "no", "partly": for some of the planners it
    is about, "not measured"), and the numbers that say so."""

    holds: str
    evidence: str


class SeedShortening(NamedTuple):
    """Roadmap+TrajOpt's returned paths against their roadmap seeds, in one scene and family.

    Attributes:
        cases: runs compared (solved, answer from a roadmap seed optimised by TrajOpt).
        solved: Roadmap+TrajOpt's solved runs (the others came from another seed or were the
            seed itself, TrajOpt's trajectory rejected).
        mean_seed_rad: mean roadmap seed length (before shortcutting) on those runs.
        mean_final_rad: mean returned path length on those runs.
    """

    cases: int
    solved: int
    mean_seed_rad: float
    mean_final_rad: float


PerPlanner = dict[str, PlannerStats]
Check = Callable[[PerPlanner, SeedShortening | None], Verdict]


class Claim(NamedTuple):
    """One of the paper's claims: its key, how the report words it, and its check."""

    key: str
    text: str
    check: Check


def seed_shortenings(rows: Iterable[dict[str, Any]]) -> dict[StatsKey, SeedShortening]:
    """Per (scene, time limit, family): Roadmap+TrajOpt's returned lengths against its
    recorded seed lengths, from :meth:`BenchDatabase.rows` dicts (their ``seed_length``,
    ``fallback_to_seed`` and ``info["seed_kind"]``)."""
    groups: dict[StatsKey, list[dict[str, Any]]] = {}
    for r in rows:
        if r["planner"] == ROADMAP and r["success"]:
            key = StatsKey(r["scene"], float(r["timelimit"]), r.get("family") or "random")
            groups.setdefault(key, []).append(r)
    out = {}
    for key, rs in groups.items():
        pairs = [(float(r["seed_length"]), float(r["solution_length"])) for r in rs
                 if _from_roadmap_seed(r)]
        out[key] = SeedShortening(
            len(pairs), len(rs),
            math.fsum(s for s, _ in pairs) / len(pairs) if pairs else math.nan,
            math.fsum(f for _, f in pairs) / len(pairs) if pairs else math.nan)
    return out


def _from_roadmap_seed(r: dict[str, Any]) -> bool:
    """The run's answer is TrajOpt's from its roadmap seed, whose length is recorded."""
    seed = r.get("seed_length")
    kind = (r.get("info") or {}).get("seed_kind", "roadmap")
    return (seed is not None and math.isfinite(seed) and seed > 0 and kind == "roadmap"
            and not r.get("fallback_to_seed"))


# --- the checks ------------------------------------------------------------------------------
def _seeded(per: PerPlanner) -> list[str]:
    """The planners in ``per`` that give TrajOpt a collision-free seed."""
    return [n for n in sorted(per)
            if seed_planner_name(n) is not None or n.startswith(ROADMAP)]


def _sampling_seeded(per: PerPlanner) -> list[str]:
    """The planners in ``per`` whose seed is a sampling-based planner's (X+TrajOpt)."""
    return [n for n in sorted(per) if seed_planner_name(n) is not None]


def _combine(results: list[bool]) -> str:
    if not results:
        return NOT_MEASURED
    return YES if all(results) else NO if not any(results) else PARTLY


def check_straight_line_fails_most(per: PerPlanner, _: SeedShortening | None = None) -> Verdict:
    """TrajOpt's failure rate above every other planner's."""
    t = per.get("TrajOpt")
    others = [n for n in sorted(per) if n != "TrajOpt"]
    if t is None or not _seeded(per):
        return Verdict(NOT_MEASURED, _missing(per, "TrajOpt and a seeded planner"))
    holds = all(t.failure_rate > per[n].failure_rate for n in others)
    return Verdict(YES if holds else NO, f"fail: TrajOpt {_pc(t.failure_rate)} vs "
                   + ", ".join(f"{n} {_pc(per[n].failure_rate)}" for n in others))


def check_seed_fails_less(per: PerPlanner, _: SeedShortening | None = None) -> Verdict:
    """Every seeded planner's failure rate below straight-line TrajOpt's."""
    t, seeded = per.get("TrajOpt"), _seeded(per)
    if t is None or not seeded:
        return Verdict(NOT_MEASURED, _missing(per, "TrajOpt and a seeded planner"))
    return Verdict(
        _combine([per[n].failure_rate < t.failure_rate for n in seeded]),
        f"fail: TrajOpt {_pc(t.failure_rate)} vs " + ", ".join(
            f"{n} {_pc(per[n].failure_rate)} (TrajOpt rejected "
            f"{_pc(per[n].trajopt_rejection_rate)} of its seeds)" for n in seeded))


def check_seed_runs_faster(per: PerPlanner, _: SeedShortening | None = None) -> Verdict:
    """Every seeded planner's mean TrajOpt stage faster than straight-line TrajOpt's mean
    runtime (a planner without a measured TrajOpt stage is left out)."""
    t, seeded = per.get("TrajOpt"), _seeded(per)
    timed = [n for n in seeded if math.isfinite(per[n].mean_trajopt_time_s)]
    if t is None or not timed:
        return Verdict(NOT_MEASURED, _missing(per, "TrajOpt and a seeded planner's TrajOpt "
                                                    "stage"))
    return Verdict(
        _combine([per[n].mean_trajopt_time_s < t.mean_runtime_s for n in timed]),
        f"mean: TrajOpt {_ms(t.mean_runtime_s)} vs " + ", ".join(
            f"{n} stage {_ms(per[n].mean_trajopt_time_s)} (total "
            f"{_ms(per[n].mean_runtime_s)})" for n in timed))


def check_sampling_too_slow(per: PerPlanner, _: SeedShortening | None = None) -> Verdict:
    """Every sampling-seeded X+TrajOpt's p95 runtime above the reaction budget."""
    sampled = _sampling_seeded(per)
    if not sampled:
        return Verdict(NOT_MEASURED, _missing(per, "a sampling-based seed + TrajOpt"))
    return Verdict(
        _combine([per[n].p95_runtime_s > REACTION_BUDGET_S for n in sampled]),
        "; ".join(f"{n} mean {_ms(per[n].mean_runtime_s)}, p95 {_ms(per[n].p95_runtime_s)} "
                  f"vs budget {_ms(REACTION_BUDGET_S)} (paper's bar: mean < "
                  f"{PAPER_REACTIVE_MEAN_S:g} s)" for n in sampled))


def check_roadmap_wins(per: PerPlanner, _: SeedShortening | None = None) -> Verdict:
    """Roadmap+TrajOpt: a lower mean runtime than every sampling-seeded planner, failure
    ≤ 2%."""
    rm = per.get(ROADMAP)
    others = _sampling_seeded(per)
    if rm is None or not others:
        return Verdict(NOT_MEASURED, _missing(per, "Roadmap+TrajOpt and a sampling-seeded "
                                                    "planner"))
    fastest = all(rm.mean_runtime_s < per[n].mean_runtime_s for n in others)
    low = rm.failure_rate <= LOW_FAILURE
    return Verdict(
        YES if fastest and low else NO,
        f"{ROADMAP} mean {_ms(rm.mean_runtime_s)} (median {_ms(rm.median_runtime_s)}), fail "
        f"{_pc(rm.failure_rate)} (bar {_pc(LOW_FAILURE)}) vs " + ", ".join(
            f"{n} mean {_ms(per[n].mean_runtime_s)} (median {_ms(per[n].median_runtime_s)}), "
            f"fail {_pc(per[n].failure_rate)}" for n in others))


def check_optimised_shorter(per: PerPlanner, short: SeedShortening | None = None) -> Verdict:
    """Roadmap+TrajOpt's returned paths ≥ 10% shorter than their roadmap seeds: paired runs
    (``short``) when given, else the means of the statistics (not paired: say so)."""
    rm = per.get(ROADMAP)
    if rm is None:
        return Verdict(NOT_MEASURED, _missing(per, ROADMAP))
    if short is not None:
        if short.cases == 0:
            return Verdict(NOT_MEASURED, f"none of {short.solved} solved runs answered from a "
                                         "roadmap seed optimised by TrajOpt")
        seed, final = short.mean_seed_rad, short.mean_final_rad
        how = (f"{short.cases} of {short.solved} solved runs (answer from the roadmap seed, "
               "optimised)")
    else:
        seed, final = rm.mean_seed_length_rad, rm.mean_path_length_rad
        how = "means over all runs with a seed / all solved runs (not paired)"
    if not (math.isfinite(seed) and math.isfinite(final) and seed > 0):
        return Verdict(NOT_MEASURED, f"no seed or path lengths recorded ({how})")
    cut = 1.0 - final / seed
    return Verdict(YES if cut >= SHORTER_BY - 1e-9 else NO,
                   f"seed {seed:.2f} rad → returned {final:.2f} rad: {100 * cut:.1f}% shorter "
                   f"(bar {100 * SHORTER_BY:.0f}%); {how}")


CLAIMS: tuple[Claim, ...] = (
    Claim("straight_line_fails_most", "Straight-line TrajOpt fails most",
          check_straight_line_fails_most),
    Claim("seed_fails_less", "A collision-free seed makes TrajOpt fail less",
          check_seed_fails_less),
    Claim("seed_runs_faster", "… and run faster (TrajOpt stage vs straight-line TrajOpt)",
          check_seed_runs_faster),
    Claim("sampling_too_slow", "Sampling-based seeds are too slow for reaction (p95 > "
          f"{1000 * REACTION_BUDGET_S:.0f} ms, the executive's replanning budget)",
          check_sampling_too_slow),
    Claim("roadmap_wins", "The roadmap seed wins on runtime (a lower mean than every "
          f"sampling-seeded planner's) with low failure (≤ {100 * LOW_FAILURE:.0f}%)",
          check_roadmap_wins),
    Claim("optimised_shorter", f"Optimised paths are ≥ {100 * SHORTER_BY:.0f}% shorter than "
          "their roadmap seeds", check_optimised_shorter),
)


def evaluate_claims(per: PerPlanner, short: SeedShortening | None = None
                    ) -> dict[str, Verdict]:
    """Every claim's verdict in one scene and family (``per``: planner → statistics;
    ``short``: the paired seed lengths, see :func:`seed_shortenings`)."""
    return {c.key: c.check(per, short) for c in CLAIMS}


# --- the report's section ----------------------------------------------------------------------
def claims_section(stats: Stats, rows: Iterable[dict[str, Any]]) -> list[str]:
    """Markdown lines: per case family (tasks first) a table "claim | holds? (per scene) |
    evidence", then our mean path lengths beside the paper's (``rows``: the runs, for the
    paired seed lengths)."""
    short = seed_shortenings(rows)
    L = ["## The paper's qualitative claims, re-checked\n",
         "Each verdict is computed from this run's statistics, per scene and case family: "
         "**yes** / **no**, **partly** when it holds for some of the planners the claim is "
         "about, *not measured* when the run lacks them. Failure: no path or an exactly "
         "colliding one; times: mean of `plan()` wall time over all runs (TrajOpt stage: "
         "everything after the seed stage). Our Roadmap+TrajOpt shortcuts its roadmap seed "
         "before TrajOpt, so the last claim's shortening is the shortcut's and TrajOpt's "
         "together. The paper's workload (pick-and-place between "
         "pre-grasp poses) is closest to our task family; its limit was "
         f"{paper.PAPER_TIME_LIMIT_S:g} s, and its claims are about 'tabletop with a pole' "
         "and 'shelf with boxes' (Tables I, II, IV) and all four of its scenes (Table III).\n"]
    for family in families(stats):
        keys = sorted(k for k in stats if k.family == family)
        verdicts = {k: evaluate_claims(stats[k], short.get(k)) for k in keys}
        L += [f"### {family} cases\n", "| claim | holds? (per scene) | evidence (the numbers) |",
              "|---|---|---|"]
        for c in CLAIMS:
            holds = ", ".join(f"{_label(k, keys)}: **{verdicts[k][c.key].holds}**"
                              for k in keys)
            evidence = "<br>".join(f"{_label(k, keys)}: {verdicts[k][c.key].evidence}"
                                   for k in keys)
            L.append(f"| {c.text} | {holds} | {evidence} |")
        L.append("\n" + _tally(verdicts) + "\n")
    return L + path_length_section(stats)


def families(stats: Stats) -> list[str]:
    """The case families of ``stats``, the task family first."""
    return sorted({k.family for k in stats}, key=lambda f: (f != "tasks", f))


def _label(key: StatsKey, keys: list[StatsKey]) -> str:
    """The scene, with its time limit when the family ran it under several."""
    several = sum(1 for k in keys if k.scene == key.scene) > 1
    return key.scene + (f" ({key.time_limit_s:g} s)" if several else "")


def _tally(verdicts: dict[StatsKey, dict[str, Verdict]]) -> str:
    """How many scene verdicts hold, per claim."""
    parts = []
    for c in CLAIMS:
        got = [v[c.key].holds for v in verdicts.values()]
        measured = [h for h in got if h != NOT_MEASURED]
        parts.append(f"{c.key} {sum(h == YES for h in measured)}/{len(measured)}"
                     + (f" ({sum(h == PARTLY for h in measured)} partly)"
                        if PARTLY in measured else ""))
    return "Scenes where each claim holds (of those measured): " + ", ".join(parts) + "."


def path_length_section(stats: Stats) -> list[str]:
    """Our mean path lengths beside the paper's, for the scenes and planners it reports."""
    L = ["### Path lengths beside the paper's\n",
         "Mean joint-space path length (rad) over each planner's solved runs; the paper's from "
         "its Tables I (stand-alone), II (X+TrajOpt), III (the roadmap's own path: our "
         "Roadmap+TrajOpt's recorded seed, before shortcutting) and IV (Roadmap+TrajOpt), "
         f"over {paper.PAPER_CASES} cases per scene. Only the scenes and planners the paper "
         "reports; its RRT is our RRTConnect.\n",
         "| family | Environment | planner | ours: mean / median (rad) | paper: mean (rad) | "
         "ours / paper |", "|---|---|---|---|---|---|"]
    ratios: dict[str, list[float]] = {}
    for family in families(stats):
        for key in sorted(k for k in stats if k.family == family):
            for name, mean, median, theirs in paper_lengths(key.scene, stats[key]):
                r = mean / theirs if math.isfinite(mean) else math.nan
                if math.isfinite(r):
                    ratios.setdefault(family, []).append(r)
                L.append(f"| {family} | {paper.SCENE_TITLES.get(key.scene, key.scene)} "
                         f"({_label(key, [k for k in stats if k.family == family])}) | "
                         f"{name} | {_rad(mean)} / {_rad(median)} | {theirs:.2f} | "
                         f"{_rad(r)} |")
    if not ratios:
        L.append("| — | — | (no scene and planner of this run is in the paper's tables) "
                 "| — | — | — |")
    L.append("\n" + " ".join(f"{f}: ours / paper {min(r):.2f}–{max(r):.2f} (mean "
                             f"{math.fsum(r) / len(r):.2f})." for f, r in ratios.items()) + "\n")
    return L


def paper_lengths(scene: str, per: PerPlanner) -> list[tuple[str, float, float, float]]:
    """(planner, our mean, our median, the paper's mean) path lengths (rad) of ``per``'s
    planners that the paper reports in ``scene``; Roadmap+TrajOpt's recorded seed as its own
    row (no median recorded: nan)."""
    out = []
    for n in planner_order(list(per)):
        s = per[n]
        base = seed_planner_name(n)
        if n.startswith(ROADMAP):
            row3 = paper.TABLE_III.get(scene)
            if row3 is not None:
                out.append((f"Roadmap (seed of {n})", s.mean_seed_length_rad, math.nan,
                            row3[2]))
            row4 = paper.TABLE_IV.get(scene, {}).get("Roadmap")
            theirs = row4[3] if row4 is not None else None
        elif base is not None:
            row2 = paper.TABLE_II.get(scene, {}).get(paper.PAPER_PLANNER.get(base, ""))
            theirs = row2[2] if row2 is not None else None
        else:
            row1 = paper.TABLE_I.get(scene, {}).get(paper.PAPER_PLANNER.get(n, ""))
            theirs = row1[2] if row1 is not None else None
        if theirs is not None:
            out.append((n, s.mean_path_length_rad, s.median_path_length_rad, theirs))
    return out


def _rad(x: float) -> str:
    return "—" if not math.isfinite(x) else f"{x:.2f}"


def _missing(per: PerPlanner, need: str) -> str:
    return f"needs {need}; this run has {', '.join(sorted(per)) or 'no planners'}"


def _pc(x: float) -> str:
    return "—" if not math.isfinite(x) else f"{100 * x:.1f}%"


def _ms(x: float) -> str:
    return "—" if not math.isfinite(x) else f"{1000 * x:.0f} ms" if x < 1 else f"{x:.2f} s"
