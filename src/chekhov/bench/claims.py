"""Several runners on one benchmark database: each claims a run just before it starts it, so
concurrent ``chekhov bench`` processes (or machines sharing the file) split the work and no run
is done twice.

Every runner registers a session (``chekhov_sessions``: host, pid, heartbeat) and claims each
run (``chekhov_claims``: experiment, planner, case → session) in the transaction that checks the
run is neither stored nor claimed by a live session; :meth:`BenchDatabase.insert_run` drops the
claim with the run written. A session is dead — its claims void — when its heartbeat is older
than its ``stale_after_s``, when it ran on this host under a process id that no longer exists
(a SIGKILLed runner is taken over at once by the next one), or when it is an earlier session of
this very process. Runs claimed by a live session are tried again every ``POLL_S`` s until that
session has written them (or died).
"""

from __future__ import annotations

import os
import socket
import sqlite3
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import replace

from chekhov.bench.database import BenchDatabase
from chekhov.bench.registry import seed_planner_name
from chekhov.bench.task import RunTask

Key = tuple[int, int, int]   # (experimentid, plannerid, case_index)

HEARTBEAT_S = 5.0   # s between heartbeats of a session
POLL_S = 0.5        # s between looks at runs another session holds
_LIVE: set[tuple[str, int]] = set()   # (database file, session id) open in this process


class Session:
    """This process's registration in ``db``; :meth:`close` withdraws it and its claims.

    Args:
        db: the database. stale_after_s: s without a heartbeat after which other runners
            take this session's runs over (longer than any one run between two heartbeats).
    """

    def __init__(self, db: BenchDatabase, stale_after_s: float) -> None:
        self.db = db
        self.host = socket.gethostname()
        self.pid = os.getpid()
        self._file = str(db.path.resolve())
        self._last_beat = time.monotonic()
        self.id = -1   # until registered

        def register(c: sqlite3.Connection) -> int:
            self._drop_dead(c)
            cur = c.execute(
                "INSERT INTO chekhov_sessions (host, pid, started, heartbeat, stale_after_s) "
                "VALUES (?, ?, ?, ?, ?)",
                (self.host, self.pid, time.time(), time.time(), float(stale_after_s)))
            assert cur.lastrowid is not None
            return int(cur.lastrowid)

        self.id = db.write("registering this runner", register)
        _LIVE.add((self._file, self.id))

    def _alive(self, sid: int, host: str, pid: int, heartbeat: float, stale_after_s: float
               ) -> bool:
        """Whether session ``sid`` may still be running its claimed runs."""
        if sid == self.id:
            return True
        if time.time() - heartbeat > stale_after_s:
            return False
        if host != self.host:
            return True
        if pid == self.pid:
            return (self._file, sid) in _LIVE
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            return True
        return True

    def _drop_dead(self, c: sqlite3.Connection) -> None:
        rows = c.execute("SELECT id, host, pid, heartbeat, stale_after_s FROM "
                         "chekhov_sessions").fetchall()
        for sid, *rest in rows:
            if not self._alive(int(sid), *rest):
                c.execute("DELETE FROM chekhov_claims WHERE session=?", (sid,))
                c.execute("DELETE FROM chekhov_sessions WHERE id=?", (sid,))

    def claim(self, keys: Sequence[Key]) -> tuple[str, set[Key]]:
        """Claim the runs ``keys`` together: ("claimed", stored) when this session now holds
        every one of them not already stored; ("done", stored) when all are stored; ("busy",
        stored) when a live session holds one (nothing claimed). ``stored``: the keys whose
        runs are in the database."""
        def attempt(c: sqlite3.Connection) -> tuple[str, set[Key]]:
            stored = {k for k in keys if c.execute(
                "SELECT 1 FROM runs WHERE experimentid=? AND plannerid=? AND case_index=?",
                k).fetchone() is not None}
            todo = [k for k in keys if k not in stored]
            if not todo:
                return "done", stored
            for k in todo:
                row = c.execute(
                    "SELECT s.id, s.host, s.pid, s.heartbeat, s.stale_after_s FROM "
                    "chekhov_claims k JOIN chekhov_sessions s ON s.id = k.session WHERE "
                    "k.experimentid=? AND k.plannerid=? AND k.case_index=?", k).fetchone()
                if row is not None and self._alive(int(row[0]), *row[1:]):
                    return "busy", stored
            now = time.time()
            c.executemany(
                "INSERT OR REPLACE INTO chekhov_claims VALUES (?, ?, ?, ?, ?)",
                [(*k, self.id, now) for k in todo])
            return "claimed", stored

        return self.db.write("claiming a run", attempt)

    def heartbeat(self) -> None:
        """Tell other runners this session is alive (at most every ``HEARTBEAT_S`` s)."""
        if time.monotonic() - self._last_beat < HEARTBEAT_S:
            return
        self._last_beat = time.monotonic()
        self.db.write("updating this runner's heartbeat", lambda c: c.execute(
            "UPDATE chekhov_sessions SET heartbeat=? WHERE id=?", (time.time(), self.id)))

    def close(self) -> None:
        """Withdraw the session and its remaining claims (one attempt of about a second: a
        session left behind is dead to every later runner anyway)."""
        _LIVE.discard((self._file, self.id))

        def withdraw(c: sqlite3.Connection) -> None:
            c.execute("DELETE FROM chekhov_claims WHERE session=?", (self.id,))
            c.execute("DELETE FROM chekhov_sessions WHERE id=?", (self.id,))

        self.db.write("withdrawing this runner", withdraw, timeout_s=1.0)


