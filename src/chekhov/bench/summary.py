"""Per scene, case family and planner statistics of stored runs, the ``--summary-json`` file
and the printed summary table.

Statistics are grouped by :class:`StatsKey` (scene, time limit, case family); every row of the
summary JSON says its ``family`` ("random" or "tasks"), and the random family keeps the keys it
had before the families (``scenes`` → scene → planner; see :func:`summary_json`).

Definitions (every run counts, failures included, unless said otherwise):

* ``failure_rate``: share of runs without success — no path returned, or a returned path that
  the runner's exact check (100 substeps per segment) finds in collision (the paper's failure:
  any failure modality).
* ``mean_runtime_s`` / ``median_runtime_s`` / ``p95_runtime_s``: the planner's time of
  ``plan`` (s) over all runs (failed runs at their time, e.g. the limit).
* ``mean_path_length_rad``: joint-space length of the returned path, over successful runs.
* ``mean_duration_s`` / ``median_duration_s``: the returned path's motion time, timed by
  :func:`chekhov.planners.timed.timed_trajectory` (toppra under the URDF velocity limits and
  3 rad/s², else ruckig), over successful runs; not part of the runtime.
* ``median_first_solution_s`` / ``p95_first_solution_s``: s from the start of ``plan`` to
  its first certified answer (an anytime planner's first path; the answer's time for the
  others), over successful runs.
* ``collision_rate``: share of returned paths the exact check finds in collision (0 when
  nothing was returned).
* With a TrajOpt stage: ``mean_trajopt_time_s`` (after the seed), ``mean_seed_length_rad``,
  ``seed_failure_rate`` (no seed), and ``trajopt_rejection_rate`` — among runs with a seed,
  the share whose TrajOpt trajectory was rejected as colliding or infeasible (the paper's
  Table II "collision rate": the paper counts TrajOpt outputs in collision).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from typing import Any, NamedTuple

import numpy as np

ROADMAP = "Roadmap+TrajOpt"


class StatsKey(NamedTuple):
    """What one group of statistics is of: a scene, a time limit (s) and a case family."""

    scene: str
    time_limit_s: float
    family: str = "random"


def stats_label(key: StatsKey, keys: Iterable[StatsKey]) -> str:
    """How tables name the group ``key`` among ``keys``: the scene, its time limit when the
    scene and family were run under several, its family in brackets when any is not
    random (so that the families of a scene stand side by side)."""
    keys = list(keys)
    out = key.scene
    if sum(1 for k in keys if (k.scene, k.family) == (key.scene, key.family)) > 1:
        out += f" ({key.time_limit_s:g} s)"
    if any(k.family != "random" for k in keys):
        out += f" [{key.family}]"
    return out


@dataclass(frozen=True)
class PlannerStats:
    """Statistics of one planner in one experiment (scene, case family and time limit). Times
    s, lengths rad, rates fractions; nan where undefined (e.g. no successful run)."""

    scene: str
    planner: str
    time_limit_s: float
    cases: int
    failure_rate: float
    mean_runtime_s: float
    median_runtime_s: float
    p95_runtime_s: float
    mean_path_length_rad: float
    median_path_length_rad: float
    collision_rate: float
    family: str = "random"
    mean_duration_s: float = math.nan
    median_duration_s: float = math.nan
    median_first_solution_s: float = math.nan
    p95_first_solution_s: float = math.nan
    mean_trajopt_time_s: float = math.nan
    median_trajopt_time_s: float = math.nan
    mean_seed_time_s: float = math.nan
    median_seed_time_s: float = math.nan
    p95_seed_time_s: float = math.nan
    mean_seed_length_rad: float = math.nan
    seed_failure_rate: float = math.nan
    trajopt_rejection_rate: float = math.nan
    fallback_rate: float = math.nan
    statuses: dict[str, int] = field(default_factory=dict)
    case_lengths: dict[int, float] = field(default_factory=dict, repr=False)

    def to_json(self) -> dict[str, Any]:
        """JSON-able dict (nan → None; without the per-case lengths)."""
        return {k: _clean(v) for k, v in asdict(self).items()
                if k not in ("scene", "planner", "case_lengths")}


Stats = dict[StatsKey, dict[str, PlannerStats]]


def compute_stats(rows: Iterable[dict[str, Any]]) -> Stats:
    """(scene, time limit, family) → planner → stats, from :meth:`BenchDatabase.rows` dicts
    (a row without ``family`` is of the random family)."""
    groups: dict[tuple[StatsKey, str], list[dict[str, Any]]] = {}
    for r in rows:
        key = StatsKey(r["scene"], float(r["timelimit"]), r.get("family") or "random")
        groups.setdefault((key, r["planner"]), []).append(r)
    out: Stats = {}
    for (key, planner), rs in groups.items():
        out.setdefault(key, {})[planner] = _stats(key, planner, rs)
    return out


def _stats(key: StatsKey, planner: str, rs: list[dict[str, Any]]) -> PlannerStats:
    scene, limit = key.scene, key.time_limit_s
    n = len(rs)
    t = np.array([r["time"] for r in rs], dtype=float)
    ok = [r for r in rs if r["success"]]
    lengths = np.array([r["solution_length"] for r in ok], dtype=float)
    durations = np.array([r["info"]["duration_s"] for r in ok
                          if "duration_s" in (r.get("info") or {})], dtype=float)
    first = np.array([r["info"]["first_solution_s"] for r in ok
                      if "first_solution_s" in (r.get("info") or {})], dtype=float)
    returned = [r for r in rs if r["solved"]]
    coll = sum(1 for r in returned if r["exact_collision"])
    extra: dict[str, Any] = {}
    if any(r["seed_found"] is not None for r in rs):
        with_seed = [r for r in rs if r["seed_found"]]
        tried = [r for r in with_seed if r["trajopt_ok"] is not None]
        tt = np.array([r["trajopt_time"] for r in tried if r["trajopt_time"] is not None])
        st = np.array([r["seed_time"] for r in rs if r["seed_time"] is not None])
        sl = np.array([r["seed_length"] for r in with_seed if r["seed_length"] is not None])
        extra = {"mean_trajopt_time_s": _mean(tt), "median_trajopt_time_s": _median(tt),
                 "mean_seed_time_s": _mean(st), "median_seed_time_s": _median(st),
                 "p95_seed_time_s": _pct(st, 95), "mean_seed_length_rad": _mean(sl),
                 "seed_failure_rate": 1.0 - len(with_seed) / n,
                 "trajopt_rejection_rate": (sum(1 for r in tried if not r["trajopt_ok"])
                                            / len(tried)) if tried else math.nan}
        if planner == ROADMAP:
            extra["fallback_rate"] = (sum(1 for r in rs if r["fallback_to_seed"]) / n)
    statuses = Counter(str(r.get("failure_kind_text") or r.get("status_text")) for r in rs)
    return PlannerStats(scene=scene, planner=planner, time_limit_s=limit, cases=n,
                        family=key.family,
                        failure_rate=1.0 - len(ok) / n, mean_runtime_s=_mean(t),
                        median_runtime_s=_median(t), p95_runtime_s=_pct(t, 95),
                        mean_path_length_rad=_mean(lengths),
                        median_path_length_rad=_median(lengths),
                        collision_rate=coll / len(returned) if returned else 0.0,
                        mean_duration_s=_mean(durations),
                        median_duration_s=_median(durations),
                        median_first_solution_s=_median(first),
                        p95_first_solution_s=_pct(first, 95),
                        statuses=dict(sorted(statuses.items())),
                        case_lengths={int(r["case_index"]): float(r["solution_length"])
                                      for r in ok},
                        **extra)


def runtime_ratios(stats: dict[str, PlannerStats]) -> dict[str, dict[str, float]]:
    """Roadmap+TrajOpt's mean and median runtime divided by every other planner's (< 1:
    Roadmap+TrajOpt is faster); empty without Roadmap+TrajOpt."""
    rm = stats.get(ROADMAP)
    if rm is None:
        return {}
    return {name: {"mean": _ratio(rm.mean_runtime_s, s.mean_runtime_s),
                   "median": _ratio(rm.median_runtime_s, s.median_runtime_s)}
            for name, s in stats.items() if name != ROADMAP}


def length_ratios(stats: dict[str, PlannerStats]) -> dict[str, float]:
    """Roadmap+TrajOpt's mean path length over every other planner's, on the cases both
    solved (a fair comparison: planners that fail the hard cases look short otherwise)."""
    rm = stats.get(ROADMAP)
    if rm is None:
        return {}
    out = {}
    for name, s in stats.items():
        common = sorted(set(rm.case_lengths) & set(s.case_lengths))
        if name != ROADMAP and common:
            out[name] = _ratio(float(np.mean([rm.case_lengths[i] for i in common])),
                               float(np.mean([s.case_lengths[i] for i in common])))
    return out


def targets(stats: dict[str, PlannerStats]) -> dict[str, bool]:
    """The issue's figures to reach, for one scene: Roadmap+TrajOpt has the lowest failure
    rate, a lower mean and median runtime than every other seed + TrajOpt combination, a
    collision rate of 0 and a mean path length within 15% of the shortest planner's — over
    each planner's own solved cases, and on the cases both solved (``_common_cases``); and
    :func:`speed_targets`."""
    from chekhov.planners.registry import seed_planner_name

    rm = stats.get(ROADMAP)
    if rm is None:
        return {}
    others = [s for n, s in stats.items() if n != ROADMAP]
    seeded = [s for s in others if seed_planner_name(s.planner) is not None]
    lengths = [s.mean_path_length_rad for s in stats.values()
               if math.isfinite(s.mean_path_length_rad)]
    return {
        "lowest_failure_rate": all(rm.failure_rate <= s.failure_rate for s in others),
        "faster_than_seeded_trajopt_mean": all(rm.mean_runtime_s < s.mean_runtime_s
                                               for s in seeded),
        "faster_than_seeded_trajopt_median": all(rm.median_runtime_s < s.median_runtime_s
                                                 for s in seeded),
        "collision_rate_zero": rm.collision_rate == 0.0,
        "path_length_within_15pct_of_shortest": bool(
            lengths and math.isfinite(rm.mean_path_length_rad)
            and rm.mean_path_length_rad <= 1.15 * min(lengths)),
        "path_length_within_15pct_of_shortest_common_cases": all(
            r <= 1.15 for r in length_ratios(stats).values() if math.isfinite(r)),
        **speed_targets(rm, length_ratios(stats)),
    }


def speed_targets(rm: PlannerStats, ratios: dict[str, float]) -> dict[str, bool]:
    """Issues 16 and 17's figures for Roadmap+TrajOpt in one scene and family: failure ≤ 0.5%,
    median ≤ 10 ms and p95 ≤ 30 ms of ``plan()`` (the optimised answer), first certified
    answer median ≤ 2 ms and p95 ≤ 10 ms, and a mean path length within 10% of every other
    planner's on the cases both solve (``ratios``: :func:`length_ratios`). Wall times on the
    machine and load the runs had: compare with the report's "How it was produced"."""
    return {
        "failure_rate_at_most_half_pct": rm.failure_rate <= 0.005,
        "median_runtime_at_most_10ms": rm.median_runtime_s <= 0.010,
        "p95_runtime_at_most_30ms": rm.p95_runtime_s <= 0.030,
        "median_first_solution_at_most_2ms": rm.median_first_solution_s <= 0.002,
        "p95_first_solution_at_most_10ms": rm.p95_first_solution_s <= 0.010,
        "path_length_within_10pct_of_shortest_common_cases": all(
            r <= 1.10 for r in ratios.values() if math.isfinite(r)),
    }


