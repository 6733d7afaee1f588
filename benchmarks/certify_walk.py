"""How hard the certification's fast walk works on Roadmap + TrajOpt's first answers: one JSON
object per scene and family.

    python benchmarks/certify_walk.py [--scenes ...] [--family tasks] [--cases 40]
                                      [--case-seed 3]

For each case of the scene's cached case set, the first answer is made as ``plan()`` makes it
(roadmap seed, shortcut) and its certification — ``exact_path_decision`` on the path resampled
at 0.16 rad, 100 substeps a segment — is timed (median of 3), and so is the compiled walk alone
over the same samples with the same margins (``first_dense_collision``, resumed after each
alarm). ``visits`` is how many configurations the walk looks at (those its clearance
certificates do not cover) on the paths it passes without an alarm: the smallest budget with
which one call of the walk finishes (found by bisection, since a compiled call cannot count
for us). Keys: scene, family, paths, ``segments_median`` (after resampling),
``decision_ms_median`` / ``_mean``, ``walk_ms_median`` / ``_mean``, ``alarm_free_paths``,
``visits_median``, ``samples_per_visit_median`` (the path's samples over its visits: how much
the certificates skip), ``us_per_visit_median`` (the walk's time over its visits). Times are
wall times on this machine: compare them only within one run.

Measured (2026-11-28, task cases, 40 a scene): the walk is 80-99% of the decision
(tabletop_container median 1.5 of 1.9 ms, panda_cage 1.9 of 1.9 ms); with the lever bounds
alone it looked at 1 sample in 4.5 and in 2.9 (575 and 670 visits a path, ~2 µs each), with
each configuration's own distances to the joint axes (``motion_bounds.clear_for``) 1 in 8.5
and in 4.9 (365 and 432; shelf_boxes 1759 → 1134, kitchen 1854 → 1142, panda_table_shelf
789 → 469). This machine's timings varied by up to 2x from run to run here: compare old and
new alternating, several times. Tried and not kept for these long segments: carrying the
certificates from one segment to the next (more visits: they then run out one at a time
instead of together at each segment's start; 2026-11-29, with runs of segments as the timed
arcs now use them (``walk_runs.run_end``) but uncapped: visits 971 → 1814 a path on
shelf_boxes, 232 → 716 on tabletop_container, the walk 4-11% slower) and, with it,
renewing those about to run out whenever one configuration is looked at (26% fewer visits,
the same time: each visit then renews more); one walk call for the whole path instead of 8
segments a call (tabletop 5-9% faster, panda_cage no faster; since 2026-11-29 a call takes
64, ``path_check.CHUNK_SEGMENTS``, for the timed arcs' sake).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import json
import time
from typing import Any

import numpy as np

from chekhov import World, builtin_scenes, load_or_build_roadmap
from chekhov.cases import cached_cases
from chekhov.collision import dense_path
from chekhov.collision.path_check import (
    CERTIFY_MAX_SEGMENT_RAD,
    CERTIFY_SUBSTEPS,
    exact_path_decision,
    screen_margins,
)
from chekhov.paths import path_length, resample_path
from chekhov.planners.query import make_query
from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
from chekhov.planners.shortcut import shortcut_path

Array = np.ndarray


def first_answers(world: World, family: str, n: int, seed: int) -> list[Array]:
    """The resampled first answers (shortcut roadmap seeds) of the scene's cached cases."""
    planner = RoadmapTrajOpt(world, load_or_build_roadmap(world))
    cases = cached_cases(world, n, seed=seed, family=family)
    out = []
    for i in range(len(cases)):
        query = make_query(world.robot, cases.q_start[i], cases.goal(i), 2.0)
        found = planner.seeder.seeds(query.q_start, query.goal, 1, deadline=query.deadline)
        paths = [f.path for f in found if f.path is not None]
        if paths:
            best = min((shortcut_path(world.fast, p, deadline=query.deadline) for p in paths),
                       key=path_length)
            out.append(resample_path(best, CERTIFY_MAX_SEGMENT_RAD))
    return out


def walk(world: World, P: Array, visits: int = dense_path.NO_BUDGET) -> tuple[int, bool]:
    """The certification's walk over P's samples, resumed after each alarm: (calls, finished
    within ``visits`` a call)."""
    fast = world.fast
    pad, grow = screen_margins(fast, world.exact, P, CERTIFY_SUBSTEPS)
    size = (len(P) - 1) * (CERTIFY_SUBSTEPS + 1) + 1
    start = calls = 0
    while True:
        i, resume = fast.run_kernel(dense_path.first_dense_collision, P, CERTIFY_SUBSTEPS,
                                    start, visits, pad, grow)
        calls += 1
        if resume >= 0:
            return calls, False
        if i < 0 or i + 1 >= size:
            return calls, True
        start = int(i) + 1


def visits_needed(world: World, P: Array) -> int | None:
    """Configurations the walk looks at over P when no sample alarms (None: one does)."""
    if walk(world, P)[0] > 1:
        return None
    lo, hi = 1, 1 << 20
    while lo < hi:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if walk(world, P, mid)[1] else (mid + 1, hi)
    return lo


def timed(f: Any, repeats: int = 3) -> float:
    """Median wall time (s) of f()."""
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def bench_scene(scene: str, family: str, n: int, seed: int) -> dict[str, Any]:
    world = World.load(scene)
    paths = first_answers(world, family, n, seed)
    fast, exact = world.fast, world.exact
    for P in paths[:3]:   # load compiled kernels
        exact_path_decision(fast, exact, P, CERTIFY_SUBSTEPS)
    decide = [timed(lambda P=P: exact_path_decision(fast, exact, P, CERTIFY_SUBSTEPS))
              for P in paths]
    walks = [timed(lambda P=P: walk(world, P)) for P in paths]
    visits = [visits_needed(world, P) for P in paths]
    free = [(v, P, w) for v, P, w in zip(visits, paths, walks, strict=True) if v is not None]
    ms = 1e3
    return {"scene": scene, "family": family, "paths": len(paths),
            "segments_median": float(np.median([len(P) - 1 for P in paths])),
            "decision_ms_median": round(float(np.median(decide)) * ms, 3),
            "decision_ms_mean": round(float(np.mean(decide)) * ms, 3),
            "walk_ms_median": round(float(np.median(walks)) * ms, 3),
            "walk_ms_mean": round(float(np.mean(walks)) * ms, 3),
            "alarm_free_paths": len(free),
            "visits_median": float(np.median([v for v, _, _ in free])) if free else None,
            "samples_per_visit_median": round(float(np.median(
                [((len(P) - 1) * (CERTIFY_SUBSTEPS + 1) + 1) / v for v, P, _ in free])), 2)
            if free else None,
            "us_per_visit_median": round(float(np.median([w / v for v, _, w in free])) * 1e6, 2)
            if free else None}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=builtin_scenes())
    ap.add_argument("--family", default="tasks", choices=("tasks", "random"))
    ap.add_argument("--cases", type=int, default=40)
    ap.add_argument("--case-seed", type=int, default=3)
    args = ap.parse_args()
    for scene in args.scenes:
        print(json.dumps(bench_scene(scene, args.family, args.cases, args.case_seed)),
              flush=True)


if __name__ == "__main__":
    main()
