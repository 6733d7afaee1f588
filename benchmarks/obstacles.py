"""Cost of updating many dynamic obstacles at once, one JSON object per scene.

    python benchmarks/obstacles.py [--json] [--scenes ...] [--n 20] [--repeats 20]

Keys: scene, n_obstacles, set_fast_ms / set_exact_ms (median ``set_obstacles`` of n random
boxes, spheres and cylinders in the fast / exact checker), one_by_one_ms (median of removing
and re-adding them one at a time with ``World.add_obstacle`` / ``remove_obstacle``, both
checkers: the old way). Targets (issue 14): set_fast_ms ≤ 1, set_exact_ms ≤ 5 for 20.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import json
import time

import numpy as np

from chekhov import Shape, World, builtin_scenes


def random_obstacles(rng: np.random.Generator, n: int) -> dict[str, tuple[Shape, np.ndarray]]:
    out = {}
    for i in range(n):
        T = np.eye(4)
        T[:3, 3] = rng.uniform([0.2, -0.8, 0.6], [1.2, 0.8, 1.6])
        kind = ("box", "sphere", "cylinder")[i % 3]
        size = {"box": (0.05, 0.05, 0.05), "sphere": (0.04,), "cylinder": (0.03, 0.2)}[kind]
        out[f"dyn{i}"] = (Shape(kind, size), T)
    return out


def bench_scene(scene: str, n: int, repeats: int) -> dict[str, float | int | str]:
    w = World.load(scene)
    rng = np.random.default_rng(0)
    sets = [random_obstacles(rng, n) for _ in range(repeats)]
    fast_ms, exact_ms, one_ms = [], [], []
    for obs in sets:
        t = time.perf_counter()
        w.fast.set_obstacles(obs)
        fast_ms.append((time.perf_counter() - t) * 1e3)
        t = time.perf_counter()
        w.exact.set_obstacles(obs)
        exact_ms.append((time.perf_counter() - t) * 1e3)
    w.set_obstacles({})
    for obs in sets[: max(3, repeats // 4)]:
        t = time.perf_counter()
        for name, (shape, T) in obs.items():
            w.add_obstacle(name, shape, T)
        for name in obs:
            w.remove_obstacle(name)
        one_ms.append((time.perf_counter() - t) * 1e3)
    return {"scene": scene, "n_obstacles": n,
            "set_fast_ms": round(float(np.median(fast_ms)), 3),
            "set_exact_ms": round(float(np.median(exact_ms)), 3),
            "one_by_one_ms": round(float(np.median(one_ms)), 3)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="*", default=list(builtin_scenes()))
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    for scene in args.scenes:
        row = bench_scene(scene, args.n, args.repeats)
        print(json.dumps(row) if args.json else "  ".join(f"{k}={v}" for k, v in row.items()))


if __name__ == "__main__":
    main()
