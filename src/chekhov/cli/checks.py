"""Checks of command-line arguments shared by every command, run before any work.

Numbers: argparse ``type=`` functions (``int_at_least(1, 10**6)``, ``positive_seconds``,
``SEED``, ``PORT`` …) raise :class:`argparse.ArgumentTypeError`, so argparse reports
``argument --x: …`` and exits 2 before the command starts.

Paths: :func:`output_file`, :func:`output_dir` and :func:`sqlite_file` raise
:class:`~chekhov.errors.ChekhovError` naming the argument, so a command that would only write
at the end of a long run (a roadmap build, a benchmark) fails in its first second instead.
"""

from __future__ import annotations

import argparse
import math
import sqlite3
import tempfile
from collections.abc import Callable
from pathlib import Path

from chekhov.errors import ChekhovError

SEED_MAX = 2**32 - 1
"""Largest seed: numpy takes any non-negative integer, OMPL's seed is a 32-bit unsigned."""

CASE_FAMILIES = ("random", "tasks")
"""``chekhov.cases.FAMILIES``, without importing it (it loads the world) for ``--help``."""

_SQLITE_MAGIC = b"SQLite format 3\x00"


def _integer(text: str) -> int:
    try:
        return int(text, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got '{text}'") from None


def int_at_least(low: int, high: int | None = None, what: str = "") -> Callable[[str], int]:
    """An argparse type: an integer in [low, high] (``high`` None: no upper bound)."""

    def parse(text: str) -> int:
        v = _integer(text)
        if v < low or (high is not None and v > high):
            span = f"at least {low}" if high is None else f"in {low}..{high}"
            raise argparse.ArgumentTypeError(f"must be {span}{what}, got {v}")
        return v

    parse.__name__ = "integer"  # argparse names the type in "invalid <name> value"
    return parse


def _number(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got '{text}'") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
    return v


def finite_float(text: str) -> float:
    """An argparse type: a finite float (no nan, no inf)."""
    return _number(text)


def number_in(low: float, high: float, what: str = "a number") -> Callable[[str], float]:
    """An argparse type: a finite number, > ``low`` and ≤ ``high``."""

    def parse(text: str) -> float:
        v = _number(text)
        if not low < v <= high:
            raise argparse.ArgumentTypeError(f"must be {what}, > {low:g} and ≤ {high:g}, got {v:g}")
        return v

    parse.__name__ = "number"
    return parse


def seconds_in(high: float) -> Callable[[str], float]:
    """An argparse type: a time limit in s, finite, > 0 and ≤ ``high``."""
    parse = number_in(0.0, high, "a time in s")
    parse.__name__ = "seconds"
    return parse


SEED = int_at_least(0, SEED_MAX)
PORT = int_at_least(1, 65535, " (a TCP port)")
WORKERS = int_at_least(1, 4096)
positive_seconds = seconds_in(7 * 24 * 3600.0)


def _nearest_existing(p: Path) -> Path:
    """``p`` or its nearest ancestor that exists (``.`` for a relative path's base)."""
    p = p if p.is_absolute() else Path.cwd() / p
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _check_dir_writable(folder: Path, arg: str, given: str | Path) -> None:
    """Raise unless files can be created in ``folder`` or in the folders it would be created
    in: its nearest existing ancestor must be a writable folder (probed with a temporary
    file, so read-only file systems and permissions are caught, even for root)."""
    base = _nearest_existing(folder)
    if not base.is_dir():
        raise ChekhovError(f"{arg} {given}: cannot create it: {base} is not a folder")
    try:
        with tempfile.TemporaryFile(dir=base):
            pass
    except OSError as e:
        raise ChekhovError(f"{arg} {given}: cannot write in {base}: {e.strerror or e}") from e


def output_file(path: str | Path, arg: str) -> Path:
    """Check that ``path`` can be written as a file (a new one, or a regular file replaced
    atomically); returns it as a Path. Raises ChekhovError naming ``arg``."""
    p = Path(path)
    try:
        if str(path) == "" or p.is_dir():
            raise ChekhovError(f"{arg} '{path}': is a folder, expected a file name")
        if p.exists() and not p.is_file():
            raise ChekhovError(f"{arg} {path}: exists and is not a regular file")
        _check_dir_writable(p.parent, arg, path)
    except OSError as e:
        raise ChekhovError(f"{arg} {path}: unusable path: {e.strerror or e}") from e
    return p


def output_dir(path: str | Path, arg: str) -> Path:
    """Check that ``path`` is, or can be created as, a writable folder; returns it."""
    p = Path(path)
    try:
        if p.exists() and not p.is_dir():
            raise ChekhovError(f"{arg} {path}: exists and is not a folder")
        _check_dir_writable(p, arg, path)
    except OSError as e:
        raise ChekhovError(f"{arg} {path}: unusable path: {e.strerror or e}") from e
    return p


def sqlite_file(path: str | Path, arg: str, must_exist: bool) -> Path:
    """Check a benchmark database path: a chekhov benchmark database (read and written in
    place), or with ``must_exist`` False also a new or empty file that can be created, so that
    another program's file or SQLite database is never written into. Never creates or changes
    the file."""
    p = Path(path)
    if must_exist and not p.exists():
        raise ChekhovError(f"{arg} {path}: no such benchmark database")
    if must_exist:
        input_file(p, arg)
    else:
        output_file(p, arg)
        if not p.exists():
            return p
    try:
        with open(p, "rb" if must_exist else "r+b") as f:
            head = f.read(len(_SQLITE_MAGIC))
    except OSError as e:
        raise ChekhovError(f"{arg} {path}: cannot open: {e.strerror or e}") from e
    if head != _SQLITE_MAGIC and (must_exist or head):
        raise ChekhovError(f"{arg} {path}: not an SQLite benchmark database "
                           f"({'empty file' if not head else 'other content'})")
    tables = _sqlite_tables(p, arg) if head else set()
    if (must_exist or tables) and "chekhov_runs" not in tables:
        raise ChekhovError(f"{arg} {path}: an SQLite database, but not a chekhov benchmark "
                           f"database (tables: {sorted(tables) or 'none'})")
    return p


def _sqlite_tables(path: Path, arg: str) -> set[str]:
    """Names of the tables of the SQLite file ``path``, read without changing it."""
    try:
        conn = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
        try:
            rows = conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")
            return {r[0] for r in rows}
        finally:
            conn.close()
    except sqlite3.Error as e:
        raise ChekhovError(f"{arg} {path}: cannot read the SQLite database: {e}") from e


def distinct_outputs(paths: list[tuple[str, str | Path | None]]) -> None:
    """Raise when two arguments name the same file (one would overwrite the other); ``paths``
    holds (argument, path or None) pairs."""
    seen: dict[Path, str] = {}
    for arg, path in paths:
        if path is None:
            continue
        key = Path(path).resolve()
        if key in seen:
            raise ChekhovError(f"{arg} {path}: the same file as {seen[key]}")
        seen[key] = arg


def input_file(path: str | Path, arg: str) -> Path:
    """Check that ``path`` is an existing, non-empty regular file; returns it."""
    p = Path(path)
    try:
        if not p.exists():
            raise ChekhovError(f"{arg} {path}: no such file")
        if not p.is_file():
            raise ChekhovError(f"{arg} {path}: not a regular file")
        if p.stat().st_size == 0:
            raise ChekhovError(f"{arg} {path}: the file is empty")
    except OSError as e:
        raise ChekhovError(f"{arg} {path}: unusable path: {e.strerror or e}") from e
    return p
