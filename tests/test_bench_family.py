"""The benchmark's case families (issue 17): ``chekhov bench --family both`` runs each scene's
random and task cases as separate experiments, every row and summary entry says its family,
the report shows the families side by side, and a database written before the families
resumes as the random family."""

import itertools
import json
import sqlite3

import pytest

from chekhov.bench.config import BenchConfig
from chekhov.bench.database import DB_VERSION, BenchDatabase
from chekhov.bench.report import write_report
from chekhov.bench.runner import run_benchmark
from chekhov.cli import main
from chekhov.errors import ChekhovError

SCENE = "tabletop_pole"
PLANNERS = ("RRTConnect", "TrajOpt")
N = 2


@pytest.fixture(scope="module")
def tmp(bench_dir):
    return bench_dir   # generated cases go to bench_dir / "cache"


@pytest.fixture(scope="module")
def both(tmp):
    """A tiny ``--family both`` run: its database and summary JSON."""
    db, js = tmp / "both.db", tmp / "summary.json"
    assert main(["bench", "--scenes", SCENE, "--planners", *PLANNERS, "--family", "both",
                 "--cases", str(N), "--time-limit", "1", "--db", str(db), "--workers", "1",
                 "--no-progress", "--summary-json", str(js)]) == 0
    return db, json.loads(js.read_text())


def test_both_families_are_run_as_experiments_of_their_own(both):
    db, _ = both
    with BenchDatabase(db) as d:
        rows = d.rows()
        experiments = d.experiments()
    assert sorted((e["name"], e["family"]) for e in experiments) == [
        (SCENE, "random"), (SCENE, "tasks")]
    assert sorted((r["family"], r["planner"], r["case_index"]) for r in rows) == sorted(
        (f, p, i) for f in ("random", "tasks") for p in PLANNERS for i in range(N))
    # the families' cases differ: a task case starts at a pre-grasp, not where a random one
    hashes = {f: {r["case_hash"] for r in rows if r["family"] == f} for f in ("random", "tasks")}
    assert not hashes["random"] & hashes["tasks"]


def test_summary_json_has_the_family_in_every_row(both):
    _, doc = both
    assert doc["families"] == ["random", "tasks"] and doc["case_families"] == ["random", "tasks"]
    # the random family keeps the keys it had before the families; tasks are scene@tasks
    assert set(doc["scenes"]) == {SCENE, f"{SCENE}@tasks"}
    for key, family in ((SCENE, "random"), (f"{SCENE}@tasks", "tasks")):
        assert set(doc["scenes"][key]) == set(PLANNERS)
        for s in doc["scenes"][key].values():
            assert s["family"] == family and s["cases"] == N
            assert {"failure_rate", "median_runtime_s", "median_first_solution_s",
                    "p95_first_solution_s", "mean_path_length_rad"} <= set(s)


def test_report_shows_the_families_side_by_side(both, tmp):
    db, _ = both
    files = write_report(db, tmp / "report")
    text = files.markdown.read_text()
    assert f"| {SCENE} [random] | RRTConnect |" in text
    assert f"| {SCENE} [tasks] | RRTConnect |" in text
    assert f"--scenes {SCENE} --family tasks --planners" in text
    lines = [ln for ln in text.splitlines() if ln.startswith(f"| {SCENE} [")]
    assert any("[random]" in a and "[tasks]" in b for a, b in itertools.pairwise(lines))
    assert "family" in files.csv.read_text().splitlines()[0]


def test_a_database_from_before_the_families_resumes_as_random(tmp):
    db = tmp / "old.db"
    config = BenchConfig((SCENE,), ("TrajOpt",), n_cases=N, time_limit_s=1.0, workers=1)
    assert run_benchmark(config, db, progress=False).ran == N
    with sqlite3.connect(db) as con:   # the layout of version 1: no family column
        con.execute("ALTER TABLE experiments DROP COLUMN family")
        con.execute("UPDATE chekhov_meta SET value='1' WHERE key='version'")
    out = run_benchmark(config, db, progress=False)
    assert (out.ran, out.skipped) == (0, N)
    with BenchDatabase(db) as d:
        assert {r["family"] for r in d.rows()} == {"random"}
    with sqlite3.connect(db) as con:
        assert con.execute("SELECT value FROM chekhov_meta WHERE key='version'"
                           ).fetchone()[0] == str(DB_VERSION)


def test_family_arguments_are_checked(tmp, capsys):
    with pytest.raises(ChekhovError, match="families must be"):
        BenchConfig((SCENE,), ("TrajOpt",), families=("chores",))
    with pytest.raises(SystemExit):
        main(["bench", "--family", "chores"])
    assert "invalid choice: 'chores'" in capsys.readouterr().err


def test_a_case_file_serves_its_own_family(tmp, world_of, capsys):
    from chekhov.cases import generate_cases

    path = generate_cases(world_of(SCENE), N, seed=1, family="tasks").save(tmp / "t.npz")
    assert main(["bench", "--scenes", SCENE, "--planners", "TrajOpt", "--cases", str(N),
                 "--case-file", str(path), "--db", str(tmp / "x.db")]) == 2
    assert "cases of family 'tasks', which --family does not run" in capsys.readouterr().err
    db = tmp / "file.db"
    assert main(["bench", "--scenes", SCENE, "--planners", "TrajOpt", "--cases", str(N),
                 "--family", "tasks", "--case-file", str(path), "--db", str(db),
                 "--workers", "1", "--no-progress", "--time-limit", "1"]) == 0
    with BenchDatabase(db) as d:
        (e,) = d.experiments()
    assert e["family"] == "tasks" and e["case_source"].startswith("file t.npz")
