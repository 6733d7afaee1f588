"""A benchmark worker: builds each world and planner once, runs tasks, re-checks every returned
path with the exact checker. One per process (local executor) or Ray actor."""

from __future__ import annotations

import contextlib
import os
import socket
import time
import traceback
from dataclasses import replace
from typing import Any

import numpy as np

from chekhov._heap import settle_heap
from chekhov.bench.config import BenchConfig
from chekhov.bench.record import RunRecord
from chekhov.bench.registry import PlannerSpec, seed_planner_name
from chekhov.bench.task import RunTask
from chekhov.errors import ChekhovError, TrajectoryError
from chekhov.planners.base import Planner, PlanResult, path_length
from chekhov.planners.status import PlanStatus, Stage, scalar_items
from chekhov.planners.timed import timed_trajectory
from chekhov.roadmap.graph import Roadmap
from chekhov.robot.goal import Goal
from chekhov.world import World

WARM_UP_LIMIT_S = 0.5


class BenchWorker:
    """Runs :class:`RunTask` s for one :class:`BenchConfig`; caches worlds, roadmaps and
    planners by scene (built on first use, never shared between processes). With
    ``config.warm_up`` each planner first plans its first task once, untimed and discarded,
    with a limit of at most ``WARM_UP_LIMIT_S`` s (numba caches, first-call setup), and the
    objects then alive are frozen out of the garbage collector's way (``_heap.settle_heap``)."""

    def __init__(self, config: BenchConfig) -> None:
        self.config = config
        self.worlds: dict[str, World] = {}
        self.roadmaps: dict[str, Roadmap] = {}
        self.planners: dict[tuple[str, str], Planner] = {}
        self.warm: set[tuple[str, str]] = set()
        self.name = f"{socket.gethostname()}:{os.getpid()}"

    def world(self, scene: str) -> World:
        w = self.worlds.get(scene)
        if w is None:
            w = World.load(scene)
            w.fast  # noqa: B018 - build the checkers before any run is timed
            w.exact  # noqa: B018
            self.worlds[scene] = w
        return w

    def roadmap(self, scene: str) -> Roadmap:
        r = self.roadmaps.get(scene)
        if r is None:
            r = load_roadmap_for(self.world(scene), self.config)
            self.roadmaps[scene] = r
        return r

    def planner(self, scene: str, name: str) -> Planner:
        p = self.planners.get((scene, name))
        if p is None:
            spec = PlannerSpec(name, self.config.resolution, self.config.planner_seed)
            p = spec.build(self.world(scene), lambda: self.roadmap(scene))
            self.planners[(scene, name)] = p
        return p

    def run(self, task: RunTask) -> RunRecord:
        """Run one task. A case that cannot be run yields a failure record (see
        :meth:`run_all`)."""
        return self.run_all(task)[0]

    def run_all(self, task: RunTask) -> list[RunRecord]:
        """Run one task: its record, then (``task.records_seed_run``) the record of its seed
        stage as the seed planner's own run.

        Anything raised while running this case — a malformed case (a non-finite goal pose),
        a planner refusing the query, an exception in planning or in the exact check — is that
        run's failure, not the end of the benchmark: status "case_error" for a
        :class:`ChekhovError`, "crash" for any other exception, with ``info`` naming the
        scene, planner, case index and stage ("goal", "plan", "check") and the error text.
        Building the world or the planner is not part of a case: its errors propagate."""
        world = self.world(task.scene)
        planner = self.planner(task.scene, task.planner)
        stage, t0 = "goal", time.perf_counter()
        try:
            goal = Goal.pose(np.asarray(task.T_world_ee_goal, dtype=float))
            q0 = np.asarray(task.q_start, dtype=float)
            stage = "plan"
            if self.config.warm_up and (task.scene, task.planner) not in self.warm:
                # first call of a planner in a process: JIT loading, caches; not timed
                self.warm.add((task.scene, task.planner))
                with contextlib.suppress(Exception):  # the timed run reports any error
                    planner.plan(q0, goal, min(task.time_limit_s, WARM_UP_LIMIT_S))
                settle_heap()   # the worker's long-lived state out of the collector's way
            reseed(planner, task.seed)
            t0 = time.perf_counter()
            r = planner.plan(q0, goal, task.time_limit_s)
            stage = "check"
            records = [self._record(world, task, task.planner, r)]
            seed_run = getattr(planner, "last_seed_result", None)
            base = seed_planner_name(task.planner)
            if task.records_seed_run and base is not None and seed_run is not None:
                records.append(replace(self._record(world, task, base, seed_run,
                                                    {"seed_stage_of": task.planner}),
                                       seed_stage_of=task.planner))
            return records
        except Exception as e:  # one bad case is a result, not the end of the benchmark
            return self._failed(task, stage, e,
                                0.0 if stage == "goal" else time.perf_counter() - t0)

    def _failed(self, task: RunTask, stage: str, e: Exception, time_s: float
                ) -> list[RunRecord]:
        """The failure records of ``task`` (and of its seed stage's planner, when it records
        that run too) for the error ``e`` raised in ``stage``."""
        status = "case_error" if isinstance(e, ChekhovError) else "crash"
        info: dict[str, object] = {
            "error": f"{type(e).__name__}: {e}", "stage": stage, "scene": task.scene,
            "case_index": task.case_index, "traceback": traceback.format_exc(limit=4)}
        names = [task.planner]
        base = seed_planner_name(task.planner)
        if task.records_seed_run and base is not None:
            names.append(base)
        shared = [{}, {"seed_stage_of": task.planner}]   # its time is counted once
        return [RunRecord(task.scene, name, task.case_index, task.case_hash, solved=False,
                          status=status, time_s=time_s,
                          info={**info, "planner": name, **extra}, worker=self.name,
                          seed_stage_of=extra.get("seed_stage_of"), family=task.family)
                for name, extra in zip(names, shared, strict=False)]

    def _record(self, world: World, task: RunTask, name: str, r: PlanResult,
                extra_info: dict[str, object] | None = None) -> RunRecord:
        """The record of ``r`` (planner ``name``), its path checked by the exact checker."""
        path = np.asarray(r.path, dtype=float) if r.success and r.path is not None else None
        exact_valid: bool | None = None
        t1 = time.perf_counter()
        if path is not None:
            exact_valid = bool(world.exact.path_valid(path, substeps=self.config.exact_substeps))
        exact_s = time.perf_counter() - t1
        timed: dict[str, object] = {}
        if path is not None and exact_valid:   # the motion's duration, outside the run's time
            if r.trajectory is not None:        # the planner timed it (default TimingConfig)
                timed = {"duration_s": r.trajectory.duration,
                         "timing_method": str(r.info.get("timing_method", ""))}
            else:
                try:
                    t = timed_trajectory(world, path)
                    timed = {"duration_s": t.trajectory.duration, "timing_method": t.method}
                except TrajectoryError as e:
                    timed = {"timing_error": str(e)}
        seed_path, seed_found = _seed_of(r)
        seed_time = float(r.timing_s["seed"]) if "seed" in r.timing_s else float("nan")
        # TrajOpt's own status string ("converged", "exact_clear", …): the typed result has
        # only its PlanStatus, so the string is still read from info (recorded, not acted on)
        trajopt_status = r.info.get("trajopt_status")
        return RunRecord(
            scene=task.scene, planner=name, case_index=task.case_index,
            case_hash=task.case_hash, solved=path is not None, status=r.status,
            time_s=float(r.time_s), timing_s={k: float(v) for k, v in r.timing_s.items()},
            path=path, path_length=path_length(path) if path is not None else float("nan"),
            exact_valid=exact_valid, exact_check_s=exact_s, seed_path=seed_path,
            seed_length=path_length(seed_path) if seed_path is not None else float("nan"),
            seed_time_s=seed_time, seed_found=seed_found,
            trajopt_status=str(trajopt_status) if trajopt_status is not None else None,
            fallback_to_seed=r.fell_back_to_seed,
            info={**scalar_items(r.info), **timed, **(extra_info or {}),
                  **({"first_solution_s": r.first_solution_s} if path is not None else {})},
            worker=self.name, family=task.family)


