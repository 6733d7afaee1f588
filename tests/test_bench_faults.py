"""The benchmark runner under faults: a database locked by another program, two ``chekhov
bench`` processes on one database, a session killed with SIGKILL, and a case that cannot be
run. Each ends in a clear error or a recorded failure, never a lost or duplicated run."""

import os
import re
import sqlite3
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import chekhov.bench.runner as runner_mod
from chekhov.bench.config import BenchConfig
from chekhov.bench.database import BenchDatabase
from chekhov.bench.runner import run_benchmark
from chekhov.bench.solvability import cached_solvable_cases
from chekhov.bench.task import RunTask
from chekhov.bench.worker import BenchWorker
from chekhov.errors import BenchError
from chekhov.world import World

SCENE = "tabletop_pole"


@pytest.fixture(scope="module")
def cache(bench_dir):
    """A case cache of its own (CHEKHOV_CACHE) with the scene's first 16 cases generated, so
    concurrent processes only read it."""
    cached_solvable_cases(World.load(SCENE), 16, 0)
    return bench_dir


def config(n=3, planners=("RRTConnect",), **kw) -> BenchConfig:
    kw.setdefault("workers", 1)
    return BenchConfig((SCENE,), planners, n_cases=n, time_limit_s=0.5, **kw)


def stored(db) -> list[tuple[str, int]]:
    with BenchDatabase(db) as d:
        return [(r["planner"], r["case_index"]) for r in d.rows()]


def spent(db) -> tuple[float, float]:
    """experiments.totaltime and what the stored runs took (planning time, counted once
    for a shared seed stage, plus the exact check), s."""
    with BenchDatabase(db) as d:
        (exp,) = d.experiments()
        runs = sum((0.0 if "seed_stage_of" in r["info"] else r["time"]) + r["exact_check_time"]
                   for r in d.rows())
    return exp["totaltime"], runs


def test_a_database_locked_too_long_stops_with_a_bench_error_and_keeps_written_runs(
        cache, monkeypatch):
    db = cache / "locked.db"
    holder = sqlite3.connect(db, check_same_thread=False, isolation_level=None)
    real = runner_mod.run_tasks

    def lock_after_first(tasks, cfg):
        for k, rec in enumerate(real(tasks, cfg)):
            if k == 1:
                holder.execute("BEGIN EXCLUSIVE")     # another program holds the database
            yield rec

    monkeypatch.setattr(runner_mod, "run_tasks", lock_after_first)
    t0 = time.perf_counter()
    with pytest.raises(BenchError, match=r"locked.*more than 1 s.*RRTConnect on case 1") as e:
        run_benchmark(config(n=3, db_lock_timeout_s=1.0), db, progress=False)
    assert time.perf_counter() - t0 < 20.0
    assert str(db) in str(e.value) and "rerun" in str(e.value)
    holder.rollback()
    assert stored(db) == [("RRTConnect", 0)]                # the finished run is kept
    assert sqlite3.connect(db).execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    # a short lock is waited out; the rerun does the rest, once each
    monkeypatch.setattr(runner_mod, "run_tasks", real)
    holder.execute("BEGIN EXCLUSIVE")
    threading.Timer(0.5, holder.rollback).start()
    out = run_benchmark(config(n=3, db_lock_timeout_s=10.0), db, progress=False)
    assert (out.ran, out.skipped) == (2, 1)
    assert sorted(stored(db)) == [("RRTConnect", i) for i in range(3)]
    holder.close()


def test_a_locked_database_at_start_is_a_bench_error(cache):
    db = cache / "locked_at_start.db"
    BenchDatabase(db).close()
    holder = sqlite3.connect(db, isolation_level=None)
    holder.execute("BEGIN EXCLUSIVE")
    t0 = time.perf_counter()
    with pytest.raises(BenchError, match="locked"):
        BenchDatabase(db, lock_timeout_s=0.5)
    assert time.perf_counter() - t0 < 5.0
    holder.rollback()
    holder.close()


_KILLED = """
import os, signal, sys
import chekhov.bench.runner as r
from chekhov.bench.config import BenchConfig
real = r.run_tasks
def dying(tasks, cfg):
    for k, rec in enumerate(real(tasks, cfg)):
        if k == 2:      # two runs written: this session dies without any clean-up
            os.kill(os.getpid(), signal.SIGKILL)
        yield rec
r.run_tasks = dying
r.run_benchmark(BenchConfig(("tabletop_pole",), ("RRTConnect",), n_cases=4,
                            time_limit_s=0.5, workers=1), sys.argv[1], progress=False)
"""


