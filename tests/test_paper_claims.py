"""The paper's qualitative claims re-checked in the report (issue 17): each verdict follows from
the statistics (hand-built ones where a claim holds, where it does not, where it holds for some
planners and where the run lacks the planners), the paired seed lengths read from the runs, and
the report's section on a small real run of both case families."""

import math

import pytest

from chekhov.bench import paper_claims as pc
from chekhov.bench.config import BenchConfig
from chekhov.bench.database import BenchDatabase
from chekhov.bench.report import write_report
from chekhov.bench.runner import run_benchmark
from chekhov.bench.summary import ROADMAP, PlannerStats, StatsKey, compute_stats
from chekhov.roadmap.config import RoadmapConfig

SCENE = "tabletop_pole"
SMALL = RoadmapConfig(n_nodes=150, n_region_nodes=20, n_wrist_nodes=60, seed=3)
PLANNERS = ("Roadmap+TrajOpt", "TrajOpt", "RRTConnect", "RRTConnect+TrajOpt")
N = 2


def ps(planner: str, fail: float, mean: float, p95: float | None = None,
       stage: float = math.nan, seed_len: float = math.nan, length: float = 1.0,
       rejected: float = math.nan) -> PlannerStats:
    """Hand-built statistics of one planner (times s, lengths rad)."""
    return PlannerStats(scene=SCENE, planner=planner, time_limit_s=1.0, cases=100,
                        failure_rate=fail, mean_runtime_s=mean, median_runtime_s=mean,
                        p95_runtime_s=mean if p95 is None else p95,
                        mean_path_length_rad=length, median_path_length_rad=length,
                        collision_rate=0.0, family="tasks", mean_trajopt_time_s=stage,
                        mean_seed_length_rad=seed_len, trajopt_rejection_rate=rejected)


def holding() -> dict[str, PlannerStats]:
    """The paper's picture: straight-line TrajOpt fails most and optimises slowest, a sampling
    seed is slow, the roadmap is fast and reliable, TrajOpt shortens its seed by 25%."""
    return {"TrajOpt": ps("TrajOpt", 0.30, 0.50),
            "RRTConnect": ps("RRTConnect", 0.05, 0.40),
            "RRTConnect+TrajOpt": ps("RRTConnect+TrajOpt", 0.10, 0.60, p95=0.90, stage=0.20,
                                     rejected=0.05),
            ROADMAP: ps(ROADMAP, 0.01, 0.04, p95=0.06, stage=0.03, seed_len=2.0,
                        length=1.5, rejected=0.02)}


def failing() -> dict[str, PlannerStats]:
    """The opposite: straight-line TrajOpt never fails and is quick, the sampling seed answers
    within the budget, the roadmap is slower and fails 5%, TrajOpt shortens its seed by 5%."""
    return {"TrajOpt": ps("TrajOpt", 0.0, 0.02),
            "RRTConnect+TrajOpt": ps("RRTConnect+TrajOpt", 0.02, 0.03, p95=0.04, stage=0.03),
            ROADMAP: ps(ROADMAP, 0.05, 0.08, stage=0.05, seed_len=2.0, length=1.9)}


def test_every_claim_holds_on_the_papers_picture():
    got = pc.evaluate_claims(holding())
    assert [c.key for c in pc.CLAIMS] == list(got)
    assert {k: v.holds for k, v in got.items()} == dict.fromkeys(got, pc.YES)
    # the evidence is the numbers the verdict came from
    assert "TrajOpt 30.0% vs RRTConnect 5.0%" in got["straight_line_fails_most"].evidence
    assert "p95 900 ms vs budget 50 ms" in got["sampling_too_slow"].evidence
    assert "seed 2.00 rad → returned 1.50 rad: 25.0% shorter" in got["optimised_shorter"].evidence


def test_no_claim_holds_on_the_opposite_picture():
    got = pc.evaluate_claims(failing())
    assert {k: v.holds for k, v in got.items()} == dict.fromkeys(got, pc.NO)
    assert "5.0% shorter" in got["optimised_shorter"].evidence


