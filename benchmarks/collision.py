"""Collision checking and IK figures, one JSON object per robot and scene.

    python benchmarks/collision.py [--json] [--scenes ...] [--robot panda | --arm ur5]
                                   [--n 100000]

Keys: robot, scene, fast_checks_per_s (batched, one core; best of 3 passes over the
configurations, fast_checks_per_s_median the median pass), exact_checks_per_s,
fast_says_free_exact_says_collision (random configurations called free that the exact checker
calls colliding: must be 0), fast_false_alarm_rate (share of exactly-free random configurations
the fast checker calls colliding), fast_false_alarm_rate_near (the same among near-contact
configurations: exact clearance 0–20 mm), fast_says_free_exact_says_collision_near (the
near-contact configurations just past contact, penetration of a few mm, that the fast checker
calls free: must be 0), near_configs, exact_path_ms (a 30-waypoint path at 100 substeps),
ik_median_ms (per solution), fast_build_s, grid_mb.

Near-contact configurations: from an exactly free random configuration, a random joint-space
direction is followed in 0.1 rad steps until the exact checker reports a collision, then
bisected until the free end's exact distance (coal, every checked pair) is below a target drawn
uniformly in 0–20 mm; the free end is a near configuration, the colliding end a near-colliding
one. ``--robot panda`` places a Franka Panda in each scene where Baxter's left shoulder is
(at the height of Baxter's base, facing the same way) instead of the scene's robot; ``--arm
ur5`` (any arm of ``benchmarks/arms.py``, from the example-robot-data package) places that arm
where ``arms.py`` does, on the pole's table.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: idle BLAS threads would only spin

import argparse
import json
import time

import numpy as np
import pinocchio as pin

from chekhov import IKError, Robot, World, builtin_scenes, load_scene, solve_ik

NEAR_MAX = 0.02  # m: near-contact configurations have an exact clearance in [0, NEAR_MAX]
NEAR_BANDS = ((0.0, 0.002), (0.002, 0.005), (0.005, NEAR_MAX + 1e-12))  # m: reported apart


def make_world(scene_name: str, robot_name: str | None, arm: str | None = None) -> World:
    """The scene with its own robot, with ``robot_name`` mounted at Baxter's left shoulder, or
    with ``arm`` (``arms.ARMS``) where ``benchmarks/arms.py`` mounts it."""
    if arm is not None:
        from arms import make_world as arm_world  # this folder: run as a script

        return arm_world(arm, scene_name)
    scene = load_scene(scene_name)
    if robot_name is None:
        return World(scene)
    baxter = World(scene).robot
    T = baxter.T_world_base.copy()
    T[:2, 3] = baxter.compute_joint_placements(np.zeros(baxter.dof))[0][:2, 3]
    return World(scene, Robot.load(robot_name, T))


def exact_distance(w: World, gd: pin.GeometryData, q: np.ndarray) -> float:
    """Smallest coal distance (m) over the exact checker's collision pairs at q."""
    ex = w.exact
    i = pin.computeDistances(ex.model, ex.data, ex.geom_model, gd, q)
    return float(gd.distanceResults[i].min_distance)


def _march(w: World, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray] | None:
    """(a exactly free, b exactly colliding) 0.1 rad apart on a random joint-space ray from a
    random exactly free configuration; None when the ray leaves the joint limits first."""
    r, ex = w.robot, w.exact
    q0 = r.sample_uniform(rng, 1)[0]
    if not ex.is_valid(q0):
        return None
    v = rng.normal(size=r.dof)
    v *= 0.1 / np.linalg.norm(v)
    a = q0
    for k in range(1, 60):
        q = q0 + k * v
        if not r.within_limits(q)[0]:
            return None
        if not ex.is_valid(q):
            return a, q
        a = q
    return None


