"""Atomic writes of the benchmark's output files, readable by others (``write_atomic``'s
temporary file is created private; the finished file gets rw-r--r-- less the umask)."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from chekhov.atomic import write_atomic


def write_file(path: str | Path, write: Callable[[Any], None], mode: str = "w") -> Path:
    """``write(file)`` into a temporary file renamed to ``path``; returns the path."""
    path = Path(path)
    write_atomic(path, write, mode=mode)
    umask = os.umask(0)
    os.umask(umask)
    path.chmod(0o644 & ~umask)
    return path


def write_text(path: str | Path, text: str) -> Path:
    """``text`` into ``path`` atomically."""
    return write_file(path, lambda f: f.write(text))
