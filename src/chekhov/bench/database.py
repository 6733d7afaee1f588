"""Benchmark results in SQLite, in the layout of OMPL's benchmark database.

OMPL's tables, as ``ompl_benchmark_statistics.py`` creates them (Planner Arena reads these):

* ``experiments`` (id, name, totaltime, timelimit, memorylimit, runcount, version, hostname,
  cpuinfo, date, seed, setup) — one per scene, case family, case source and time limit;
  ``name`` is the scene. Extra columns (as OMPL's experiment properties): ``scene_hash``,
  ``case_seed``, ``case_source``, ``exact_substeps``, ``resolution``, ``family`` (the case
  family, "random" or "tasks"; added as "random" to the experiments of a version-1 database
  when it is opened, which is what they all hold, so such a database resumes as before).
* ``plannerConfigs`` (id, name, settings) — ``settings`` is the planner's configuration as JSON.
* ``enums`` (name, value, description) — ``status`` (OMPL's PlannerStatus strings) and
  ``failure_kind`` (ours, values added as they occur).
* ``runs`` (id, experimentid, plannerid, + properties) with OMPL's property columns ``time``
  REAL (s, planning time), ``solved`` BOOLEAN (a path was returned), ``status`` ENUM,
  ``approximate_solution`` BOOLEAN (always 0: approximate answers count as failures),
  ``solution_length`` REAL (rad, joint-space), ``correct_solution`` BOOLEAN (the exact
  100-substep check), ``memory`` REAL (NULL: not measured), and ours: ``case_index``
  INTEGER, ``success`` BOOLEAN (solved and exactly collision-free: the paper's success),
  ``exact_collision`` BOOLEAN, ``failure_kind`` ENUM, ``waypoints`` INTEGER,
  ``seed_time`` / ``trajopt_time`` REAL (s), ``seed_length`` REAL (rad), ``seed_found`` /
  ``trajopt_ok`` / ``fallback_to_seed`` BOOLEAN, ``exact_check_time`` REAL (s, not part of
  ``time``). One row per (experimentid, plannerid, case_index) (unique index ``runs_case``).
* ``progress`` (runid, time) — OMPL's progress properties; empty here.
* views ``bestPlannerConfigsPerExperiment`` and ``bestPlannerConfigs``, as OMPL computes them.

Ours only (a side table, so that OMPL's tools see plain numeric runs): ``chekhov_runs``
(runid → runs.id, scene, planner, case_index, case_hash, status text, failure_kind text,
trajopt_status, timing_json — the breakdown of ``time`` in s —, info_json, worker, dof,
path / seed_path — float32 little-endian bytes, row-major (T, dof), rad —, waypoints,
seed_waypoints, finished), ``chekhov_meta`` (key, value), and the bookkeeping of concurrent
runners (:mod:`chekhov.bench.claims`): ``chekhov_sessions`` (id, host, pid, started,
heartbeat — Unix time, s —, stale_after_s) and ``chekhov_claims`` (experimentid, plannerid,
case_index → the session running that run now).

Every run is written in its own transaction, together with its share of the experiment's
``totaltime``, so an interrupted (even SIGKILLed) benchmark keeps every run written before
and the time they took, and a rerun skips them (:meth:`BenchDatabase.done_cases`). Every
statement that finds the database locked by another program is retried with backoff for up to
``lock_timeout_s`` (s); then, and on any other SQLite failure, a :class:`BenchError` names the
file and what was being done.
"""

from __future__ import annotations

import csv
import json
import math
import sqlite3
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from chekhov.bench.files import write_file
from chekhov.bench.record import RunRecord
from chekhov.errors import BenchError

T = TypeVar("T")

DB_FORMAT = "chekhov-bench"
DB_VERSION = 2   # 2: experiments.family

