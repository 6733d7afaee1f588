"""Where runs execute: in this process, a local pool of processes, or a Ray cluster. Each
yields :class:`RunRecord` s as they finish (any order); the caller writes them.

Every worker (process or Ray actor) holds one :class:`BenchWorker`, so it builds each world,
roadmap and planner once.
"""

from __future__ import annotations

import multiprocessing as mp
import os
from collections.abc import Iterator, Sequence
from typing import Any

from chekhov.bench.config import BenchConfig
from chekhov.bench.record import RunRecord
from chekhov.bench.task import RunTask
from chekhov.bench.worker import BenchWorker
from chekhov.errors import ChekhovError

# Each process plans on one core: keep BLAS / OpenMP pools from oversubscribing the machine.
_SINGLE_THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
                      "MKL_NUM_THREADS": "1"}

_WORKER: BenchWorker | None = None


def run_tasks(tasks: Sequence[RunTask], config: BenchConfig) -> Iterator[RunRecord]:
    """Run ``tasks`` with the executor ``config`` names."""
    if not tasks:
        return iter(())
    if config.executor == "ray":
        return run_ray(tasks, config)
    if config.local_workers == 1:
        return run_inline(tasks, config)
    return run_local(tasks, config)


def run_inline(tasks: Sequence[RunTask], config: BenchConfig) -> Iterator[RunRecord]:
    """One worker in this process."""
    worker = BenchWorker(config)
    for t in tasks:
        yield from worker.run_all(t)


def _init_worker(config: BenchConfig) -> None:
    global _WORKER
    _WORKER = BenchWorker(config)


def _run_one(task: RunTask) -> list[RunRecord]:
    assert _WORKER is not None, "worker not initialised"
    return _WORKER.run_all(task)


def run_local(tasks: Sequence[RunTask], config: BenchConfig) -> Iterator[RunRecord]:
    """A pool of ``config.local_workers`` fresh processes (spawned: no state shared with
    this process, no inherited threads). Stopping the iteration (or Ctrl-C) terminates the
    pool; runs already yielded stay yielded."""
    n = min(config.local_workers, len(tasks))
    ctx = mp.get_context("spawn")
    saved = {k: os.environ.get(k) for k in _SINGLE_THREAD_ENV}
    for k, v in _SINGLE_THREAD_ENV.items():
        os.environ.setdefault(k, v)
    try:
        pool = ctx.Pool(n, initializer=_init_worker, initargs=(config,))
    finally:
        for k, old in saved.items():
            if old is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = old
    try:
        for records in pool.imap_unordered(_run_one, tasks, chunksize=1):
            yield from records
        pool.close()
    finally:
        pool.terminate()
        pool.join()


def run_ray(tasks: Sequence[RunTask], config: BenchConfig) -> Iterator[RunRecord]:
    """The runs on a Ray cluster (``config.address``; None starts a local Ray with
    ``config.workers`` CPUs): one actor per worker (``config.workers``, default the cluster's
    CPUs), each with its own :class:`BenchWorker`. Needs ``pip install 'chekhov[ray]'``."""
    ray = _import_ray()
    started = False
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False,
                                  "configure_logging": False}
        if config.address is not None:
            ray.init(address=config.address, **kwargs)
        else:
            ray.init(num_cpus=config.local_workers, **kwargs)
        started = True
    try:
        n_actors = config.workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
        n_actors = min(n_actors, len(tasks))
        from chekhov.bench.ray_worker import RayWorker

        actor_cls = ray.remote(num_cpus=1, runtime_env={"env_vars": _SINGLE_THREAD_ENV}
                               )(RayWorker)
        actors = [actor_cls.remote(config) for _ in range(n_actors)]
        pending: dict[Any, Any] = {}
        queue = list(tasks)
        queue.reverse()
        for a in actors:
            if queue:
                pending[a.run.remote(queue.pop())] = a
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            ref = ready[0]
            actor = pending.pop(ref)
            if queue:
                pending[actor.run.remote(queue.pop())] = actor
            yield from ray.get(ref)
        for a in actors:
            ray.kill(a)
    finally:
        if started:
            ray.shutdown()


def _import_ray() -> Any:
    try:
        import ray
    except ImportError as e:
        raise ChekhovError("--executor ray needs Ray: pip install 'chekhov[ray]' "
                           "(or pip install ray)") from e
    return ray