def test_partly_ties_and_thresholds():
    per = holding()
    # one seeded planner fails more than straight-line TrajOpt, the other less: partly
    per["RRTConnect+TrajOpt"] = ps("RRTConnect+TrajOpt", 0.40, 0.60, p95=0.90, stage=0.70)
    got = pc.evaluate_claims(per)
    assert got["seed_fails_less"].holds == pc.PARTLY
    assert got["seed_runs_faster"].holds == pc.PARTLY
    assert got["straight_line_fails_most"].holds == pc.NO
    # a tie is not "fails most"; the roadmap over 2% failure does not win
    per = holding()
    per["TrajOpt"] = ps("TrajOpt", 0.10, 0.50)
    per[ROADMAP] = ps(ROADMAP, 0.03, 0.04, stage=0.03, seed_len=2.0, length=1.8)
    got = pc.evaluate_claims(per)
    assert got["straight_line_fails_most"].holds == pc.NO
    assert got["roadmap_wins"].holds == pc.NO
    assert got["optimised_shorter"].holds == pc.YES          # exactly 10% shorter counts
    # a p95 within the budget is fast enough for reaction
    per["RRTConnect+TrajOpt"] = ps("RRTConnect+TrajOpt", 0.1, 0.03, p95=pc.REACTION_BUDGET_S)
    assert pc.evaluate_claims(per)["sampling_too_slow"].holds == pc.NO


def test_the_papers_variant_of_the_roadmap_planner_is_no_rival_for_the_roadmap_seed():
    """``roadmap_wins`` is the roadmap seed against sampling seeds: the paper's variant of the
    roadmap planner (a roadmap seed too) being as fast or faster does not refute it (the
    500-case task run of 2026-11-29 said "no" in 6 of 6 scenes for that alone); a sampling
    seed being faster does."""
    per = holding()
    per["Roadmap+TrajOpt(paper)"] = ps("Roadmap+TrajOpt(paper)", 0.0, 0.03, stage=0.03)
    got = pc.evaluate_claims(per)
    assert got["roadmap_wins"].holds == pc.YES
    assert "Roadmap+TrajOpt(paper)" not in got["roadmap_wins"].evidence
    per["RRTConnect+TrajOpt"] = ps("RRTConnect+TrajOpt", 0.10, 0.035, p95=0.90, stage=0.02)
    assert pc.evaluate_claims(per)["roadmap_wins"].holds == pc.NO


def test_claims_without_their_planners_are_not_measured():
    got = pc.evaluate_claims({"RRTConnect": ps("RRTConnect", 0.0, 0.01)})
    assert {v.holds for v in got.values()} == {pc.NOT_MEASURED}
    assert "this run has RRTConnect" in got["roadmap_wins"].evidence
    only_rm = {ROADMAP: holding()[ROADMAP]}
    got = pc.evaluate_claims(only_rm)
    assert got["optimised_shorter"].holds == pc.YES
    assert got["roadmap_wins"].holds == pc.NOT_MEASURED


def row(case: int, seed: float | None, length: float, **kw) -> dict:
    r = {"planner": ROADMAP, "scene": SCENE, "timelimit": 1.0, "family": "tasks",
         "case_index": case, "success": 1, "seed_length": seed, "solution_length": length,
         "fallback_to_seed": 0, "info": {"seed_kind": "roadmap"}}
    return {**r, **kw}


def test_seed_shortening_pairs_the_runs_optimised_from_a_roadmap_seed():
    rows = [row(0, 2.0, 1.0), row(1, 4.0, 3.0),
            row(2, 4.0, 4.0, fallback_to_seed=1),                # the seed itself: left out
            row(3, 5.0, 1.0, info={"seed_kind": "straight_line"}),   # another seed: left out
            row(4, None, 1.0), row(5, 9.0, 0.0, success=0),
            {**row(6, 1.0, 1.0), "planner": "TrajOpt"}]
    key = StatsKey(SCENE, 1.0, "tasks")
    short = pc.seed_shortenings(rows)
    assert list(short) == [key]
    assert short[key] == pc.SeedShortening(2, 5, 3.0, 2.0)
    v = pc.check_optimised_shorter(holding(), short[key])
    assert v.holds == pc.YES and "33.3% shorter" in v.evidence and "2 of 5 solved" in v.evidence
    none = pc.check_optimised_shorter(holding(), pc.SeedShortening(0, 3, math.nan, math.nan))
    assert none.holds == pc.NOT_MEASURED