class ClaimedTasks:
    """The tasks of one runner, handed out (:meth:`take`) only once claimed; a task another
    live session holds waits and is tried again every ``POLL_S`` s, a task found stored is
    dropped (counted in ``by_others``).

    Args:
        session: this runner's session. tasks: in order.
        keys: the runs a task records: its own and, for a task that records its seed stage,
            the seed planner's (in that order).
    """

    def __init__(self, session: Session, tasks: Sequence[RunTask],
                 keys: Callable[[RunTask], list[Key]]) -> None:
        self.session = session
        self.keys = keys
        self.ready: deque[RunTask] = deque(tasks)
        self.waiting: list[RunTask] = []
        self.retry_at = 0.0
        self.by_others = 0

    @property
    def exhausted(self) -> bool:
        return not self.ready and not self.waiting

    @property
    def left(self) -> int:
        return len(self.ready) + len(self.waiting)

    def take(self) -> RunTask | None:
        """The next task claimed for this runner; None when none can be claimed now."""
        if not self.ready and self.waiting and time.monotonic() >= self.retry_at:
            self.ready.extend(self.waiting)
            self.waiting.clear()
        while self.ready:
            task = self.ready.popleft()
            keys = self.keys(task)
            state, stored = self.session.claim(keys)
            if state == "busy":
                self.waiting.append(task)
                if not self.ready:
                    self.retry_at = time.monotonic() + POLL_S
                continue
            self.by_others += len(stored)
            if state == "claimed":
                return _without_stored(task, keys, stored)
        return None

    def tick(self) -> None:
        self.session.heartbeat()


def _without_stored(task: RunTask, keys: list[Key], stored: set[Key]) -> RunTask:
    """``task`` reduced to the runs not yet stored: X+TrajOpt recording X's run as its seed
    stage runs as X+TrajOpt alone when X is stored, and as X alone when X+TrajOpt is."""
    if not task.records_seed_run:
        return task
    own, seed = keys
    base = seed_planner_name(task.planner)
    if seed in stored:
        return replace(task, records_seed_run=False)
    if own in stored and base is not None:
        return replace(task, planner=base, records_seed_run=False)
    return task