def summary_json(stats: Stats, meta: dict[str, Any] | None = None) -> dict[str, Any]:
    """The ``--summary-json`` document: ``families`` (those present), ``scenes`` → scene →
    planner → statistics (each with its ``family``; with ``roadmap_mean_runtime_ratio`` /
    ``roadmap_median_runtime_ratio``: Roadmap+TrajOpt's over this planner's;
    ``roadmap_path_length_ratio_common_cases``: see :func:`length_ratios`), ``ratios`` (the
    runtime ratios, by scene), ``targets`` (see :func:`targets`). The random family's cases
    are keyed by the scene, the task family's ``scene@tasks``; a scene and family benchmarked
    under several time limits adds ``@LIMITs``."""
    scenes: dict[str, Any] = {}
    ratios: dict[str, Any] = {}
    goals: dict[str, Any] = {}
    multi = Counter((k.scene, k.family) for k in stats)
    for k, per in sorted(stats.items()):
        key = k.scene + ("" if k.family == "random" else f"@{k.family}")
        if multi[(k.scene, k.family)] > 1:
            key += f"@{k.time_limit_s:g}s"
        rat = runtime_ratios(per)
        lrat = length_ratios(per)
        entry = {}
        for name, s in per.items():
            d = s.to_json()
            if name in rat:
                d["roadmap_mean_runtime_ratio"] = _clean(rat[name]["mean"])
                d["roadmap_median_runtime_ratio"] = _clean(rat[name]["median"])
            if name in lrat:
                d["roadmap_path_length_ratio_common_cases"] = _clean(lrat[name])
            entry[name] = d
        scenes[key] = entry
        if rat:
            ratios[key] = {n: {k: _clean(v) for k, v in r.items()} for n, r in rat.items()}
            goals[key] = targets(per)
    return {**(meta or {}), "families": sorted({k.family for k in stats}), "scenes": scenes,
            "ratios": ratios, "targets": goals}


