"""Timed trajectories: the JointTrajectory value type (sampling, resampling, files, located
errors) and time parameterisation with toppra and ruckig.

What is checked, and how:

* limits hold everywhere on the interpolant: velocities and accelerations sampled every 1 ms
  and at random times never exceed the limits by more than ``TOL`` (1e-6, relative: float
  rounding; a different mechanism than the exact bound the code enforces);
* ends match the path's and are at rest;
* the trajectory stays near the certified polyline: ruckig on it (1e-9 rad), toppra within
  ``blend_deviation_rad`` (+ 1e-6 rad for the cubic interpolation between knots);
* a real collision-free polyline in tabletop_pole, timed by either method and sampled every
  1 ms, is collision-free by the exact checker; and so is a planner's timed answer;
* save/load is identical, malformed inputs raise a TrajectoryError naming the field.

Seeds are fixed; hypothesis runs derandomised.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from chekhov import (
    Goal,
    JointTrajectory,
    PlanStatus,
    TimingConfig,
    TrajectoryError,
    World,
    time_parameterize,
)
from chekhov.planners.registry import make_planner
from chekhov.roadmap.build import build_roadmap
from chekhov.roadmap.config import RoadmapConfig
from chekhov.timing import BlendedPolyline, corners, joint_limits, polyline_deviation

NAMES = tuple(f"j{i}" for i in range(7))
BAXTER_VELOCITY = np.array([1.5, 1.5, 1.5, 1.5, 4.0, 4.0, 4.0])   # rad/s, its URDF
LIMITS = joint_limits(BAXTER_VELOCITY, TimingConfig())
TOL = 1e-6          # relative, on the limits
INTERP_TOL = 1e-6   # rad, the cubic interpolation's distance from toppra's arcs between knots


def _random_path(rng, n):
    return np.cumsum(rng.normal(scale=0.3, size=(n, 7)), axis=0)


def _dense(traj, dt=1e-3):
    return np.append(np.arange(0.0, traj.duration, dt), traj.duration)


def _assert_within_limits(traj, rng, limits=LIMITS):
    ts = np.concatenate([_dense(traj), rng.uniform(0, traj.duration, 2000)])
    _, qd, qdd = traj.sample(ts)
    assert np.all(np.abs(qd) <= limits.velocity * (1 + TOL)), \
        np.abs(qd / limits.velocity).max()
    assert np.all(np.abs(qdd) <= limits.acceleration * (1 + TOL)), \
        np.abs(qdd / limits.acceleration).max()


def _assert_near_polyline(timed, P, config):
    traj = timed.trajectory
    bound = 1e-9 if config.method == "ruckig" else config.blend_deviation_rad + INTERP_TOL
    assert timed.max_deviation_rad <= bound
    assert polyline_deviation(traj.sample(_dense(traj))[0], P) <= bound   # between knots too


@pytest.mark.parametrize("config", [TimingConfig(method="ruckig"), TimingConfig(),
                                    TimingConfig(blend_deviation_rad=0.0),
                                    TimingConfig(blend_deviation_rad=0.1)],
                         ids=["ruckig", "toppra", "toppra-rest", "toppra-0.1"])
def test_limits_hold_ends_match_and_the_polyline_is_kept(config):
    rng = np.random.default_rng(3)
    for n in (2, 3, 8):
        P = _random_path(rng, n)
        timed = time_parameterize(P, NAMES, LIMITS, config)
        traj = timed.trajectory
        q, qd, _ = traj.sample(np.array([0.0, traj.duration]))
        assert np.allclose(q, P[[0, -1]], atol=1e-9) and np.allclose(qd, 0.0, atol=1e-6)
        _assert_within_limits(traj, rng)
        _assert_near_polyline(timed, P, config)


@settings(max_examples=30, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 10),
       method=st.sampled_from(["toppra", "ruckig"]),
       deviation=st.sampled_from([0.0, 0.02, 0.1]))
def test_property_limits_ends_and_polyline(seed, n, method, deviation):
    rng = np.random.default_rng(seed)
    P = _random_path(rng, n)
    accel = tuple(rng.uniform(1.0, 10.0, 7))          # per joint, rad/s²
    config = TimingConfig(method=method, acceleration_limit=accel,
                          blend_deviation_rad=deviation)
    limits = joint_limits(BAXTER_VELOCITY, config)
    timed = time_parameterize(P, NAMES, limits, config)
    assert np.allclose(timed.trajectory.positions[[0, -1]], P[[0, -1]], atol=1e-9)
    _assert_within_limits(timed.trajectory, rng, limits)
    _assert_near_polyline(timed, P, config)


@pytest.mark.parametrize("length", [1e-6, 5e-5, 1e-4, 3e-4])
def test_a_path_shorter_than_the_grid_merge_step_is_timed_by_toppra(length):
    P = np.zeros((3, 7))
    P[1, 0], P[2, 0], P[2, 1] = length / 2, length, length / 10
    timed = time_parameterize(P, NAMES, LIMITS)
    assert timed.method == "toppra"
    assert np.allclose(timed.trajectory.positions[[0, -1]], P[[0, -1]], atol=1e-12)
    _assert_within_limits(timed.trajectory, np.random.default_rng(0))


@pytest.mark.parametrize("seed", range(4))
def test_the_compiled_toppra_matches_the_toppra_package(seed):
    # the same problem (grid, blends, limits) solved by chekhov.topp_kernel and by the toppra
    # package's LP solver: the same speeds at every grid point (durations before the final
    # check on the interpolant agree to ~1e-6; that check may slow either by ~1e-5)
    rng = np.random.default_rng(seed)
    limits = joint_limits(rng.uniform(0.5, 4.0, 7), TimingConfig(
        acceleration_limit=tuple(rng.uniform(1.0, 6.0, 7))))
    for scale in (0.02, 0.3, 1.0):
        P = np.cumsum(rng.normal(scale=scale, size=(int(rng.integers(2, 9)), 7)), axis=0)
        ours, theirs = (time_parameterize(P, NAMES, limits, TimingConfig(toppra_solver=solver))
                        .trajectory for solver in ("compiled", "library"))
        assert ours.duration == pytest.approx(theirs.duration, rel=1e-4), (scale, P)
        assert ours.duration > 0.0
        for t in np.linspace(0.0, 1.0, 11):
            q_ours, qd_ours, _ = ours.sample(t * ours.duration)
            q_theirs, qd_theirs, _ = theirs.sample(t * theirs.duration)
            assert np.allclose(q_ours, q_theirs, atol=1e-4), (scale, t)
            assert np.allclose(qd_ours, qd_theirs, atol=1e-3 * limits.velocity.max()), (scale, t)
        _assert_within_limits(ours, rng, limits)


def test_a_reversal_rests_at_the_corner_and_a_straight_corner_is_passed():
    a, b = np.zeros(7), np.full(7, 0.4)
    back = np.array([a, b, a])                          # turns by pi: cannot be rounded
    assert corners(back, 0.02).stops.tolist() == [True]
    traj = time_parameterize(back, NAMES, LIMITS).trajectory
    i = int(np.argmin(np.linalg.norm(traj.positions - b, axis=1)))
    assert np.allclose(traj.positions[i], b) and np.allclose(traj.velocities[i], 0.0)
    straight = np.array([a, b / 2, b])                  # a waypoint on a straight line
    assert corners(straight, 0.02).stops.tolist() == [False]
    traj = time_parameterize(straight, NAMES, LIMITS).trajectory
    _, qd, _ = traj.sample(traj.duration / 2)
    assert np.linalg.norm(qd) > 0.5                     # passes it at speed


def test_an_evenly_spaced_gentle_bend_is_not_slowed_down():
    # TrajOpt's answers: 30 evenly spaced waypoints, corners turning by 1e-6..1e-2 rad, so each
    # is rounded over half of both segments and the lines between the arcs are 1e-7 rad long.
    # Their grid points, microns apart, made stages of ~1e-7 s whose rounding the interpolant
    # read as accelerations 100-200 000 times the limit, and the whole motion was slowed 13-467
    # times (a 1.4 rad path took 120 s). Checked against ruckig's timing, which rests at every
    # waypoint and so can only be slower than the blended one.
    t = np.linspace(0.0, 1.0, 30)[:, None]
    for seed in range(5):
        rng = np.random.default_rng(seed)
        P = rng.uniform(-1, 1, 7) + t * rng.normal(size=7) + 0.05 * t ** 6 * rng.normal(size=7)
        blended = time_parameterize(P, NAMES, LIMITS).trajectory
        resting = time_parameterize(P, NAMES, LIMITS, TimingConfig(method="ruckig")).trajectory
        assert blended.duration < resting.duration, (seed, blended.duration, resting.duration)
        _assert_within_limits(blended, rng)


def test_the_blend_is_a_unit_speed_path_near_each_corner():
    P = _random_path(np.random.default_rng(4), 6)
    path = BlendedPolyline(P, 0.05)
    s = np.linspace(0.0, path.length, 20001)
    q, dq = path(s), path(s, 1)
    assert np.allclose(q[[0, -1]], P[[0, -1]]) and np.allclose(np.linalg.norm(dq, axis=1), 1.0)
    ds = s[1] - s[0]
    assert np.allclose(np.linalg.norm(np.diff(q, axis=0), axis=1), ds, rtol=1e-3)   # no jump
    assert polyline_deviation(q, P) <= 0.05 + 1e-12
    corner = np.linalg.norm(q[:, None] - P[None, 1:-1], axis=2).min(axis=0)
    assert np.all(corner <= 0.05 + ds) and np.any(corner > 0.01)   # rounded, not passed


def test_sample_is_consistent_with_its_derivatives_and_knots():
    traj = time_parameterize(_random_path(np.random.default_rng(5), 4), NAMES, LIMITS).trajectory
    q, qd, qdd = traj.sample(traj.times)
    assert np.allclose(q, traj.positions) and np.allclose(qd, traj.velocities)
    assert np.allclose(qdd, traj.accelerations)
    q0, qd0, qdd0 = traj.sample(traj.times[3])          # a scalar time: (K,) each
    assert q0.shape == qd0.shape == qdd0.shape == (7,) and np.allclose(q0, traj.positions[3])
    t = np.linspace(0.1, traj.duration - 0.1, 50)
    eps = 1e-6
    (qa, va, _), (qb, vb, _) = traj.sample(t - eps), traj.sample(t + eps)
    _, v, a = traj.sample(t)
    assert np.allclose((qb - qa) / (2 * eps), v, atol=1e-5)
    assert np.allclose((vb - va) / (2 * eps), a, atol=1e-3)
    assert np.allclose(traj.sample(np.array([-1.0, traj.duration + 1]))[0],
                       traj.positions[[0, -1]])          # clamped
    dense = traj.densify(3)
    assert len(dense.times) == 3 * (len(traj.times) - 1) + 1
    assert np.allclose(dense.sample(t)[0], traj.sample(t)[0], atol=1e-12)   # same curve
    r = traj.resample(0.01)
    assert r.duration == pytest.approx(traj.duration) and np.all(np.diff(r.times) <= 0.01 + 1e-12)
    assert np.allclose(r.sample(t)[0], traj.sample(t)[0], atol=1e-6)
    assert traj.length == pytest.approx(np.linalg.norm(np.diff(traj.positions, axis=0),
                                                       axis=1).sum())


def test_from_waypoints_passes_the_waypoints_at_their_times_at_rest_at_the_ends():
    P = _random_path(np.random.default_rng(7), 5)
    times = np.array([0.0, 0.5, 1.2, 1.5, 2.5])
    traj = JointTrajectory.from_waypoints(P, times, NAMES)
    q, qd, qdd = traj.sample(times)
    assert np.allclose(q, P) and np.allclose(qd[[0, -1]], 0.0)
    assert np.allclose(qdd, traj.accelerations)
    assert np.allclose(traj.sample(times[1:-1] - 1e-9)[2], qdd[1:-1], atol=1e-4)   # C²
    one = JointTrajectory.from_waypoints(P[:1], [0.0], NAMES)
    assert one.duration == 0.0 and one.resample(0.1) is one and one.densify(4) is one
    assert np.allclose(one.sample(3.0)[0], P[0])
    with pytest.raises(TrajectoryError, match="'times': not strictly increasing at index 2"):
        JointTrajectory.from_waypoints(P[:3], [0.0, 1.0, 1.0], NAMES)


def test_save_and_load_are_identical(tmp_path):
    traj = time_parameterize(_random_path(np.random.default_rng(6), 3), NAMES, LIMITS,
                             TimingConfig(method="ruckig")).trajectory
    path = traj.save(tmp_path / "t.npz")
    back = JointTrajectory.load(path)
    assert back.joint_names == traj.joint_names
    for f in ("times", "positions", "velocities", "accelerations"):
        assert np.array_equal(getattr(back, f), getattr(traj, f))
    assert [p.name for p in tmp_path.iterdir()] == ["t.npz"]   # no temporary left behind


@pytest.mark.parametrize("change, match", [
    ({"times": [0.0, 0.2, 0.1]}, "'times': not strictly increasing at index 2"),
    ({"times": [0.1, 0.2, 0.3]}, "'times': must start at 0"),
    ({"times": [[0.0, 0.1, 0.2]]}, "'times': 2-D, expected 1-D"),
    ({"times": [0.0, np.inf, 0.2]}, r"'times': not finite at index \(1,\)"),
    ({"positions": np.full((3, 2), np.nan)}, r"'positions': not finite at index \(0, 0\)"),
    ({"positions": "abc"}, "'positions': not an array of numbers"),
    ({"velocities": np.zeros((2, 2))}, r"'velocities': shape \(2, 2\), expected \(3, 2\)"),
    ({"accelerations": np.zeros(3)}, "'accelerations': 1-D, expected 2-D"),
])
def test_malformed_trajectories_name_the_field(change, match):
    fields = {"joint_names": ("a", "b"), "times": [0.0, 0.1, 0.2],
              "positions": np.zeros((3, 2)), "velocities": np.zeros((3, 2)),
              "accelerations": np.zeros((3, 2))}
    with pytest.raises(TrajectoryError, match=match):
        JointTrajectory(**{**fields, **change})


def _write(path, **arrays):
    fields = {"format": np.array("chekhov-trajectory"), "version": np.array(1),
              "joint_names": np.array(["a"]), "times": np.zeros(1), "positions": np.zeros((1, 1)),
              "velocities": np.zeros((1, 1)), "accelerations": np.zeros((1, 1))}
    fields.update(arrays)
    np.savez(path, **{k: v for k, v in fields.items() if v is not None})
    return path


@pytest.mark.parametrize("arrays, match", [
    ({"format": np.array("something-else")}, "field 'format'"),
    ({"version": np.array(7)}, "field 'version' is 7"),
    ({"velocities": None}, "field 'velocities' is missing"),
    ({"times": np.array([0.0, -1.0])}, "'times': not strictly increasing at index 1"),
])
def test_a_bad_file_names_the_file_and_the_field(tmp_path, arrays, match):
    path = _write(tmp_path / "bad.npz", **arrays)
    with pytest.raises(TrajectoryError, match=rf"bad\.npz: .*{match}"):
        JointTrajectory.load(path)


def test_an_unreadable_file_or_config_says_so(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(TrajectoryError, match=r"bad\.npz"):
        JointTrajectory.load(bad)
    with pytest.raises(TrajectoryError, match=r"no such trajectory file"):
        JointTrajectory.load(tmp_path / "missing.npz")
    with pytest.raises(TrajectoryError, match=r"TimingConfig\.method"):
        TimingConfig(method="linear")
    with pytest.raises(TrajectoryError, match=r"TimingConfig\.blend_deviation_rad"):
        TimingConfig(blend_deviation_rad=-0.1)
    with pytest.raises(TrajectoryError, match=r"TimingConfig\.toppra_solver"):
        TimingConfig(toppra_solver="seidel")
    with pytest.raises(TrajectoryError, match=r"TimingConfig\.acceleration_limit: 2 values"):
        joint_limits(BAXTER_VELOCITY, TimingConfig(acceleration_limit=(1.0, 2.0)))
    with pytest.raises(TrajectoryError, match=r"path: expected a finite \(T, 7\)"):
        time_parameterize(np.full((3, 7), np.nan), NAMES, LIMITS)


def _free_polyline(world, rng, n=6, step=0.6):
    """A polyline of n waypoints in ``world`` from a benchmark start (near the table), each
    segment ``step`` rad in a random direction, within the joint limits and collision-free by
    the exact check at 100 substeps (the planners' certification)."""
    from chekhov.bench.cases import generate_cases

    path = [generate_cases(world, 1, seed=9).q_start[0]]
    while len(path) < n:
        u = rng.normal(size=7)
        q = path[-1] + step * u / np.linalg.norm(u)
        if world.robot.within_limits(q)[0] and world.exact.path_valid(np.array([path[-1], q])):
            path.append(q)
    return np.array(path)


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_a_certified_polyline_timed_and_sampled_every_ms_is_exactly_free(world_of, method):
    world = world_of("tabletop_pole")
    P = _free_polyline(world, np.random.default_rng(11))
    assert world.exact.path_valid(P, substeps=100)
    config = TimingConfig(method=method)
    limits = joint_limits(world.robot.velocity_limit, config)
    timed = time_parameterize(P, world.robot.joint_names, limits, config)
    traj = timed.trajectory
    Q, V, A = traj.sample(_dense(traj))
    assert world.exact.valid(Q).all() and world.robot.within_limits(Q).all()
    assert np.all(np.abs(V) <= limits.velocity * (1 + TOL))
    assert np.all(np.abs(A) <= limits.acceleration * (1 + TOL))
    _assert_near_polyline(timed, P, config)


@pytest.mark.parametrize("planner_name", ["Roadmap+TrajOpt", "RRTConnect"])
def test_a_planners_timed_answer_is_exactly_free_when_sampled_densely(world_of, planner_name):
    """plan() times every answer by default: the trajectory starts at the start and ends at the
    path's end, respects the robot's limits, and its samples every 2 ms — not its knots — are
    collision-free by the exact checker. RRTConnect (OMPL seeds its own sampler, so its paths
    differ from run to run) may end "collision" when the certification rejects its path: at
    least 2 of 3 answers; Roadmap + TrajOpt all 3. The planner is warmed up first: a cold
    process's first plan compiles its kernels within the 2 s limit and may leave too little of
    it to time the answer (as documented: no trajectory, ``timing_error`` says why)."""
    world = world_of("tabletop_pole")
    roadmap = build_roadmap(world, RoadmapConfig(n_nodes=150, n_region_nodes=20,
                                                 n_wrist_nodes=60, seed=3))
    planner = make_planner(planner_name, world, roadmap)
    assert planner.timing == TimingConfig()      # the default
    planner.warmup()
    from chekhov.bench.cases import generate_cases
    cases = generate_cases(world, 3, seed=9)
    limits = joint_limits(world.robot.velocity_limit, planner.timing)
    solved = 0
    for i in range(3):
        r = planner.plan(cases.q_start[i], cases.goal(i), 2.0)
        assert r.success or (planner_name == "RRTConnect" and r.status == PlanStatus.COLLISION)
        if not r.success:
            continue
        solved += 1
        traj = r.trajectory
        assert traj is not None, r.info.get("timing_error")
        assert traj.joint_names == world.robot.joint_names
        assert np.allclose(traj.positions[0], r.path[0]) and np.allclose(traj.positions[-1],
                                                                          r.path[-1])
        ts = np.arange(0.0, traj.duration, 0.002) + 0.0007
        Q, V, A = traj.sample(ts)
        assert world.exact.valid(Q).all()
        assert world.robot.within_limits(Q).all()
        assert np.all(np.abs(V) <= limits.velocity * (1 + TOL))
        assert np.all(np.abs(A) <= limits.acceleration * (1 + TOL))
        assert r.info["timing_method"] in ("toppra", "ruckig")
    assert solved >= (2 if planner_name == "RRTConnect" else 3)


def test_a_failed_parameterisation_never_loses_the_answer(world_of, monkeypatch):
    """toppra failing falls back to ruckig; both failing keeps the certified path as the
    answer, without a trajectory and saying why."""
    import chekhov.timing as timing
    from chekhov.planners.timed import timed_trajectory

    world = world_of("tabletop_pole")
    Q = world.robot.sample_uniform(np.random.default_rng(8), 200)
    q0, q1 = Q[world.fast.valid(Q)][:2]
    path = np.linspace(q0, q0 + 0.05 * (q1 - q0), 4)     # short: free in practice
    assert world.exact.path_valid(path, substeps=100)

    def broken(*args, **kwargs):
        raise TrajectoryError("toppra failed: test")

    monkeypatch.setattr(timing, "_toppra", broken)
    assert timed_trajectory(world, path).method == "ruckig"
    monkeypatch.setattr(timing, "_ruckig_segments", broken)
    with pytest.raises(TrajectoryError):
        timed_trajectory(world, path)
    planner = make_planner("TrajOpt", world)
    planner.timing = TimingConfig()
    r = planner.plan(q0, Goal.configuration(path[-1]), 2.0)
    assert r.success and r.trajectory is None and "toppra failed" in r.info["timing_error"]


def test_an_answer_is_not_timed_when_that_would_break_the_time_limit(world_of):
    """With less than TIMING_RESERVE_S left after certification, the certified path is the
    answer without a trajectory, and info says why; plan() returns by its deadline."""
    import time

    from chekhov.planners.base import TIMING_RESERVE_S

    world = world_of("tabletop_pole")
    planner = make_planner("TrajOpt", world)
    Q = world.robot.sample_uniform(np.random.default_rng(8), 200)
    q0, q1 = Q[world.fast.valid(Q)][:2]
    goal = Goal.configuration(q0 + 0.05 * (q1 - q0))
    limit = TIMING_RESERVE_S / 2
    t = time.perf_counter()
    r = planner.plan(q0, goal, limit)
    elapsed = time.perf_counter() - t
    assert r.success and r.trajectory is None and "not timed" in r.info["timing_error"]
    assert elapsed <= limit + 0.005
    planner.timing = None
    r = planner.plan(q0, goal, 2.0)
    assert r.success and r.trajectory is None and "timing_error" not in r.info


def _corner_path(world, rng):
    """A free right-angled corner path q0 → qc → q1 (legs 1 rad)."""
    while True:
        q0 = world.robot.sample_uniform(rng, 1)[0]
        u, v = np.linalg.qr(rng.normal(size=(world.robot.dof, 2)))[0].T
        path = np.array([q0, q0 + u, q0 + u + v])
        if world.robot.within_limits(path).all() and world.exact.path_valid(path, substeps=100):
            return path


def _arc_obstacle(world, path, Q, off):
    """(centre (3,), radius) m of a sphere that the robot touches at the arc's middle (the
    knot off the polyline ``path`` nearest its corner, where it is farthest from it: the
    obstacle lies in a sphere's inner ball there) and that every sphere of the robot along
    the polyline clears; None when no sphere gives one 4 mm clear."""
    q_arc = Q[np.argmin(np.where(off, np.linalg.norm(Q - path[1], axis=1), np.inf))]
    along = np.linspace(0, 1, 200)[:, None]
    poly = np.concatenate([path[0] + along * (path[1] - path[0]),
                           path[1] + along * (path[2] - path[1])])
    sph = world.fast.packed.spheres
    C_arc = world.fast.sphere_centers(q_arc)
    C_poly = np.stack([world.fast.sphere_centers(q) for q in poly])       # (M, S, 3)
    clear = np.array([(np.linalg.norm(C_poly - c, axis=2) - sph.radius).min() for c in C_arc])
    s = int(np.argmax(np.where(sph.inner > 0, clear, -np.inf)))
    return (C_arc[s], min(clear[s] / 2, sph.inner[s])) if clear[s] > 0.004 else None


def test_only_the_rounded_corners_are_rechecked_and_an_obstacle_on_one_is_found():
    """timed_trajectory re-checks the chords that leave the certified polyline — every knot
    off it, by projection onto each segment here, is in a run — and not the straight parts;
    an obstacle placed on a corner's arc (inside a sphere's inner ball there, clear of every
    sphere along the polyline, so the polyline stays free) makes it fall back to ruckig."""
    from chekhov.planners.timed import off_polyline_runs, timed_trajectory
    from chekhov.scene.model import Shape

    config = TimingConfig(blend_deviation_rad=0.3)
    world = World.load("tabletop_pole")
    rng = np.random.default_rng(23)
    found = 0
    for _ in range(20):
        path = _corner_path(world, rng)
        timed = timed_trajectory(world, path, config)
        assert timed.method == "toppra"
        Q = timed.trajectory.positions
        a, d = path[:-1], np.diff(path, axis=0)
        t = np.clip(np.einsum("nsk,sk->ns", Q[:, None] - a, d) / (d * d).sum(1), 0, 1)
        off = np.linalg.norm(Q[:, None] - (a + t[..., None] * d), axis=2).min(axis=1) > 1e-9
        in_run = np.zeros(len(Q), dtype=bool)
        for lo, hi in off_polyline_runs(Q, path):
            in_run[lo:hi + 1] = True
        assert off.sum() >= 5 and np.all(in_run[off])
        assert in_run.sum() <= 0.8 * len(Q)
        obstacle = _arc_obstacle(world, path, Q, off)
        if obstacle is None:
            continue
        T = np.eye(4)
        T[:3, 3] = obstacle[0]
        world.set_obstacles({"on_the_arc": (Shape("sphere", (obstacle[1],)), T)})
        assert world.exact.path_valid(path, substeps=100)
        assert not world.exact.valid(Q).all()
        assert timed_trajectory(world, path, config).method == "ruckig"
        world.set_obstacles({})
        found += 1
    assert found >= 3, found
    # two knots on the polyline but on different segments: their chord cuts the corner
    cut = np.array([path[0], (path[0] + path[1]) / 2, (path[1] + path[2]) / 2, path[2]])
    assert off_polyline_runs(cut, path) == [(1, 2)]
