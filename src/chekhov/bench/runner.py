"""The benchmark runner: every selected planner on the same cases of every scene, results into
a :class:`~chekhov.bench.database.BenchDatabase`, resumable.

    from chekhov.bench.runner import run_benchmark
    from chekhov.bench.config import BenchConfig
    out = run_benchmark(BenchConfig(("tabletop_pole",), ("Roadmap+TrajOpt", "TrajOpt"),
                                    n_cases=20, time_limit_s=2.0), "bench.db")

Flow: the main process loads each scene, its cases of each family in ``config.families``
(``cached_solvable_cases`` or a case file; each (scene, family) is one experiment, its
``family`` column saying which) and, for Roadmap+TrajOpt, its roadmap (built and saved once,
before any worker starts, so workers only load it); it records each planner's configuration
(plannerConfigs) and skips the (scene, family, planner, case) runs the database already holds —
checking that a stored run was made on the same case (content hash). The remaining runs go to
the executor (local processes by default, or Ray), each claimed in the database just before it
starts, so that runners sharing the database split the work (:mod:`chekhov.bench.claims`). Each
finished run is written in its own transaction as it arrives, with its time added to its
experiment's ``totaltime``, so an interruption — even SIGKILL — loses nothing already written.
A case that cannot be run is recorded as that run's failure (:meth:`BenchWorker.run_all`) and
logged. Where X and X+TrajOpt both run on a case, one run serves both
(:func:`share_seed_runs`).
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import platform
import socket
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from chekhov.bench.claims import ClaimedTasks, Key, Session
from chekhov.bench.config import BenchConfig
from chekhov.bench.database import BenchDatabase
from chekhov.bench.executors import run_tasks
from chekhov.bench.progress import ProgressBar
from chekhov.bench.record import RUN_ERRORS
from chekhov.bench.registry import (
    PlannerSpec,
    planner_settings,
    seed_planner_name,
    settings_text,
    uses_roadmap,
)
from chekhov.bench.solvability import cached_solvable_cases
from chekhov.bench.task import RunTask, case_hash
from chekhov.bench.worker import load_roadmap_for
from chekhov.cases import CaseSet
from chekhov.errors import BenchError, ChekhovError
from chekhov.roadmap.graph import Roadmap
from chekhov.world import World

_log = logging.getLogger(__name__)

# s without a heartbeat after which a runner's claims are void (plus 3 time limits: one run
# of the in-process executor goes between two heartbeats)
STALE_AFTER_S = 60.0


@dataclass(frozen=True)
class BenchOutcome:
    """What :func:`run_benchmark` did.

    Attributes:
        db_path: the database. experiment_ids: (scene, experiments.id) of every experiment
            (one per scene and case family; ``experiment_families`` says which).
        planned: runs selected in all; skipped: already in the database at the start; ran:
            run and written by this call; by_others: written meanwhile by another runner on
            the same database (not run here). When the call completes, planned = skipped +
            ran + by_others.
        time_s: s, wall time of the call. workers: processes or actors used.
    """

    db_path: str
    experiment_ids: tuple[tuple[str, int], ...]
    planned: int
    skipped: int
    ran: int
    time_s: float
    workers: int
    by_others: int = 0
    experiment_families: tuple[tuple[str, str, int], ...] = ()

    def experiment_id(self, scene: str, family: str = "random") -> int:
        """experiments.id of ``scene`` and case ``family``."""
        return {(s, f): e for s, f, e in self.experiment_families}[(scene, family)]


@dataclass
class _Plan:
    """The runs still to do: experiments by (scene, family), planner configs by scene, tasks
    in any order."""

    exp_ids: dict[tuple[str, str], int] = field(default_factory=dict)
    planner_ids: dict[tuple[str, str], int] = field(default_factory=dict)
    tasks: list[RunTask] = field(default_factory=list)
    skipped: int = 0
    progress: bool = True     # draw the progress of the work before the runs too


def load_cases(world: World, config: BenchConfig, family: str = "random", *,
               progress: bool = False) -> tuple[CaseSet, str]:
    """The first ``config.n_cases`` cases of the scene's ``family`` and a description of their
    source (naming the solvability pass's planner: a database written with the timed pass
    before session 38 starts new experiments, as its cases may differ). ``progress``: a bar
    for a solvability pass not cached yet (500 task cases take minutes)."""
    files = [CaseSet.load(p, world) for p in config.case_files_of(world.scene.name)]
    found = [(p, c) for p, c in zip(config.case_files_of(world.scene.name), files,
                                    strict=True) if c.family == family]
    if not found:
        bar = ProgressBar(config.n_cases, f"cases {world.scene.name} {family}",
                          enabled=progress, count_failures=False)
        cases = cached_solvable_cases(world, config.n_cases, config.case_seed, family=family,
                                      progress=lambda done, total: bar.update())
        if bar.done:         # a pass ran (none when the cases were cached)
            bar.close()
        kind = "" if family == "random" else f"{family} cases, "
        return (cases, f"generated ({kind}seed {config.case_seed}, solvability pass by "
                       f"{cases.solvability or 'an unrecorded planner'}: {cases.replaced} "
                       "replaced)")
    path, cases = found[0]
    if len(cases) < config.n_cases:
        raise ChekhovError(f"{path}: {len(cases)} cases, --cases asks for {config.n_cases}")
    return (cases.head(config.n_cases),
            f"file {Path(path).name} (seed {cases.seed}, {cases.replaced} replaced)")


def run_benchmark(config: BenchConfig, db_path: str | Path, progress: bool = True
                  ) -> BenchOutcome:
    """Run what ``config`` selects into the database at ``db_path`` (see the module doc)."""
    t0 = time.perf_counter()
    db_path = Path(db_path)
    with BenchDatabase(db_path, config.db_lock_timeout_s) as db:
        plan = _Plan(progress=progress)
        for scene in config.scenes:
            _plan_scene(db, db_path, config, scene, plan)
        # case-major order: every scene and planner advances together, so an interrupted
        # benchmark has comparable data and the ETA is representative
        tasks = sorted(plan.tasks, key=lambda t: (t.case_index, config.scenes.index(t.scene),
                                                  config.families.index(t.family),
                                                  config.planners.index(t.planner)))
        n_runs = len(tasks)
        if config.share_seed_runs:
            tasks = share_seed_runs(tasks)
        workers = config.local_workers if config.executor == "local" else (config.workers or 0)
        ran, by_others = _execute(db, config, plan, tasks, n_runs, progress)
    return BenchOutcome(str(db_path), tuple((s, e) for (s, _), e in plan.exp_ids.items()),
                        n_runs + plan.skipped, plan.skipped, ran, time.perf_counter() - t0,
                        workers, by_others,
                        tuple((s, f, e) for (s, f), e in plan.exp_ids.items()))


def _plan_scene(db: BenchDatabase, db_path: Path, config: BenchConfig, scene: str,
                plan: _Plan) -> None:
    """Record the scene's experiment and planner configs in ``plan`` and add the runs the
    database does not hold yet to ``plan.tasks`` (a stored run must be of the same case)."""
    world = World.load(scene)
    roadmap = (load_roadmap_for(world, config)
               if any(uses_roadmap(n) for n in config.planners) else None)

    def get_roadmap() -> Roadmap:
        if roadmap is None:  # pragma: no cover - loaded whenever Roadmap+TrajOpt runs
            raise ChekhovError("internal: no roadmap loaded")
        return roadmap

    for name in config.planners:
        spec = PlannerSpec(name, config.resolution, config.planner_seed)
        planner = spec.build(world, get_roadmap)
        pid = db.planner_id(name, settings_text(planner_settings(spec, planner, roadmap)))
        plan.planner_ids[(scene, name)] = pid
    for family in config.families:
        _plan_family(db, db_path, config, world, scene, family, plan)


def _plan_family(db: BenchDatabase, db_path: Path, config: BenchConfig, world: World,
                 scene: str, family: str, plan: _Plan) -> None:
    """The experiment of (scene, family) and its runs not stored yet (see _plan_scene)."""
    cases, source = load_cases(world, config, family, progress=plan.progress)
    setup = {"scene": world.scene.name, "robot": world.robot.name,
             "cases": source, "time_limit_s": config.time_limit_s,
             "resolution_rad": config.resolution, "exact_substeps": config.exact_substeps}
    if family != "random":   # the random family's setup text is as before the families
        setup["family"] = family
    eid = db.experiment_id(
        world.scene.name, world.scene.content_hash(), config.case_seed, source,
        config.time_limit_s, config.exact_substeps, config.resolution,
        setup=json.dumps(setup), version=_version(), hostname=socket.gethostname(),
        cpuinfo=_cpuinfo(), family=family)
    db.set_runcount(eid, config.n_cases)
    plan.exp_ids[(scene, family)] = eid
    hashes = [case_hash(cases.q_start[i], cases.T_world_ee_goal[i]) for i in range(len(cases))]
    for name in config.planners:
        done = db.done_cases(eid, plan.planner_ids[(scene, name)])
        for i in range(len(cases)):
            if i in done:
                if done[i] != hashes[i]:
                    raise ChekhovError(
                        f"{db_path}: the run of {name} on case {i} of '{scene}' ({family} "
                        f"cases) was made on another case (hash {done[i]}, now "
                        f"{hashes[i]}); use another --db file")
                plan.skipped += 1
                continue
            plan.tasks.append(RunTask(scene, name, i, cases.q_start[i],
                                      cases.T_world_ee_goal[i], config.time_limit_s,
                                      _run_seed(config.planner_seed, i), family=family))


def _execute(db: BenchDatabase, config: BenchConfig, plan: _Plan, tasks: list[RunTask],
             n_runs: int, progress: bool) -> tuple[int, int]:
    """Run ``tasks``, each claimed as it starts, and write every record as it arrives with its
    time added to its experiment's ``totaltime``; returns (runs written, runs found written
    by another runner)."""
    def keys(t: RunTask) -> list[Key]:
        eid = plan.exp_ids[(t.scene, t.family)]
        out = [(eid, plan.planner_ids[(t.scene, t.planner)], t.case_index)]
        base = seed_planner_name(t.planner)
        if t.records_seed_run and base is not None:
            out.append((eid, plan.planner_ids[(t.scene, base)], t.case_index))
        return out

    session = Session(db, stale_after_s=STALE_AFTER_S + 3 * config.time_limit_s)
    source = ClaimedTasks(session, tasks, keys)
    bar = ProgressBar(n_runs, label=f"bench ({n_runs} runs, {plan.skipped} done before)",
                      enabled=progress)
    ran = lost = seen = 0
    try:
        for rec in run_tasks(source, config):
            if rec.status in RUN_ERRORS:
                _log.warning("bench: %s on case %d of '%s' could not be run (%s in stage "
                             "%s): %s; recorded as that run's failure", rec.planner,
                             rec.case_index, rec.scene, rec.status, rec.info["stage"],
                             rec.info.get("error"))
            shared = rec.seed_stage_of is not None  # its planning time is counted once
            seconds = (0.0 if shared else rec.time_s) + rec.exact_check_s
            pid = plan.planner_ids[(rec.scene, rec.planner)]
            if db.insert_run(plan.exp_ids[(rec.scene, rec.family)], pid, rec,
                             seconds) is None:
                lost += 1   # another runner took this run over and wrote it first
            else:
                ran += 1
            bar.update(failed=not rec.success)
            if source.by_others > seen:   # runs other runners wrote count as progress too
                bar.update(source.by_others - seen)
                seen = source.by_others
    finally:
        bar.close()
        with contextlib.suppress(BenchError):   # a dead session's claims are void anyway
            session.close()
    return ran, lost + source.by_others


def share_seed_runs(tasks: list[RunTask]) -> list[RunTask]:
    """``tasks`` with each X run dropped where X+TrajOpt runs on the same case, that run then
    recording its seed stage as X's run (``RunTask.records_seed_run``). Order kept."""
    keys = {t.key for t in tasks}
    out: list[RunTask] = []
    for t in tasks:
        base = seed_planner_name(t.planner)
        if base is not None and (t.scene, t.family, base, t.case_index) in keys:
            out.append(replace(t, records_seed_run=True))
        elif (t.scene, t.family, f"{t.planner}+TrajOpt", t.case_index) not in keys \
                or seed_planner_name(f"{t.planner}+TrajOpt") is None:
            out.append(t)
    return out


def _run_seed(base: int, case_index: int) -> int:
    """Per-run seed: the same for a case wherever and whenever it runs."""
    return (int(base) * 1_000_003 + int(case_index)) % (2**63)


def _version() -> str:
    try:
        from importlib.metadata import version
        return f"chekhov {version('chekhov')}"
    except Exception:  # pragma: no cover
        return "chekhov"


def _cpuinfo() -> str:
    return f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, " \
           f"{platform.platform()}"