def load_roadmap_for(world: World, config: BenchConfig) -> Roadmap:
    """The roadmap of ``world`` for ``config`` (loaded, or built and saved once)."""
    from pathlib import Path

    from chekhov.roadmap.io import load_or_build_roadmap

    path = (Path(config.roadmap_dir) / f"{world.scene.name}.npz"
            if config.roadmap_dir is not None else None)
    return load_or_build_roadmap(world, config.roadmap_config, path)


def reseed(planner: Any, seed: int) -> None:
    """Give the planner (and a seed planner inside it) fresh random streams for this run, so a
    run's outcome does not depend on which worker ran which runs before. OMPL's own sampler
    is process-global and not reseeded."""
    for p in (planner, getattr(planner, "seed_planner", None)):
        if p is not None and isinstance(getattr(p, "rng", None), np.random.Generator):
            p.rng = np.random.default_rng(seed)


def _seed_of(r: PlanResult) -> tuple[np.ndarray | None, bool | None]:
    """The seed path worth storing and whether the seed stage found one (None: the planner
    has no seed stage). A roadmap's or another planner's seed is that stage's own path; a
    straight-line TrajOpt's, the line it started from."""
    if r.seed_from is None:
        return None, None
    report = r.seed_report
    if r.seed_from in (Stage.ROADMAP_SEED, Stage.SEED):
        if report is None or report.path is None or report.status != PlanStatus.SOLVED:
            return None, False
        return np.asarray(report.path, dtype=float), True
    return (None, False) if r.seed is None else (np.asarray(r.seed, dtype=float), True)
