"""The command line as a careless or hostile user meets it: every bad argument or output path
fails at once, before any work, with one line on stderr naming the argument, a non-zero exit
and no traceback (issue 13)."""

from __future__ import annotations

import contextlib
import io
import math
import os
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from chekhov.cases import CaseSet
from chekhov.cli import build_parser, main
from chekhov.errors import ChekhovError

SRC = Path(__file__).resolve().parents[1] / "src"


class WorkStartedError(Exception):
    """Raised by the patched World.load: a command began its work before its checks."""


@pytest.fixture()
def no_work(monkeypatch, tmp_path):
    """Fail the test if a command loads a world (the first step of any real work); caches go
    to a temporary folder."""
    from chekhov.world import World

    def refuse(*a, **k):
        raise WorkStartedError("World.load was called before the arguments were checked")

    monkeypatch.setattr(World, "load", classmethod(lambda cls, *a, **k: refuse()))
    monkeypatch.setenv("CHEKHOV_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("CHEKHOV_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    return tmp_path


def run(argv: list[str], capsys) -> tuple[int, str]:
    """(exit status, stderr) of ``chekhov argv`` run in this process (under 5 s: the checks
    come before any work; the first call also imports the command's modules)."""
    t0 = time.perf_counter()
    try:
        code = main(argv)
    except SystemExit as e:  # argparse's usage errors
        code = e.code if isinstance(e.code, int) else 1
    err = capsys.readouterr().err
    assert time.perf_counter() - t0 < 5.0, f"{argv} took {time.perf_counter() - t0:.2f} s"
    return code, err


def assert_fails(argv: list[str], capsys, *names: str) -> str:
    """Non-zero exit, no traceback, the last stderr line names every one of ``names``."""
    code, err = run(argv, capsys)
    assert code != 0, f"{argv} exited 0"
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith("chekhov"), err
    for name in names:
        assert name in last, f"{name!r} not in {last!r}"
    return last


def assert_one_line(argv: list[str], capsys, *names: str) -> str:
    """As :func:`assert_fails`, and stderr is that one line alone (a ChekhovError)."""
    code, err = run(argv, capsys)
    assert code == 2 and "Traceback" not in err, err
    assert len(err.strip().splitlines()) == 1, err
    for name in names:
        assert name in err, f"{name!r} not in {err!r}"
    return err


@pytest.fixture()
def afile(no_work) -> Path:
    """A regular file: nothing can be created under it."""
    p = no_work / "afile"
    p.write_text("x")
    return p


@pytest.fixture()
def case_file(tmp_path) -> Path:
    """A case file of 3 (meaningless) cases of tabletop_pole."""
    n, k = 3, 7
    cases = CaseSet(scene="tabletop_pole", scene_hash="0" * 64, robot="robot",
                    joint_names=tuple(f"j{i}" for i in range(k)), seed=0,
                    q_start=np.zeros((n, k)), q_goal=np.zeros((n, k)),
                    T_world_ee_start=np.tile(np.eye(4), (n, 1, 1)),
                    T_world_ee_goal=np.tile(np.eye(4), (n, 1, 1)))
    return cases.save(tmp_path / "three.npz")


BENCH = ["bench", "--scenes", "tabletop_pole", "--planners", "TrajOpt", "--cases", "1",
         "--time-limit", "0.5", "--workers", "1", "--no-progress"]


# --- output paths ---------------------------------------------------------------------------
@pytest.mark.parametrize("argv, arg", [
    ([*BENCH, "--db", "afile/x.db"], "--db"),
    ([*BENCH, "--db", "b.db", "--summary-json", "afile/s.json"], "--summary-json"),
    ([*BENCH, "--db", "b.db", "--csv", "afile/runs.csv"], "--csv"),
    ([*BENCH, "--db", "b.db", "--report", "afile/rep"], "--report"),
    ([*BENCH, "--db", "b.db", "--report", "afile"], "--report"),
    (["show", "tabletop_pole", "--out", "afile/s.png"], "--out"),
    (["cases", "generate", "tabletop_pole", "--n", "2", "--no-solvability",
      "--out", "afile/c.npz"], "--out"),
    (["roadmap", "build", "tabletop_pole", "--nodes", "2", "--wrist-nodes", "0",
      "--no-semantic", "--quiet", "--out", "afile/r.npz"], "--out"),
    (["demo", "--cases", "1", "--out", "afile/demo"], "--out"),
], ids=["db", "summary-json", "csv", "report-under-file", "report-is-file", "show", "cases",
        "roadmap", "demo"])
def test_unwritable_output_fails_before_any_work(argv, arg, afile, capsys):
    assert_one_line(argv, capsys, arg, "afile")
    assert afile.read_text() == "x" and not Path("b.db").exists()


def test_report_out_under_a_file(afile, capsys, tmp_path):
    db = tmp_path / "r.db"
    with sqlite3.connect(db) as conn:
        conn.execute("CREATE TABLE chekhov_runs (x)")
    conn.close()
    assert_one_line(["report", str(db), "--out", "afile/rep"], capsys, "--out", "afile")


def test_output_that_is_a_folder_or_a_device(no_work, capsys):
    (no_work / "d").mkdir()
    assert_one_line([*BENCH, "--db", "d"], capsys, "--db", "folder")
    assert_one_line(["show", "tabletop_pole", "--out", "d"], capsys, "--out", "folder")
    assert_one_line(["show", "tabletop_pole", "--out", "/dev/null"], capsys, "--out",
                    "not a regular file")
    assert_one_line(["show", "tabletop_pole", "--out", "s.jpg"], capsys, "--out", ".png")


def test_bench_outputs_must_be_distinct(no_work, capsys):
    assert_one_line([*BENCH, "--db", "b.db", "--csv", "b.db"], capsys, "--csv", "--db")
    assert_one_line([*BENCH, "--db", "b.db", "--summary-json", "rep/summary.json",
                             "--report", "rep"], capsys, "--report", "--summary-json")
    assert not Path("b.db").exists()


def test_bench_db_that_is_not_a_database_is_left_alone(no_work, capsys):
    text = "my notes\n"
    Path("notes.txt").write_text(text)
    assert_one_line([*BENCH, "--db", "notes.txt"], capsys, "--db", "not an SQLite")
    assert Path("notes.txt").read_text() == text


def test_other_sqlite_databases_are_left_alone(no_work, capsys):
    with sqlite3.connect("app.db") as conn:
        conn.execute("CREATE TABLE t (x)")
    conn.close()
    before = Path("app.db").read_bytes()
    assert_one_line([*BENCH, "--db", "app.db"], capsys, "--db", "not a chekhov")
    assert_one_line(["report", "app.db", "--out", "rep"], capsys, "app.db", "not a chekhov")
    assert Path("app.db").read_bytes() == before and not Path("rep").exists()


def test_report_of_an_empty_file_leaves_it_empty(no_work, capsys):
    Path("empty.db").touch()
    assert_one_line(["report", "empty.db", "--out", "rep"], capsys, "empty.db")
    assert Path("empty.db").stat().st_size == 0 and not Path("rep").exists()


@pytest.mark.parametrize("argv, name", [
    (["cases", "info", "empty.npz"], "empty.npz"),
    (["roadmap", "info", "empty.npz"], "empty.npz"),
    (["show", "tabletop_pole", "--path", "empty.npz"], "--path"),
])
def test_empty_input_file(argv, name, no_work, capsys):
    Path("empty.npz").touch()
    assert_one_line(argv, capsys, name, "empty")


# --- scene and planner names: checked before any file is created ----------------------------
@pytest.mark.parametrize("extra, arg", [
    (["--scenes", "no_such_scene"], "--scenes"),
    (["--scenes", "tabletop_pole", "--planners", "NoSuchPlanner"], "--planners"),
])
def test_bench_bad_names_leave_no_database(extra, arg, no_work, capsys):
    assert_one_line(["bench", "--db", "b.db", *extra], capsys, arg)
    assert not Path("b.db").exists()


def test_bench_case_files_of_one_scene_twice(no_work, capsys, case_file):
    assert_one_line([*BENCH, "--db", "b.db", "--case-file", str(case_file), str(case_file)],
                    capsys, "--case-file", "second")
    assert not Path("b.db").exists()


def test_cases_generate_bad_planner_or_contradiction(no_work, capsys):
    assert_one_line(["cases", "generate", "tabletop_pole", "--planners", "Nope"], capsys,
                    "--planners", "Nope")
    assert_one_line(["cases", "generate", "tabletop_pole", "--planners", "RRT", "RRT"], capsys,
                    "--planners", "twice")
    assert_one_line(["cases", "generate", "tabletop_pole", "--no-solvability",
                     "--solvability-limit", "2"], capsys, "--solvability-limit")


# --- numbers ----------------------------------------------------------------------------------
@pytest.mark.parametrize("argv, arg", [
    (["view", "tabletop_pole", "--port", "99999"], "--port"),
    (["view", "tabletop_pole", "--port", "0"], "--port"),
    (["view", "tabletop_pole", "--port", "-1"], "--port"),
    (["view", "tabletop_pole", "--n-cases", "0"], "--n-cases"),
    (["cases", "generate", "tabletop_pole", "--solvability-limit", "-1"], "--solvability-limit"),
    (["cases", "generate", "tabletop_pole", "--solvability-limit", "0"], "--solvability-limit"),
    (["cases", "generate", "tabletop_pole", "--solvability-limit", "nan"], "--solvability-limit"),
    (["cases", "generate", "tabletop_pole", "--solvability-limit", "inf"], "--solvability-limit"),
    (["cases", "generate", "tabletop_pole", "--n", "0"], "--n"),
    (["cases", "generate", "tabletop_pole", "--n", "2", "--seed", "-1"], "--seed"),
    (["roadmap", "build", "tabletop_pole", "--nodes", "0"], "--nodes"),
    (["roadmap", "build", "tabletop_pole", "--k", "0"], "--k"),
    (["roadmap", "build", "tabletop_pole", "--wrist-nodes", "-1"], "--wrist-nodes"),
    (["roadmap", "build", "tabletop_pole", "--nodes", "2", "--seed", "-1"], "--seed"),
    (["bench", "--db", "b.db", "--cases", "0"], "--cases"),
    (["bench", "--db", "b.db", "--time-limit", "0"], "--time-limit"),
    (["bench", "--db", "b.db", "--time-limit", "-2"], "--time-limit"),
    (["bench", "--db", "b.db", "--time-limit", "inf"], "--time-limit"),
    (["bench", "--db", "b.db", "--time-limit", "nan"], "--time-limit"),
    (["bench", "--db", "b.db", "--workers", "0"], "--workers"),
    (["bench", "--db", "b.db", "--case-seed", "-1"], "--case-seed"),
    (["demo", "--cases", "0"], "--cases"),
    (["show", "tabletop_pole", "--ghosts", "-1", "--path", "p.npy"], "--ghosts"),
    (["show", "tabletop_pole", "--case", "-1"], "--case"),
    (["show", "tabletop_pole", "--q", "nan", "0", "0", "0", "0", "0", "0"], "--q"),
], ids=lambda v: " ".join(v) if isinstance(v, list) else v)
def test_bad_number_is_an_argument_error(argv, arg, no_work, capsys):
    assert_fails(argv, capsys, f"argument {arg}")
    assert not Path("b.db").exists()


def test_show_case_beyond_the_cached_cases(no_work, capsys):
    last = assert_one_line(["show", "tabletop_pole", "--case", "99999"], capsys, "--case",
                           "0..99")
    assert "--cases" in last
    assert not (no_work / "cache").exists()  # nothing generated or cached


def test_show_case_beyond_a_case_file(no_work, capsys, case_file):
    assert_one_line(["show", "tabletop_pole", "--case", "3", "--cases", str(case_file)], capsys,
                    "--case 3", "0..2")


@pytest.mark.parametrize("argv, arg", [
    (["show", "tabletop_pole", "--cases", "c.npz"], "--cases"),
    (["show", "tabletop_pole", "--planner", "TrajOpt"], "--planner"),
    (["show", "tabletop_pole", "--save-path", "p.npy"], "--save-path"),
    (["show", "tabletop_pole", "--case", "1", "--planner", "TrajOpt", "--roadmap", "r.npz"],
     "--roadmap"),
    (["view", "tabletop_pole", "--cases", "c.npz", "--n-cases", "5"], "--n-cases"),
])
def test_ignored_arguments_are_errors(argv, arg, no_work, capsys):
    assert_one_line(argv, capsys, arg)


@settings(max_examples=60, deadline=None)
@given(st.one_of(st.integers(-2**40, 2**40).map(str), st.floats().map(repr),
                 st.text(max_size=8)))
def test_numeric_arguments_parse_to_their_range_or_exit_2(text):
    """Any text for --port, --time-limit, --workers, --case-seed: in range, or exit 2."""
    parser = build_parser()
    checks = [(["view", "s", f"--port={text}"], "port",
               lambda v: isinstance(v, int) and 1 <= v <= 65535),
              (["bench", f"--time-limit={text}"], "time_limit",
               lambda v: math.isfinite(v) and v > 0),
              (["bench", f"--workers={text}"], "workers", lambda v: v >= 1),
              (["bench", f"--case-seed={text}"], "case_seed", lambda v: 0 <= v < 2**32)]
    for argv, field, ok in checks:
        t0 = time.perf_counter()
        try:
            with contextlib.redirect_stderr(io.StringIO()):
                value = getattr(parser.parse_args(argv), field)
        except SystemExit as e:
            assert e.code == 2
        else:
            assert ok(value), (argv, value)
        assert time.perf_counter() - t0 < 1.0


# --- the error funnel of main() ----------------------------------------------------------------
def test_every_error_is_one_line(monkeypatch, capsys):
    import chekhov.scene.io as scene_io

    def raise_(e: BaseException):
        def f(*a, **k):
            raise e
        return f

    monkeypatch.setattr(scene_io, "builtin_scenes", raise_(ChekhovError("first\nsecond")))
    assert_one_line(["scenes"], capsys, "first", "second")
    monkeypatch.setattr(scene_io, "builtin_scenes",
                        raise_(PermissionError(13, "Permission denied", "/x/y")))
    code, err = run(["scenes"], capsys)
    assert code == 1 and err.strip() == "chekhov: error: /x/y: Permission denied"
    monkeypatch.setattr(scene_io, "builtin_scenes", raise_(KeyboardInterrupt()))
    code, err = run(["scenes"], capsys)
    assert code == 130 and err.strip() == "chekhov: interrupted"


def test_closed_stdout_is_a_quiet_exit():
    env = dict(os.environ, PYTHONPATH=f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    p = subprocess.Popen([sys.executable, "-m", "chekhov.cli", "scenes"], env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert p.stdout is not None and p.stderr is not None
    p.stdout.close()
    err = p.stderr.read().decode()
    p.stderr.close()
    assert p.wait(timeout=120) == 141
    assert "Traceback" not in err and "Exception ignored" not in err, err
