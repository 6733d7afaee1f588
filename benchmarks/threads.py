"""Planning on a thread beside a real-time control loop, and two planners raced on two cores,
one JSON object per scene.

    python benchmarks/threads.py [--json] [--scenes ...] [--cases 20] [--seconds 3]

Keys: scene; ``tick_late_ms_p50`` / ``_p99`` / ``_max``: how late a 100 Hz loop's ticks come
(the loop sleeps to each tick, then samples a timed trajectory: the executive's own work) while
Roadmap + TrajOpt plans pick-and-place task cases back to back on a second thread, and
``idle_tick_late_ms_p99`` with nothing planning; ``plans_beside``: how many plans the thread
finished meanwhile; ``first_alone_ms_p50`` / ``_p95``: Roadmap + TrajOpt's first certified
answer alone, and ``first_raced_ms_p50`` / ``_p95``: the first certified answer of Roadmap +
TrajOpt and straight-line TrajOpt started together on two threads (each in its own World),
over the same task cases; ``raced_won_by_line``: how often the straight line came first.

Numba kernels that hold the GIL stall the loop for as long as they run, and a race on two
threads then runs one planner at a time (issues 16 and 18).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import json
import threading
import time
from collections.abc import Callable

import numpy as np

from chekhov import World
from chekhov.bench.solvability import cached_solvable_cases
from chekhov.cases import CaseSet
from chekhov.planners.base import Planner
from chekhov.planners.registry import make_planner
from chekhov.roadmap.io import load_or_build_roadmap

TICK_S = 0.01


def tick_lateness(seconds: float, work: Callable[[], None] | None) -> tuple[list[float], int]:
    """Lateness (ms) of each tick of a 100 Hz loop over ``seconds`` while ``work`` runs over
    and over on another thread (None: nothing else runs); and how many times it ran."""
    stop = threading.Event()
    done = [0]

    def background() -> None:
        while not stop.is_set():
            assert work is not None
            work()
            done[0] += 1
    thread = threading.Thread(target=background) if work is not None else None
    if thread is not None:
        thread.start()
    late = []
    t_next = time.perf_counter()
    q = np.zeros(7)
    for _ in range(int(seconds / TICK_S)):
        t_next += TICK_S
        time.sleep(max(0.0, t_next - time.perf_counter()))
        late.append(1000 * (time.perf_counter() - t_next))
        q = np.sin(q + 0.01)           # a control step's own (small) work
    stop.set()
    if thread is not None:
        thread.join()
    return late, done[0]


def first_answer_s(planner: Planner, cases: CaseSet, i: int, t0: float) -> float:
    """s from t0 to the planner's first certified answer to case i (inf: none)."""
    first = [float("inf")]

    def heard(_solution: object) -> None:
        first[0] = min(first[0], time.perf_counter() - t0)
    planner.plan(cases.q_start[i], cases.goal(i), 1.0, on_solution=heard)
    return first[0]


def race(a: Planner, b: Planner, cases: CaseSet, i: int) -> tuple[float, bool]:
    """The first certified answer (s) of a and b started together on two threads, and whether
    b's came first."""
    out = [float("inf"), float("inf")]
    t0 = time.perf_counter()

    def run(k: int, p: Planner) -> None:
        out[k] = first_answer_s(p, cases, i, t0)
    threads = [threading.Thread(target=run, args=(k, p)) for k, p in enumerate((a, b))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return min(out), out[1] < out[0]


def bench_scene(scene: str, n_cases: int, seconds: float) -> dict[str, float | int | str]:
    worlds = [World.load(scene), World.load(scene)]
    roadmap = load_or_build_roadmap(worlds[0])
    rt = make_planner("Roadmap+TrajOpt", worlds[0], roadmap)
    line = make_planner("TrajOpt", worlds[1])
    cases = cached_solvable_cases(worlds[0], max(n_cases, 2), 0, family="tasks").head(n_cases)
    for p in (rt, line):                       # compiled and warm
        p.plan(cases.q_start[0], cases.goal(0), 1.0)
    k = [0]

    def plan_next() -> None:
        i = k[0] % len(cases)
        k[0] += 1
        rt.plan(cases.q_start[i], cases.goal(i), 0.5)
    idle, _ = tick_lateness(seconds, None)
    busy, plans = tick_lateness(seconds, plan_next)
    alone = [first_answer_s(rt, cases, i, time.perf_counter()) for i in range(len(cases))]
    raced = [race(rt, line, cases, i) for i in range(len(cases))]
    ms = [1000 * r[0] for r in raced]
    a_ms = [1000 * x for x in alone]
    return {
        "scene": scene,
        "tick_late_ms_p50": float(np.percentile(busy, 50)),
        "tick_late_ms_p99": float(np.percentile(busy, 99)),
        "tick_late_ms_max": float(np.max(busy)),
        "idle_tick_late_ms_p99": float(np.percentile(idle, 99)),
        "plans_beside": plans,
        "first_alone_ms_p50": float(np.percentile(a_ms, 50)),
        "first_alone_ms_p95": float(np.percentile(a_ms, 95)),
        "first_raced_ms_p50": float(np.percentile(ms, 50)),
        "first_raced_ms_p95": float(np.percentile(ms, 95)),
        "raced_won_by_line": int(sum(r[1] for r in raced)),
        "cases": len(cases),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=["tabletop_pole", "shelf_boxes",
                                                    "panda_cage"])
    ap.add_argument("--cases", type=int, default=20)
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    for scene in args.scenes:
        row = bench_scene(scene, args.cases, args.seconds)
        print(json.dumps(row) if args.json else
              "  ".join(f"{k}={v:.2f}" if isinstance(v, float) else f"{k}={v}"
                        for k, v in row.items()), flush=True)


if __name__ == "__main__":
    main()
