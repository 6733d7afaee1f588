"""Where runs execute: in this process, a local pool of processes, or a Ray cluster. Each
yields :class:`RunRecord` s as they finish (any order); the caller writes them.

Every worker (process or Ray actor) holds one :class:`BenchWorker`, so it builds each world,
roadmap and planner once. Tasks are taken from a :class:`TaskSource` one at a time, as a worker
frees up (never more in flight than workers), so a runner claims a run only when it starts it.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from chekhov.bench.config import BenchConfig
from chekhov.bench.record import RunRecord
from chekhov.bench.task import RunTask, TaskList, TaskSource
from chekhov.bench.worker import BenchWorker
from chekhov.errors import ChekhovError

# Each process plans on one core: keep BLAS / OpenMP pools from oversubscribing the machine.
_SINGLE_THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
                      "MKL_NUM_THREADS": "1"}
TICK_S = 1.0    # s, longest wait for a result before the source's tick (heartbeat)
IDLE_S = 0.2    # s, pause while no task can be taken and none is in flight

_WORKER: BenchWorker | None = None

Submit = Callable[[RunTask], None]
Collect = Callable[[float], list[RunRecord] | None]


def run_tasks(tasks: TaskSource | Sequence[RunTask], config: BenchConfig
              ) -> Iterator[RunRecord]:
    """Run the tasks (a list, or a :class:`TaskSource`) with the executor ``config`` names."""
    source: TaskSource = TaskList(tasks) if isinstance(tasks, Sequence) else tasks
    if source.exhausted:
        return iter(())
    if config.executor == "ray":
        return run_ray(source, config)
    if config.local_workers == 1:
        return run_inline(source, config)
    return run_local(source, config)


def drive(source: TaskSource, slots: int, submit: Submit, collect: Collect
          ) -> Iterator[RunRecord]:
    """Keep up to ``slots`` tasks in flight: ``submit`` starts one, ``collect(timeout_s)``
    returns the records of one finished task (None when none finished in time). A freed slot
    is refilled before the finished task's records are handed on."""
    busy = 0

    def refill() -> None:
        nonlocal busy
        while busy < slots:
            task = source.take()
            if task is None:
                return
            submit(task)
            busy += 1

    refill()
    while busy or not source.exhausted:
        if not busy:
            time.sleep(IDLE_S)
            source.tick()
            refill()
            continue
        records = collect(TICK_S)
        source.tick()
        if records is not None:
            busy -= 1
        refill()
        if records:
            yield from records


def run_inline(source: TaskSource, config: BenchConfig) -> Iterator[RunRecord]:
    """One worker in this process."""
    worker = BenchWorker(config)
    todo: list[RunTask] = []
    yield from drive(source, 1, todo.append,
                     lambda timeout_s: worker.run_all(todo.pop()))


def _init_worker(config: BenchConfig) -> None:
    global _WORKER
    _WORKER = BenchWorker(config)


def _run_one(task: RunTask) -> list[RunRecord]:
    assert _WORKER is not None, "worker not initialised"
    return _WORKER.run_all(task)


def run_local(source: TaskSource, config: BenchConfig) -> Iterator[RunRecord]:
    """A pool of ``config.local_workers`` fresh processes (spawned: no state shared with
    this process, no inherited threads). Stopping the iteration (or Ctrl-C) terminates the
    pool; runs already yielded stay yielded."""
    n = min(config.local_workers, source.left)
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
    done: queue.Queue[list[RunRecord] | BaseException] = queue.Queue()

    def submit(task: RunTask) -> None:
        pool.apply_async(_run_one, (task,), callback=done.put, error_callback=done.put)

    def collect(timeout_s: float) -> list[RunRecord] | None:
        try:
            out = done.get(timeout=timeout_s)
        except queue.Empty:
            return None
        if isinstance(out, BaseException):
            raise out
        return out

    try:
        yield from drive(source, n, submit, collect)
        pool.close()
    finally:
        pool.terminate()
        pool.join()


def run_ray(source: TaskSource, config: BenchConfig) -> Iterator[RunRecord]:
    """The runs on a Ray cluster (``config.address``; None starts a local Ray with
    ``config.workers`` CPUs, unless this process has started Ray already): one actor per
    worker (``config.workers``, default the cluster's CPUs), each with its own
    :class:`BenchWorker`. Needs ``pip install 'chekhov[ray]'``."""
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
        from chekhov.bench.ray_worker import RayWorker

        n_actors = config.workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
        n_actors = min(n_actors, source.left)
        actor_cls = ray.remote(num_cpus=1, runtime_env={"env_vars": _SINGLE_THREAD_ENV}
                               )(RayWorker)
        idle = [actor_cls.remote(config) for _ in range(n_actors)]
        actors = list(idle)
        pending: dict[Any, Any] = {}

        def submit(task: RunTask) -> None:
            actor = idle.pop()
            pending[actor.run.remote(task)] = actor

        def collect(timeout_s: float) -> list[RunRecord] | None:
            ready, _ = ray.wait(list(pending), num_returns=1, timeout=timeout_s)
            if not ready:
                return None
            idle.append(pending.pop(ready[0]))
            records: list[RunRecord] = ray.get(ready[0])
            return records

        yield from drive(source, n_actors, submit, collect)
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
