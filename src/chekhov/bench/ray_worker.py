"""The Ray actor of ``chekhov bench --executor ray``: a :class:`BenchWorker` in a Ray worker
process (decorated with ``ray.remote`` at run time, so Ray stays an optional dependency)."""

from __future__ import annotations

from chekhov.bench.config import BenchConfig
from chekhov.bench.record import RunRecord
from chekhov.bench.task import RunTask
from chekhov.bench.worker import BenchWorker


class RayWorker:
    """Builds its worlds and planners once (in its own process), then runs tasks."""

    def __init__(self, config: BenchConfig) -> None:
        self.worker = BenchWorker(config)

    def run(self, task: RunTask) -> list[RunRecord]:
        return self.worker.run_all(task)