def test_a_killed_session_keeps_its_runs_and_their_time(cache):
    db = cache / "killed.db"
    p = subprocess.run([sys.executable, "-c", _KILLED, str(db)], env=os.environ.copy(),
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == -9, p.stderr
    assert sorted(stored(db)) == [("RRTConnect", 0), ("RRTConnect", 1)]
    total, runs = spent(db)
    assert runs > 0 and total == pytest.approx(runs, rel=1e-6)
    # the rerun takes over at once (the dead session's claims are void) and adds its own time
    t0 = time.perf_counter()
    out = run_benchmark(config(n=4), db, progress=False)
    assert (out.ran, out.skipped) == (2, 2) and time.perf_counter() - t0 < 30.0
    total, runs = spent(db)
    assert sorted(stored(db)) == [("RRTConnect", i) for i in range(4)]
    assert total == pytest.approx(runs, rel=1e-6)


_DONE = re.compile(r"bench: (\d+) run\(s\) done, (\d+) already in")


def test_two_processes_on_one_database_split_the_runs(cache):
    db = cache / "shared.db"
    n = 16
    cmd = [sys.executable, "-m", "chekhov.cli", "bench", "--scenes", SCENE, "--planners",
           "RRT*", "--cases", str(n), "--time-limit", "0.25", "--workers", "1", "--db",
           str(db), "--no-progress"]
    procs = [subprocess.Popen(cmd, env=os.environ.copy(), stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    done = []
    for p in procs:
        _, err = p.communicate(timeout=300)
        assert p.returncode == 0, err
        m = _DONE.search(err)
        assert m, err
        done.append(int(m.group(1)))
    keys = stored(db)
    assert len(keys) == len(set(keys)) == n
    # each did a share of the work, and says how much it did
    assert sum(done) == n and min(done) > 0, done
    with BenchDatabase(db) as d:
        assert d.conn.execute("SELECT count(*) FROM chekhov_claims").fetchone()[0] == 0
    total, runs = spent(db)
    assert total == pytest.approx(runs, rel=1e-6)


def bad_goal_cases(real):
    def load(world, cfg, *family, **kw):
        cases, source = real(world, cfg, *family, **kw)
        T = cases.T_world_ee_goal.copy()
        T[1, 0, 3] = np.nan
        from dataclasses import replace
        return replace(cases, T_world_ee_goal=T), source
    return load


def test_a_bad_case_is_recorded_as_its_failure_and_the_benchmark_goes_on(cache, monkeypatch):
    monkeypatch.setattr(runner_mod, "load_cases", bad_goal_cases(runner_mod.load_cases))
    db = cache / "bad_case.db"
    planners = ("RRTConnect", "RRTConnect+TrajOpt", "TrajOpt")
    out = run_benchmark(config(n=3, planners=planners), db, progress=False)
    assert out.ran == 9
    with BenchDatabase(db) as d:
        rows = {(r["planner"], r["case_index"]): r for r in d.rows()}
    assert len(rows) == 9
    for p in planners:
        bad = rows[(p, 1)]
        assert not bad["solved"] and bad["failure_kind_text"] == "case_error"
        info = bad["info"]
        assert info["case_index"] == 1 and info["planner"] == p and info["scene"] == SCENE
        assert "goal pose must be a finite 4x4 matrix" in info["error"]
        assert info["stage"] == "goal"
        for i in (0, 2):
            assert rows[(p, i)]["failure_kind_text"] != "case_error"


def test_the_worker_records_a_chekhov_error_in_planning_as_that_runs_failure(cache):
    from chekhov.errors import PlanningInputError

    w = BenchWorker(config())

    class Refusing:
        def plan(self, *a, **k):
            raise PlanningInputError("time_limit_s: refused for the test")

    w.planners[(SCENE, "RRTConnect")] = Refusing()
    task = RunTask(SCENE, "RRTConnect", 5, np.zeros(7), np.eye(4), 0.5, 0)
    (rec,) = w.run_all(task)
    assert rec.status == "case_error" and not rec.solved
    assert rec.info["stage"] == "plan" and rec.info["case_index"] == 5
    assert "PlanningInputError: time_limit_s: refused for the test" in rec.info["error"]
