"""Where Roadmap + TrajOpt's time goes, stage by stage: one JSON object per scene and family.

    python benchmarks/stages.py [--json] [--scenes ...] [--family tasks] [--cases 40]
                                [--case-seed 3] [--time-limit 2] [--arm tiago]

Each case of the scene's cached case set (``chekhov.cases.cached_cases``) is planned once
(after three warm-up calls), and the ``StageReport`` times are summed per stage; ``--arm``
puts an arm of ``benchmarks/arms.py`` in the scene in place of its robot. Keys: scene,
family, arm, cases, ``mean_ms`` / ``median_ms`` (``result.time_s``), ``first_median_ms``
(``result.first_solution_s``), ``stage_ms_per_case`` (stage → mean ms a case, over all cases,
0 where a stage did not run), ``stage_runs`` (stage → how many cases ran it),
``certify_ms_per_case`` (the certification of offered paths, ``timing_s["offers"]`` and
``["certify"]``), ``route_check_ms_per_case`` (the roadmap route's own check before it is
offered, ``timing_s["route_check"]``), ``first_from_route`` (cases whose first answer was
the route itself), ``final_from`` (stage → cases whose final answer it gave),
``abandoned_runs`` (TrajOpt runs stopped as unable to beat the answer). Times are wall
times on this machine: compare them only within one run (alternate old and new code).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: idle BLAS threads would only spin

import argparse
import json
from collections import Counter, defaultdict
from typing import Any

import numpy as np

from chekhov import World, builtin_scenes, load_or_build_roadmap
from chekhov.cases import cached_cases
from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
from chekhov.planners.status import PlanStatus, Stage


def bench_scene(scene: str, family: str, n: int, seed: int, limit_s: float,
                arm: str | None = None) -> dict[str, Any]:
    if arm is None:
        world = World.load(scene)
    else:
        from arms import make_world  # this folder: run as a script

        world = make_world(arm, scene)
    planner = RoadmapTrajOpt(world, load_or_build_roadmap(world))
    cases = cached_cases(world, n, seed=seed, family=family)
    for i in range(min(3, len(cases))):   # load compiled kernels, fill caches
        planner.plan(cases.q_start[i], cases.goal(i), limit_s)
    stage_s: dict[str, float] = defaultdict(float)
    runs: Counter[str] = Counter()
    final: Counter[str] = Counter()
    total, first, certify, route, abandoned = [], [], [], [], 0
    from_route = 0
    for i in range(len(cases)):
        r = planner.plan(cases.q_start[i], cases.goal(i), limit_s)
        total.append(r.time_s)
        if r.success:
            first.append(r.first_solution_s)
            final[r.solutions[-1].stage.value] += 1
            from_route += r.solutions[0].stage is Stage.ROADMAP_SEED
        for s in r.stages:
            stage_s[s.stage.value] += s.time_s
            abandoned += s.status is PlanStatus.ABANDONED
        runs.update({s.stage.value for s in r.stages})
        certify.append(r.timing_s.get("offers", 0.0) + r.timing_s.get("certify", 0.0))
        route.append(r.timing_s.get("route_check", 0.0))
    k = len(cases)
    return {"scene": scene, "family": family, "arm": arm, "cases": k,
            "mean_ms": round(float(np.mean(total)) * 1e3, 2),
            "median_ms": round(float(np.median(total)) * 1e3, 2),
            "first_median_ms": round(float(np.median(first)) * 1e3, 2) if first else None,
            "stage_ms_per_case": {s: round(v / k * 1e3, 2) for s, v in stage_s.items()},
            "stage_runs": dict(runs),
            "certify_ms_per_case": round(float(np.mean(certify)) * 1e3, 2),
            "route_check_ms_per_case": round(float(np.mean(route)) * 1e3, 2),
            "first_from_route": from_route,
            "final_from": dict(final), "abandoned_runs": abandoned}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="*", default=list(builtin_scenes()))
    ap.add_argument("--family", choices=["random", "tasks"], default="tasks")
    ap.add_argument("--cases", type=int, default=40)
    ap.add_argument("--case-seed", type=int, default=3)
    ap.add_argument("--time-limit", type=float, default=2.0, help="s per plan call")
    ap.add_argument("--arm", default=None,
                    help="an arm of benchmarks/arms.py in place of the scene's robot")
    ap.add_argument("--json", action="store_true", help="JSON lines only")
    args = ap.parse_args()
    for scene in args.scenes:
        row = bench_scene(scene, args.family, args.cases, args.case_seed, args.time_limit,
                          args.arm)
        print(json.dumps(row) if args.json else
              "  ".join(f"{k}={v}" for k, v in row.items()), flush=True)


if __name__ == "__main__":
    main()
