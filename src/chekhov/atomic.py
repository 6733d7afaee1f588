"""Atomic file writes: a temporary file beside the target, flushed to disk, renamed into place,
so a reader sees the old file or the new one and an interrupted write leaves no partial file
(its temporary is removed, unless the process is killed: see ``roadmap.io`` for cleaning up
after a killed writer)."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any


def write_atomic(path: Path, write: Callable[[Any], None], mode: str = "w", *,
                 prefix: str | None = None, suffix: str = "") -> None:
    """Call ``write(file)`` on a temporary file next to ``path`` (named ``prefix`` + random +
    ``suffix``; default prefix ``.NAME.``), then rename it into place. ``mode``: "w" or "wb"."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=prefix if prefix is not None else f".{path.name}.",
                               suffix=suffix, dir=path.parent)
    try:
        with os.fdopen(fd, mode) as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