def near_contact(w: World, rng: np.random.Generator, n: int, max_tries: int = 50
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(near (n', K), past (n', K)), n' ≤ n: ``near`` exactly free with an exact clearance in
    [0, NEAR_MAX] m, the first such point of a bisection between a free and a colliding
    configuration (see :func:`_march`); ``past`` exactly colliding, 12 bisection steps further
    on the collision boundary (a penetration of a fraction of a millimetre)."""
    ex = w.exact
    gd = pin.GeometryData(ex.geom_model)
    near, past = [], []
    for _ in range(n * max_tries):
        if len(near) == n:
            break
        ab = _march(w, rng)
        if ab is None:
            continue
        a, b = ab
        for _ in range(60):
            if exact_distance(w, gd, a) <= NEAR_MAX:
                break
            m = 0.5 * (a + b)
            a, b = (m, b) if ex.is_valid(m) else (a, m)
        if not 0.0 <= exact_distance(w, gd, a) <= NEAR_MAX:
            continue
        near.append(a)
        for _ in range(12):
            m = 0.5 * (a + b)
            a, b = (m, b) if ex.is_valid(m) else (a, m)
        past.append(b)
    K = w.robot.dof
    return np.array(near).reshape(-1, K), np.array(past).reshape(-1, K)


def near_figures(w: World, n: int, seed: int) -> dict[str, float | int]:
    """False alarms on near-contact configurations (overall and by exact clearance) and false
    frees just past contact."""
    near, past = near_contact(w, np.random.default_rng(seed + 1), n)
    gd = pin.GeometryData(w.exact.geom_model)
    d = np.array([exact_distance(w, gd, q) for q in near])
    alarm = ~w.fast.valid(near)
    out: dict[str, float | int] = {
        "fast_false_alarm_rate_near": round(float(np.mean(alarm)) if len(near) else np.nan, 4)}
    for lo, hi in NEAR_BANDS:
        sel = (d >= lo) & (d < hi)
        out[f"near_{1e3 * lo:g}_{1e3 * hi:g}mm"] = int(sel.sum())
        out[f"fast_false_alarm_rate_near_{1e3 * lo:g}_{1e3 * hi:g}mm"] = \
            round(float(np.mean(alarm[sel])), 4) if sel.any() else np.nan
    out["fast_says_free_exact_says_collision_near"] = int(np.sum(w.fast.valid(past)))
    out["near_configs"] = len(near)
    return out


def bench_scene(name: str, robot: str | None, n: int, n_exact: int, n_near: int, seed: int,
                arm: str | None = None) -> dict[str, float | int | str]:
    rng = np.random.default_rng(seed)
    w = make_world(name, robot, arm)
    t = time.perf_counter()
    fast = w.fast
    build_s = time.perf_counter() - t
    Q = w.robot.sample_uniform(rng, n)
    fast.valid(Q[:10])  # load compiled kernels
    # best of 3 passes over the same n configurations (timeit's convention: the other passes
    # measure the machine's other load); the median pass is reported too
    times = []
    for _ in range(3):
        t = time.perf_counter()
        free = fast.valid(Q)
        times.append(time.perf_counter() - t)
    fast_rate = n / min(times)
    fast_rate_median = n / float(np.median(times))
    # soundness on all n: the exact checker rechecks every configuration called free
    missed = int(np.sum(~w.exact.valid(Q[free])))
    t = time.perf_counter()
    exact_free = w.exact.valid(Q[:n_exact])
    exact_rate = n_exact / (time.perf_counter() - t)
    false_alarm = float(np.sum(~free[:n_exact] & exact_free) / max(1, exact_free.sum()))
    # a 30-waypoint path through free space (straight line between two free configurations)
    starts = Q[free][:2]
    path = starts[0] + np.linspace(0, 1, 30)[:, None] * (starts[1] - starts[0])
    times = []
    for _ in range(3):
        t = time.perf_counter()
        w.exact.path_valid(path, substeps=100)
        times.append(time.perf_counter() - t)
    ik_times = []
    for q in Q[free][:200]:
        T = w.robot.compute_ee_pose(q)
        t = time.perf_counter()
        try:
            solve_ik(w.robot, T, 1, rng=rng)
        except IKError:
            continue
        ik_times.append(time.perf_counter() - t)
    return {"robot": w.robot.name, "scene": name, "fast_checks_per_s": round(fast_rate),
            "fast_checks_per_s_median": round(fast_rate_median),
            "exact_checks_per_s": round(exact_rate),
            "fast_says_free_exact_says_collision": missed,
            "fast_false_alarm_rate": round(false_alarm, 4),
            **near_figures(w, n_near, seed),
            "exact_path_ms": round(1e3 * min(times), 1),
            "ik_median_ms": round(1e3 * float(np.median(ik_times)), 2),
            "ik_solved": len(ik_times),
            "fast_build_s": round(build_s, 2), "grid_mb": round(fast.nbytes / 1e6, 1),
            "configs": n, "free_rate": round(float(free.mean()), 3)}


def main() -> None:
    from arms import ARMS  # this folder: run as a script

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--scenes", nargs="+", default=builtin_scenes())
    who = ap.add_mutually_exclusive_group()
    who.add_argument("--robot", default=None,
                     help="a built-in robot placed at Baxter's left shoulder (default: the "
                          "scene's own robot)")
    who.add_argument("--arm", default=None, choices=list(ARMS),
                     help="an example-robot-data arm placed as benchmarks/arms.py places it")
    ap.add_argument("--n", type=int, default=100_000, help="random configurations per scene")
    ap.add_argument("--n-exact", type=int, default=5000, help="for the exact rate / false alarms")
    ap.add_argument("--n-near", type=int, default=1000, help="near-contact configurations")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", action="store_true", help="one JSON object per line")
    args = ap.parse_args()
    for name in args.scenes:
        row = bench_scene(name, args.robot, args.n, args.n_exact, args.n_near, args.seed,
                          args.arm)
        if args.json:
            print(json.dumps(row), flush=True)
        else:
            print("  ".join(f"{k}={v}" for k, v in row.items()), flush=True)


if __name__ == "__main__":
    main()