# ompl::base::PlannerStatus, in order (the strings OMPL's Benchmark writes to its logs).
OMPL_STATUS = ("Unknown status", "Invalid start", "Invalid goal", "Unrecognized goal type",
               "Timeout", "Approximate solution", "Exact solution", "Crash", "Abort")
_STATUS_OF = {"solved": 6, "timeout": 4, "seed_timeout": 4, "invalid_start": 1,
              "seed_invalid_start": 1, "no_ik": 2, "seed_no_ik": 2, "invalid_goal": 2,
              "crash": 7, "case_error": 8}

# How long a locked database is waited for (s) before the runner stops with a BenchError.
DEFAULT_LOCK_TIMEOUT_S = 120.0
_BUSY_WAIT_S = 1.0        # SQLite's own wait per attempt (s), at most
_FIRST_BACKOFF_S = 0.05   # pause after the first locked attempt (s), doubled up to ...
_MAX_BACKOFF_S = 2.0

_SCHEMA = """
CREATE TABLE IF NOT EXISTS experiments
    (id INTEGER PRIMARY KEY AUTOINCREMENT, name VARCHAR(512),
    totaltime REAL, timelimit REAL, memorylimit REAL, runcount INTEGER,
    version VARCHAR(128), hostname VARCHAR(1024), cpuinfo TEXT,
    date DATETIME, seed VARCHAR(24), setup TEXT,
    scene_hash VARCHAR(64), case_seed INTEGER, case_source TEXT, exact_substeps INTEGER,
    resolution REAL, family TEXT NOT NULL DEFAULT 'random');
CREATE TABLE IF NOT EXISTS plannerConfigs
    (id INTEGER PRIMARY KEY AUTOINCREMENT,
    name VARCHAR(512) NOT NULL, settings TEXT);
CREATE TABLE IF NOT EXISTS enums
    (name VARCHAR(512), value INTEGER, description TEXT,
    PRIMARY KEY (name, value));
CREATE TABLE IF NOT EXISTS runs
    (id INTEGER PRIMARY KEY AUTOINCREMENT, experimentid INTEGER, plannerid INTEGER,
    time REAL, solved BOOLEAN, status ENUM, approximate_solution BOOLEAN,
    solution_length REAL, correct_solution BOOLEAN, memory REAL,
    case_index INTEGER, success BOOLEAN, exact_collision BOOLEAN, failure_kind ENUM,
    waypoints INTEGER, seed_time REAL, trajopt_time REAL, seed_length REAL,
    seed_found BOOLEAN, trajopt_ok BOOLEAN, fallback_to_seed BOOLEAN, exact_check_time REAL,
    FOREIGN KEY (experimentid) REFERENCES experiments(id) ON DELETE CASCADE,
    FOREIGN KEY (plannerid) REFERENCES plannerConfigs(id) ON DELETE CASCADE);
CREATE TABLE IF NOT EXISTS progress
    (runid INTEGER, time REAL, PRIMARY KEY (runid, time),
    FOREIGN KEY (runid) REFERENCES runs(id) ON DELETE CASCADE);
CREATE UNIQUE INDEX IF NOT EXISTS runs_case ON runs(experimentid, plannerid, case_index);
CREATE TABLE IF NOT EXISTS chekhov_runs
    (runid INTEGER PRIMARY KEY, scene TEXT, planner TEXT, case_index INTEGER,
    case_hash TEXT, status TEXT, failure_kind TEXT, trajopt_status TEXT, timing_json TEXT,
    info_json TEXT, worker TEXT, dof INTEGER, path BLOB, waypoints INTEGER, seed_path BLOB,
    seed_waypoints INTEGER, finished DATETIME,
    FOREIGN KEY (runid) REFERENCES runs(id) ON DELETE CASCADE);
CREATE TABLE IF NOT EXISTS chekhov_meta (key TEXT PRIMARY KEY, value TEXT);
CREATE TABLE IF NOT EXISTS chekhov_sessions
    (id INTEGER PRIMARY KEY AUTOINCREMENT, host TEXT, pid INTEGER, started REAL,
    heartbeat REAL, stale_after_s REAL);
CREATE TABLE IF NOT EXISTS chekhov_claims
    (experimentid INTEGER, plannerid INTEGER, case_index INTEGER, session INTEGER,
    claimed REAL, PRIMARY KEY (experimentid, plannerid, case_index));
"""