def format_table(stats: Stats) -> str:
    """The summary table (plain text), one line per scene, family and planner."""
    head = (f"{'scene':20s} {'family':6s} {'planner':22s} {'limit s':>7s} {'cases':>5s} "
            f"{'fail':>7s} "
            f"{'mean s':>8s} {'median s':>8s} {'p95 s':>8s} {'length':>7s} {'coll':>6s} "
            f"{'RM/mean':>8s} {'RM/med':>7s}")
    lines = [head, "-" * len(head)]
    for (scene, limit, family), per in sorted(stats.items()):
        rat = runtime_ratios(per)
        for name in sorted(per, key=lambda n: (n != ROADMAP, n)):
            s = per[name]
            r = rat.get(name, {})
            lines.append(
                f"{scene:20s} {family:6s} {name:22s} {limit:7.3g} {s.cases:5d} "
                f"{s.failure_rate:7.1%} "
                f"{s.mean_runtime_s:8.3f} {s.median_runtime_s:8.3f} {s.p95_runtime_s:8.3f} "
                f"{_fmt(s.mean_path_length_rad, 7, 2)} {s.collision_rate:6.1%} "
                f"{_fmt(r.get('mean', math.nan), 8, 3)} {_fmt(r.get('median', math.nan), 7, 3)}")
    lines.append("fail: no path or an exactly colliding one; times: plan() wall time over all "
                 "runs; length: rad, solved runs; coll: returned paths the exact 100-substep "
                 "check rejects; RM/x: Roadmap+TrajOpt's runtime over this planner's")
    return "\n".join(lines)


def _fmt(x: float, width: int, prec: int) -> str:
    return f"{x:{width}.{prec}f}" if math.isfinite(x) else f"{'-':>{width}s}"


def _mean(a: np.ndarray) -> float:
    return float(np.mean(a)) if len(a) else math.nan


def _median(a: np.ndarray) -> float:
    return float(np.median(a)) if len(a) else math.nan


def _pct(a: np.ndarray, q: float) -> float:
    return float(np.percentile(a, q)) if len(a) else math.nan


def _ratio(a: float, b: float) -> float:
    return a / b if b > 0 and math.isfinite(a) and math.isfinite(b) else math.nan


def _clean(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v