def test_paper_lengths_map_our_planners_to_the_papers_tables():
    got = {n: (mean, theirs) for n, mean, _, theirs in pc.paper_lengths(SCENE, holding())}
    assert got == {f"Roadmap (seed of {ROADMAP})": (2.0, 1.24), ROADMAP: (1.5, 0.82),
                   "RRTConnect": (1.0, 0.77), "RRTConnect+TrajOpt": (1.0, 0.70),
                   "TrajOpt": (1.0, 0.71)}
    assert pc.paper_lengths("panda_cage", holding()) == []    # not one of the paper's scenes


@pytest.fixture(scope="module")
def report(bench_dir):
    """A small real run of both families (its database) and its report's Markdown."""
    db = bench_dir / "claims.db"
    config = BenchConfig((SCENE,), PLANNERS, n_cases=N, time_limit_s=1.0, roadmap_config=SMALL,
                         roadmap_dir=str(bench_dir / "roadmaps"), workers=1,
                         families=("random", "tasks"))
    assert run_benchmark(config, db, progress=False).ran == 2 * N * len(PLANNERS)
    return db, write_report(db, bench_dir / "report").markdown.read_text()


def test_report_section_gives_the_verdicts_of_the_runs_numbers(report):
    db, text = report
    assert "## The paper's qualitative claims, re-checked" in text
    # the task family first
    assert text.index("### tasks cases") < text.index("### random cases")
    with BenchDatabase(db) as d:
        rows = d.rows()
    stats = compute_stats(rows)
    short = pc.seed_shortenings(rows)
    for family in ("tasks", "random"):
        key = StatsKey(SCENE, 1.0, family)
        per = stats[key]
        section = text[text.index(f"### {family} cases"):]
        verdicts = pc.evaluate_claims(per, short.get(key))
        for c in pc.CLAIMS:
            line = next(ln for ln in section.splitlines() if ln.startswith(f"| {c.text} |"))
            assert f"{SCENE}: **{verdicts[c.key].holds}**" in line
            assert verdicts[c.key].evidence in line
        # the verdict is the numbers': straight-line TrajOpt fails most iff its failure rate
        # is above every other planner's
        t = per["TrajOpt"].failure_rate
        expected = all(t > s.failure_rate for n, s in per.items() if n != "TrajOpt")
        assert verdicts["straight_line_fails_most"].holds == (pc.YES if expected else pc.NO)
        assert f"TrajOpt {100 * t:.1f}%" in verdicts["straight_line_fails_most"].evidence
        assert verdicts["sampling_too_slow"].holds == (
            pc.YES if per["RRTConnect+TrajOpt"].p95_runtime_s > pc.REACTION_BUDGET_S
            else pc.NO)
        # every claim's planners ran: nothing is "not measured" except claim (f) when no
        # run answered from an optimised roadmap seed
        assert all(v.holds != pc.NOT_MEASURED for k, v in verdicts.items()
                   if k != "optimised_shorter")
    # our path lengths beside the paper's (0.82 rad: its Roadmap+TrajOpt, Table IV)
    assert "### Path lengths beside the paper's" in text
    rm = stats[StatsKey(SCENE, 1.0, "tasks")][ROADMAP]
    assert (f"| tasks | Tabletop with a Pole ({SCENE}) | {ROADMAP} | "
            f"{rm.mean_path_length_rad:.2f} / {rm.median_path_length_rad:.2f} | 0.82 |"
            in text)
