"""A progress bar with ETA on stderr (a redrawn line on a terminal; else a line every ~10% of the
work and at least every ``log_interval_s`` seconds, for logs of long runs)."""

from __future__ import annotations

import sys
import time
from typing import TextIO


class ProgressBar:
    """``update()`` after each finished unit of work; ``close()`` at the end.

    Args:
        total: units of work. label: shown before the bar. stream: default stderr.
        enabled: False draws nothing. log_interval_s: most seconds between lines when the
        stream is not a terminal. count_failures: show "(N failed)" (off for work whose
        units cannot fail).
    """

    def __init__(self, total: int, label: str = "bench", stream: TextIO | None = None,
                 enabled: bool = True, width: int = 30, log_interval_s: float = 30.0,
                 count_failures: bool = True) -> None:
        self.total = max(int(total), 0)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled and self.total > 0
        self.width = width
        self.log_interval_s = log_interval_s
        self.count_failures = count_failures
        self.done = 0
        self.failed = 0
        self.t0 = time.perf_counter()
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._last_decile = -1
        self._last_draw = 0.0

    def update(self, n: int = 1, failed: bool = False) -> None:
        self.done += n
        self.failed += int(failed)
        if not self.enabled:
            return
        now = time.perf_counter()
        if self._tty:
            if now - self._last_draw >= 0.1 or self.done >= self.total:
                self._last_draw = now
                self.stream.write("\r" + self.line())
                self.stream.flush()
        else:
            decile = (10 * self.done) // self.total
            if decile != self._last_decile or now - self._last_draw >= self.log_interval_s:
                self._last_decile = decile
                self._last_draw = now
                self.stream.write(self.line() + "\n")
                self.stream.flush()

    def line(self) -> str:
        """The current bar: ``label [####      ] 12/40  30%  0:12 elapsed  ETA 0:28``."""
        frac = self.done / self.total if self.total else 1.0
        filled = round(frac * self.width)
        elapsed = time.perf_counter() - self.t0
        eta = elapsed / self.done * (self.total - self.done) if self.done else float("nan")
        return (f"{self.label} [{'#' * filled}{' ' * (self.width - filled)}] "
                f"{self.done}/{self.total} {100 * frac:3.0f}%  {_clock(elapsed)} elapsed  "
                f"ETA {_clock(eta)}" + (f"  ({self.failed} failed)" if self.count_failures
                                        else ""))

    def close(self) -> None:
        if self.enabled and self._tty:
            self.stream.write("\n")
            self.stream.flush()


def _clock(seconds: float) -> str:
    if seconds != seconds:  # nan
        return "--:--"
    s = round(seconds)
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"
