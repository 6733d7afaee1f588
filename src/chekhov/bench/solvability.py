"""The paper's solvability pass: every case must be solved by at least one planner.

Each case is given to the planners in turn (start configuration, goal pose, ``time_limit_s``
each); a case none of them solves is replaced by a new sample of the same family
(:func:`chekhov.cases.draw_case`) — replacement ``a`` of case ``i`` comes from the stream
``default_rng([seed, i, a])``, so the candidates are deterministic — and
the new case is tried again, up to ``max_attempts`` replacements.

The default decider is :class:`~chekhov.planners.rrt_connect.DeterministicRRTConnect` with no time
limit: seeded samples, a node budget, answers certified like every planner's — so the cases
after the pass are a function of the scene, the family, ``n`` and the seed, on any machine.
(Deciding with OMPL's RRTConnect at 1 s, as before, replaced 3-4 different cases of 100 from
one fresh cache to the next: its clock and its once-per-process seed.) Planners given
explicitly run under ``time_limit_s`` (1 s unless given), and then which cases get replaced
depends on how fast the machine was: keep that file with the results (its ``replaced`` field
says how many were).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from chekhov.cases import (
    CaseSet,
    cache_stem,
    cached_cases,
    default_cache_dir,
    draw_case,
    find_cached,
)
from chekhov.planners.base import Planner
from chekhov.robot.goal import Goal
from chekhov.world import World


@dataclass(frozen=True, eq=False)
class SolvabilityReport:
    """What a solvability pass did.

    Attributes:
        cases: the cases after the pass (``cases.replaced`` includes this pass).
        replaced: how many replacements this pass made.
        replaced_indices: indices of the cases that were replaced (at least once).
        unsolved_indices: cases still unsolved after ``max_attempts`` replacements (kept).
        planners: names of the planners used. time_limit_s: their limit per case (s).
        time_s: wall time of the pass (s).
    """

    cases: CaseSet
    replaced: int
    replaced_indices: tuple[int, ...]
    unsolved_indices: tuple[int, ...]
    planners: tuple[str, ...]
    time_limit_s: float
    time_s: float


DEFAULT_PLANNER = "RRTConnect(deterministic)"
TIMED_LIMIT_S = 1.0
"""s per planner and case when planners are given and no limit is."""


def default_planners(world: World) -> list[Planner]:
    """The reproducible default: :data:`DEFAULT_PLANNER` (seeded, node-bounded)."""
    from chekhov.planners.registry import make_planner

    return [make_planner(DEFAULT_PLANNER, world)]


def solvability_pass(world: World, cases: CaseSet, planners: Sequence[Planner] | None = None,
                     time_limit_s: float | None = None, max_attempts: int = 20,
                     progress: Callable[[int, int], None] | None = None) -> SolvabilityReport:
    """Replace the cases that no planner solves within ``time_limit_s`` (s) by new samples.

    ``planners`` default to :func:`default_planners`; ``time_limit_s`` defaults to none (inf)
    for them and to :data:`TIMED_LIMIT_S` for planners given. ``progress(done, total)`` is
    called after each case.
    """
    cases.check_world(world)
    t0 = time.perf_counter()
    if time_limit_s is None:
        time_limit_s = math.inf if planners is None else TIMED_LIMIT_S
    planners = list(planners) if planners is not None else default_planners(world)
    q_start, q_goal = cases.q_start.copy(), cases.q_goal.copy()
    T_start, T_goal = cases.T_world_ee_start.copy(), cases.T_world_ee_goal.copy()
    starts, goals = list(cases.start_labels), list(cases.goal_labels)
    replaced, replaced_idx, unsolved = 0, [], []
    for i in range(len(cases)):
        attempt = 0
        while not _solved(planners, q_start[i], Goal.pose(T_goal[i]), time_limit_s):
            if attempt == max_attempts:
                unsolved.append(i)
                break
            attempt += 1
            d = draw_case(world, cases.family, cases.seed, i, attempt)
            q_start[i], q_goal[i], T_start[i], T_goal[i] = d.q_start, d.q_goal, d.T_start, \
                d.T_goal
            if cases.family == "tasks":
                starts[i], goals[i] = d.start_label, d.goal_label
            replaced += 1
        if attempt:
            replaced_idx.append(i)
        if progress is not None:
            progress(i + 1, len(cases))
    limit = "no time limit" if math.isinf(time_limit_s) else f"{time_limit_s:g} s each"
    decided = f"{', '.join(p.name for p in planners)}, {limit}"
    out = replace(cases, q_start=q_start, q_goal=q_goal, T_world_ee_start=T_start,
                  T_world_ee_goal=T_goal, replaced=cases.replaced + replaced,
                  start_labels=tuple(starts), goal_labels=tuple(goals),
                  solvability="; ".join(x for x in (cases.solvability, decided) if x))
    return SolvabilityReport(out, replaced, tuple(replaced_idx), tuple(unsolved),
                             tuple(p.name for p in planners), float(time_limit_s),
                             time.perf_counter() - t0)


def _solved(planners: Sequence[Planner], q_start: np.ndarray, goal: Goal,
            time_limit_s: float) -> bool:
    return any(p.plan(q_start, goal, time_limit_s).success for p in planners)


def cached_solvable_cases(world: World, n: int, seed: int = 0,
                          cache_dir: str | Path | None = None,
                          family: str = "random",
                          progress: Callable[[int, int], None] | None = None) -> CaseSet:
    """``cached_cases(world, n, seed, family=family)`` after a solvability pass with the
    default planner (:data:`DEFAULT_PLANNER`, deterministic), cached beside them
    (``{scene}-{hash[:12]}-{family}-s{seed}-solvable-deterministic-n{n}.npz``; the files of the
    earlier timed pass, ``-solvable-n{n}``, are not read): what ``chekhov bench`` uses when no
    case file is given, so no case that nothing solves counts against every planner.
    ``progress(done, total)``: after each case of a pass (none when the file is cached)."""
    d = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    stem = cache_stem(world, seed, "-solvable-deterministic", family)
    cases = find_cached(world, d, stem, n, family)
    if cases is None:
        cases = solvability_pass(world, cached_cases(world, n, seed, d, family),
                                 progress=progress).cases
        cases.save(d / f"{stem}-n{n}.npz")
    return cases
