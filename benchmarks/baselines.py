"""Smoke figures for the baseline planners: a few cases per scene, a short time limit.

    python benchmarks/baselines.py --json                     # all scenes, 20 cases, 1 s
    python benchmarks/baselines.py --scenes tabletop_pole --planners RRTConnect LazyPRM --cases 5

Per scene and planner: cases, failure_rate, median_ms / mean_ms (wall time of ``plan``, IK
included; ``ik_ms`` its IK share), mean_path_length_rad (solved cases only), statuses. The cases
are ``generate_cases(world, N, seed)`` without a solvability pass. Every planner uses the fast
checker at the same resolution (0.02 rad); RRT* and PRM* run to the limit. Planners come from
the registry (``chekhov.planners.registry.make_planner``), as in ``chekhov bench``. Not the full
benchmark (that is ``chekhov bench``), a quick smoke figure.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: idle BLAS threads would only spin

import argparse
import json
import time
from collections import Counter
from functools import partial

import numpy as np

from chekhov.cases import generate_cases
from chekhov.errors import ChekhovError
from chekhov.planners.registry import canonical_planner_name, make_planner
from chekhov.roadmap.io import load_or_build_roadmap
from chekhov.scene.io import builtin_scenes
from chekhov.world import World

# the registry's sampling-based planners (chekhov.planners.registry); --planners takes any
# registry name or alias
ALL = ["RRTConnect", "RRT", "RRT*", "PRM*", "LazyPRM", "RRTConnect(deterministic)"]


def planner_name(text: str) -> str:
    """The registry name of ``text``, as an argparse type (an unknown name: exit status 2)."""
    try:
        return canonical_planner_name(text)
    except ChekhovError as e:
        raise argparse.ArgumentTypeError(str(e)) from e


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=builtin_scenes())
    ap.add_argument("--planners", nargs="+", default=ALL, type=planner_name,
                    help=f"registry planner names (default {' '.join(ALL)})")
    ap.add_argument("--cases", type=int, default=20)
    ap.add_argument("--time-limit", type=float, default=1.0, help="s per plan call")
    ap.add_argument("--resolution", type=float, default=0.02, help="rad")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", action="store_true", help="one JSON line per scene and planner")
    args = ap.parse_args()
    if not args.json:
        print(f"{'scene':20s} {'planner':20s} {'cases':>5s} {'fail':>6s} {'median ms':>10s} "
              f"{'mean ms':>9s} {'ik ms':>7s} {'length rad':>10s}")
    for scene in args.scenes:
        world = World.load(scene)
        world.fast  # noqa: B018 - build the checker before timing
        cases = generate_cases(world, args.cases, args.seed)
        for name in args.planners:
            planner = make_planner(name, world, partial(load_or_build_roadmap, world),
                                   resolution=args.resolution, seed=args.seed)
            times, ik, lengths, status = [], [], [], Counter()
            for i in range(len(cases)):
                r = planner.plan(cases.q_start[i], cases.goal(i), args.time_limit)
                times.append(r.time_s)
                ik.append(r.timing_s.get("ik", 0.0))
                status[r.status] += 1
                if r.success:
                    lengths.append(r.path_length)
            row = {"scene": scene, "planner": name, "cases": len(cases),
                   "failure_rate": 1.0 - len(lengths) / len(cases),
                   "median_ms": 1e3 * float(np.median(times)),
                   "mean_ms": 1e3 * float(np.mean(times)),
                   "ik_ms": 1e3 * float(np.mean(ik)),
                   "mean_path_length_rad": float(np.mean(lengths)) if lengths else None,
                   "time_limit_s": args.time_limit, "resolution_rad": args.resolution,
                   "statuses": dict(status), "when": time.strftime("%Y-%m-%dT%H:%M:%S")}
            if args.json:
                print(json.dumps(row), flush=True)
            else:
                length = row["mean_path_length_rad"]
                print(f"{scene:20s} {name:20s} {row['cases']:5d} {row['failure_rate']:6.1%} "
                      f"{row['median_ms']:10.1f} {row['mean_ms']:9.1f} {row['ik_ms']:7.1f} "
                      f"{length if length is None else round(length, 2)!s:>10s}", flush=True)


if __name__ == "__main__":
    main()