_VIEWS_BASE = """SELECT plannerid, plannerConfigs.name AS plannerName, experimentid,
    solved, time AS total_time
    FROM plannerConfigs INNER JOIN experiments INNER JOIN runs
    ON plannerConfigs.id=runs.plannerid AND experiments.id=runs.experimentid"""


class BenchDatabase:
    """A benchmark database file (created on first use). Use as a context manager or call
    :meth:`close`. Several runners may share one (each writes its own runs; see
    :mod:`chekhov.bench.claims`).

    Args:
        path: the SQLite file.
        lock_timeout_s: s, how long a statement that finds the database locked by another
            program is retried (with backoff) before a :class:`BenchError`.
    """

    def __init__(self, path: str | Path,
                 lock_timeout_s: float = DEFAULT_LOCK_TIMEOUT_S) -> None:
        if not (isinstance(lock_timeout_s, int | float) and lock_timeout_s > 0):
            raise BenchError(f"{path}: lock_timeout_s must be positive (s), got "
                             f"{lock_timeout_s!r}")
        self.path = Path(path)
        self.lock_timeout_s = float(lock_timeout_s)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.conn = sqlite3.connect(self.path, isolation_level=None,
                                        timeout=min(_BUSY_WAIT_S, self.lock_timeout_s / 4))
        except (OSError, sqlite3.Error) as e:
            raise BenchError(f"{self.path}: cannot open the benchmark database: {e}") from e
        self.conn.row_factory = sqlite3.Row
        try:
            self.read("opening the database",
                      lambda c: c.execute("PRAGMA foreign_keys = ON"))
            self.write("opening the database", self._create)
        except BaseException:
            self.conn.close()
            raise

    def __enter__(self) -> BenchDatabase:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self.conn.close()

    @contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """One write transaction: committed on success, rolled back on any error (including
        KeyboardInterrupt and a failed commit). Not retried; see :meth:`write`."""
        self.conn.execute("BEGIN IMMEDIATE")
        try:
            yield self.conn
            self.conn.commit()
        except BaseException:
            if self.conn.in_transaction:
                self.conn.rollback()
            raise

    def write(self, what: str, fn: Callable[[sqlite3.Connection], T],
              timeout_s: float | None = None) -> T:
        """``fn(conn)`` in one write transaction, retried while the database is locked (see
        :meth:`_retry`); ``what`` says what is being written, for the error message."""
        def attempt() -> T:
            with self.transaction() as c:
                return fn(c)
        return self._retry(what, attempt, timeout_s)

    def read(self, what: str, fn: Callable[[sqlite3.Connection], T]) -> T:
        """``fn(conn)`` outside a transaction, retried while the database is locked."""
        return self._retry(what, lambda: fn(self.conn))

    def _retry(self, what: str, attempt: Callable[[], T], timeout_s: float | None = None) -> T:
        """``attempt()``, again after a pause (0.05 s, doubling up to 2 s) while it finds the
        database locked, for up to ``timeout_s`` (default ``lock_timeout_s``) s in all. Then,
        or on any other SQLite error, a :class:`BenchError` naming the file and ``what``."""
        limit = self.lock_timeout_s if timeout_s is None else timeout_s
        deadline = time.monotonic() + limit
        pause = _FIRST_BACKOFF_S
        while True:
            try:
                return attempt()
            except sqlite3.OperationalError as e:
                left = deadline - time.monotonic()
                if not _locked(e):
                    raise BenchError(f"{self.path}: SQLite failed while {what}: {e}") from e
                if left <= 0:
                    raise BenchError(
                        f"{self.path}: the database was locked by another program for more "
                        f"than {limit:g} s while {what}; every run written before is kept. "
                        "Close that program (an open sqlite3 shell or transaction), then rerun "
                        "the same command to do the rest") from e
                time.sleep(min(pause, left))
                pause = min(2 * pause, _MAX_BACKOFF_S)
            except sqlite3.DatabaseError as e:
                raise BenchError(f"{self.path}: not a usable SQLite benchmark database "
                                 f"({what}): {e}") from e

    # --- schema ---------------------------------------------------------------------------
    def _create(self, c: sqlite3.Connection) -> None:
        """Check the file's format and create what is missing, in one transaction (so that
        a runner starting beside another never sees half a schema)."""
        meta = c.execute("SELECT name FROM sqlite_master WHERE name='chekhov_meta'").fetchall()
        if meta:
            fmt = dict(c.execute("SELECT key, value FROM chekhov_meta").fetchall())
            if fmt.get("format") != DB_FORMAT or int(fmt.get("version", 0)) > DB_VERSION:
                raise BenchError(f"{self.path}: benchmark database format "
                                 f"{fmt.get('format')} version {fmt.get('version')}; this "
                                 f"chekhov writes {DB_FORMAT} version {DB_VERSION}")
        elif c.execute("SELECT count(*) FROM sqlite_master WHERE name='runs'").fetchone()[0]:
            raise BenchError(f"{self.path}: an OMPL benchmark database not written by "
                             "chekhov; use another --db file")
        for statement in _SCHEMA.split(";"):
            if statement.strip():
                c.execute(statement)
        columns = {r[1] for r in c.execute("PRAGMA table_info(experiments)").fetchall()}
        if "family" not in columns:   # a version-1 database: every experiment is random
            c.execute("ALTER TABLE experiments ADD COLUMN family TEXT NOT NULL "
                      "DEFAULT 'random'")
        c.executemany("INSERT OR IGNORE INTO chekhov_meta VALUES (?, ?)",
                      [("format", DB_FORMAT),
                       ("units", "time s, lengths rad, paths float32 rad (T, dof)")])
        c.execute("INSERT OR REPLACE INTO chekhov_meta VALUES ('version', ?)",
                  (str(DB_VERSION),))
        c.executemany("INSERT OR IGNORE INTO enums VALUES (?, ?, ?)",
                      [("status", i, s) for i, s in enumerate(OMPL_STATUS)]
                      + [("failure_kind", 0, "none")])
        c.execute("DROP VIEW IF EXISTS bestPlannerConfigsPerExperiment")
        c.execute("CREATE VIEW bestPlannerConfigsPerExperiment AS SELECT plannerid, "
                  "experimentid, MIN(avg_solved) AS avg_solved, avg_total_time FROM "
                  "(SELECT plannerid, plannerName, experimentid, AVG(solved) AS "
                  "avg_solved, AVG(total_time) AS avg_total_time FROM (" + _VIEWS_BASE +
                  ") GROUP BY plannerid, experimentid) GROUP BY plannerName, experimentid "
                  "ORDER BY avg_solved DESC, avg_total_time ASC")
        c.execute("DROP VIEW IF EXISTS bestPlannerConfigs")
        c.execute("CREATE VIEW bestPlannerConfigs AS SELECT plannerid, MIN(avg_solved) AS "
                  "avg_solved, avg_total_time FROM (SELECT plannerid, plannerName, "
                  "AVG(solved) AS avg_solved, AVG(total_time) AS avg_total_time FROM ("
                  + _VIEWS_BASE + ") GROUP BY plannerid) GROUP BY plannerName ORDER BY "
                  "avg_solved DESC, avg_total_time ASC")

    def tables(self) -> list[str]:
        return [r[0] for r in self.read("listing tables", lambda c: c.execute(
            "SELECT name FROM sqlite_master WHERE type='table' ORDER BY name").fetchall())]

    # --- experiments and planner configs ----------------------------------------------
    def experiment_id(self, scene: str, scene_hash: str, case_seed: int, case_source: str,
                      time_limit_s: float, exact_substeps: int, resolution: float,
                      setup: str = "", version: str = "", hostname: str = "",
                      cpuinfo: str = "", family: str = "random") -> int:
        """The experiment of these settings and case family (created when new; looked up and
        created in one transaction, so runners starting together share it)."""
        key = (scene, scene_hash, case_seed, case_source, time_limit_s, exact_substeps,
               resolution, family)

        def get(c: sqlite3.Connection) -> int:
            row = c.execute(
                "SELECT id FROM experiments WHERE name=? AND scene_hash=? AND case_seed=? AND "
                "case_source=? AND timelimit=? AND exact_substeps=? AND resolution=? AND "
                "family=? ORDER BY id", key).fetchone()
            if row is not None:
                return int(row[0])
            cur = c.execute(
                "INSERT INTO experiments (name, totaltime, timelimit, memorylimit, runcount, "
                "version, hostname, cpuinfo, date, seed, setup, scene_hash, case_seed, "
                "case_source, exact_substeps, resolution, family) VALUES "
                "(?, 0, ?, 0, 0, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (scene, time_limit_s, version, hostname, cpuinfo,
                 time.strftime("%Y-%m-%d %H:%M:%S"), str(case_seed), setup, scene_hash,
                 case_seed, case_source, exact_substeps, resolution, family))
            assert cur.lastrowid is not None
            return int(cur.lastrowid)

        return self.write(f"recording the experiment of scene '{scene}' ({family} cases)",
                          get)

    def planner_id(self, name: str, settings: str) -> int:
        """The plannerConfigs row of (name, settings) (created when new), as OMPL does."""
        def get(c: sqlite3.Connection) -> int:
            row = c.execute("SELECT id FROM plannerConfigs WHERE name=? AND settings=? "
                            "ORDER BY id", (name, settings)).fetchone()
            if row is not None:
                return int(row[0])
            cur = c.execute("INSERT INTO plannerConfigs (name, settings) VALUES (?, ?)",
                            (name, settings))
            assert cur.lastrowid is not None
            return int(cur.lastrowid)

        return self.write(f"recording the configuration of planner {name}", get)

    def set_runcount(self, experiment_id: int, runcount: int) -> None:
        """Raise ``runcount`` (cases per planner) to at least ``runcount``."""
        self.write("setting the experiment's run count", lambda c: c.execute(
            "UPDATE experiments SET runcount = MAX(runcount, ?) WHERE id=?",
            (runcount, experiment_id)))

    # --- runs ---------------------------------------------------------------------------
    def done_cases(self, experiment_id: int, planner_id: int) -> dict[int, str]:
        """case index → case hash of the runs already stored."""
        rows = self.read("reading the runs already done", lambda c: c.execute(
            "SELECT r.case_index, k.case_hash FROM runs r LEFT JOIN chekhov_runs k "
            "ON k.runid = r.id WHERE r.experimentid=? AND r.plannerid=?",
            (experiment_id, planner_id)).fetchall())
        return {int(a): str(b) for a, b in rows}

    def _failure_kind_value(self, c: sqlite3.Connection, kind: str) -> int:
        row = c.execute("SELECT value FROM enums WHERE name='failure_kind' AND description=?",
                        (kind,)).fetchone()
        if row is not None:
            return int(row[0])
        v = int(c.execute("SELECT COALESCE(MAX(value), -1) + 1 FROM enums WHERE "
                          "name='failure_kind'").fetchone()[0])
        c.execute("INSERT INTO enums VALUES ('failure_kind', ?, ?)", (v, kind))
        return v

    def insert_run(self, experiment_id: int, planner_id: int, rec: RunRecord,
                   seconds: float = 0.0) -> int | None:
        """Store one run and add ``seconds`` (s) to its experiment's ``totaltime``, in one
        transaction that also drops any claim on the run; returns runs.id. A run already
        stored for the same case is left as it is, and None returned."""
        def insert(c: sqlite3.Connection) -> int | None:
            key = (experiment_id, planner_id, rec.case_index)
            c.execute("DELETE FROM chekhov_claims WHERE experimentid=? AND plannerid=? AND "
                      "case_index=?", key)
            if c.execute("SELECT id FROM runs WHERE experimentid=? AND plannerid=? AND "
                         "case_index=?", key).fetchone() is not None:
                return None
            runid = self._insert_rows(c, experiment_id, planner_id, rec)
            c.execute("UPDATE experiments SET totaltime = totaltime + ? WHERE id=?",
                      (float(seconds), experiment_id))
            return runid

        return self.write(f"writing the run of {rec.planner} on case {rec.case_index} of "
                          f"'{rec.scene}'", insert)

    def _insert_rows(self, c: sqlite3.Connection, experiment_id: int, planner_id: int,
                     rec: RunRecord) -> int:
        """The ``runs`` and ``chekhov_runs`` rows of ``rec``; returns runs.id."""
        fk = self._failure_kind_value(c, rec.failure_kind)
        cur = c.execute(
            "INSERT INTO runs (experimentid, plannerid, time, solved, status, "
            "approximate_solution, solution_length, correct_solution, memory, case_index, "
            "success, exact_collision, failure_kind, waypoints, seed_time, trajopt_time, "
            "seed_length, seed_found, trajopt_ok, fallback_to_seed, exact_check_time) "
            "VALUES (?, ?, ?, ?, ?, 0, ?, ?, NULL, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (experiment_id, planner_id, rec.time_s, int(rec.solved),
             ompl_status(rec.status), _num(rec.path_length), _flag(rec.exact_valid),
             rec.case_index, int(rec.success),
             None if rec.exact_valid is None else int(not rec.exact_valid), fk,
             None if rec.path is None else len(rec.path), _num(rec.seed_time_s),
             _num(rec.trajopt_time_s), _num(rec.seed_length), _flag(rec.seed_found),
             _flag(rec.trajopt_ok), _flag(rec.fallback_to_seed), rec.exact_check_s))
        runid = cur.lastrowid
        assert runid is not None
        dof = (rec.path.shape[1] if rec.path is not None else
               rec.seed_path.shape[1] if rec.seed_path is not None else None)
        c.execute(
            "INSERT INTO chekhov_runs VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, "
            "?, ?)",
            (runid, rec.scene, rec.planner, rec.case_index, rec.case_hash, rec.status,
             rec.failure_kind, rec.trajopt_status, json.dumps(rec.timing_s),
             json.dumps(rec.info, default=str), rec.worker, dof, pack_path(rec.path),
             None if rec.path is None else len(rec.path), pack_path(rec.seed_path),
             None if rec.seed_path is None else len(rec.seed_path),
             time.strftime("%Y-%m-%d %H:%M:%S")))
        return int(runid)

    # --- reading ------------------------------------------------------------------------
    def experiments(self) -> list[dict[str, Any]]:
        return [dict(r) for r in self.read("reading the experiments", lambda c: c.execute(
            "SELECT * FROM experiments ORDER BY id").fetchall())]

    def planner_configs(self) -> list[dict[str, Any]]:
        return [dict(r) for r in self.read("reading the planner configurations", lambda c:
                                           c.execute("SELECT * FROM plannerConfigs ORDER BY "
                                                     "id").fetchall())]

    def rows(self, experiment_ids: list[int] | None = None, planners: list[str] | None = None,
             max_case: int | None = None, paths: bool = False) -> list[dict[str, Any]]:
        """Runs joined with their experiment, planner and side-table fields, one dict each
        (``scene``, ``family``, ``planner``, ``timelimit``, every ``runs`` column,
        ``status_text``,
        ``failure_kind_text``, ``trajopt_status``, ``timing`` (dict, s), ``info`` (dict);
        with ``paths``, ``path`` / ``seed_path`` as (T, dof) float arrays or None)."""
        where: list[str] = []
        args: list[object] = []
        if experiment_ids is not None:
            where.append(f"r.experimentid IN ({','.join('?' * len(experiment_ids))})")
            args += experiment_ids
        if planners is not None:
            where.append(f"p.name IN ({','.join('?' * len(planners))})")
            args += planners
        if max_case is not None:
            where.append("r.case_index < ?")
            args.append(max_case)
        extra = ", k.path AS path_blob, k.seed_path AS seed_blob, k.dof AS dof" if paths else ""
        sql = ("SELECT r.*, e.name AS scene, e.family AS family, e.timelimit AS timelimit, "
               "p.name AS planner, "
               "k.status AS status_text, k.failure_kind AS failure_kind_text, "
               "k.trajopt_status AS trajopt_status, k.timing_json AS timing_json, "
               "k.info_json AS info_json, k.case_hash AS case_hash" + extra + " FROM runs r "
               "JOIN experiments e ON e.id = r.experimentid "
               "JOIN plannerConfigs p ON p.id = r.plannerid "
               "LEFT JOIN chekhov_runs k ON k.runid = r.id"
               + (" WHERE " + " AND ".join(where) if where else "")
               + " ORDER BY r.experimentid, p.name, r.case_index")
        out = []
        for row in self.read("reading the runs", lambda c: c.execute(sql, args).fetchall()):
            d = dict(row)
            d["timing"] = json.loads(d.pop("timing_json") or "{}")
            d["info"] = json.loads(d.pop("info_json") or "{}")
            if paths:
                dof = d.pop("dof")
                d["path"] = unpack_path(d.pop("path_blob"), dof)
                d["seed_path"] = unpack_path(d.pop("seed_blob"), dof)
            out.append(d)
        return out

    def export_csv(self, path: str | Path) -> Path:
        """All runs as CSV (one row each, no paths; ``timing`` as JSON), written atomically."""
        rows = self.rows()
        cols = ["scene", "family", "timelimit", "planner", "case_index", "case_hash", "success",
                "solved", "status_text", "failure_kind_text", "time", "solution_length",
                "correct_solution", "exact_collision", "waypoints", "seed_found",
                "seed_time", "seed_length", "trajopt_time", "trajopt_status", "trajopt_ok",
                "fallback_to_seed", "exact_check_time", "timing"]

        def write(f: IO[str]) -> None:
            w = csv.writer(f)
            w.writerow([c.replace("_text", "") for c in cols])
            for r in rows:
                w.writerow([json.dumps(r[c]) if c == "timing" else r[c] for c in cols])

        return write_file(path, write)


def ompl_status(status: str) -> int:
    """OMPL PlannerStatus value of a planner status string (6 = exact solution)."""
    return _STATUS_OF.get(status, 0)


def pack_path(path: NDArray[np.float64] | None) -> bytes | None:
    """A (T, K) path as float32 little-endian bytes (row-major); None stays None."""
    if path is None:
        return None
    return np.ascontiguousarray(path, dtype="<f4").tobytes()


def unpack_path(blob: bytes | None, dof: int | None) -> NDArray[np.float64] | None:
    """Inverse of :func:`pack_path`: a (T, dof) float64 array."""
    if blob is None or dof is None:
        return None
    return np.frombuffer(blob, dtype="<f4").astype(np.float64).reshape(-1, int(dof))


def _locked(e: sqlite3.OperationalError) -> bool:
    """``e`` says the database (or a table) is locked by another connection."""
    name = getattr(e, "sqlite_errorname", "")
    return name.startswith(("SQLITE_BUSY", "SQLITE_LOCKED")) or "locked" in str(e)


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _flag(x: bool | None) -> int | None:
    return None if x is None else int(bool(x))
