"""Timed trajectories: the JointTrajectory value type (sampling, resampling, files, located
errors) and time parameterisation with toppra and ruckig: limits hold everywhere on the
interpolant (checked on a dense random grid, a different mechanism than the exact bound the
code uses), ends match, ruckig stays on the polyline, and a planner's timed answer sampled
densely in time is exactly collision-free."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from chekhov import Goal, JointTrajectory, TimingConfig, TrajectoryError, time_parameterize
from chekhov.planners.registry import make_planner
from chekhov.roadmap.build import build_roadmap
from chekhov.roadmap.config import RoadmapConfig
from chekhov.timing import joint_limits, polyline_deviation

NAMES = tuple(f"j{i}" for i in range(7))
LIMITS = joint_limits(np.array([1.5, 1.5, 1.5, 1.5, 4.0, 4.0, 4.0]), TimingConfig())
TOL = 1e-6   # relative, on the limits at random times


def _random_path(rng, n):
    return np.cumsum(rng.normal(scale=0.3, size=(n, 7)), axis=0)


def _assert_within_limits(traj, rng):
    ts = np.sort(rng.uniform(0, traj.duration, 4000))
    _, qd, qdd = traj.sample(ts)
    assert np.all(np.abs(qd) <= LIMITS.velocity * (1 + TOL)), np.abs(qd / LIMITS.velocity).max()
    assert np.all(np.abs(qdd) <= LIMITS.acceleration * (1 + TOL)), \
        np.abs(qdd / LIMITS.acceleration).max()


@pytest.mark.parametrize("method", ["toppra", "ruckig"])
def test_limits_hold_and_ends_match(method):
    rng = np.random.default_rng(3)
    for n in (2, 3, 8):
        P = _random_path(rng, n)
        timed = time_parameterize(P, NAMES, LIMITS, TimingConfig(method=method))
        traj = timed.trajectory
        q, qd, _ = traj.sample(np.array([0.0, traj.duration]))
        assert np.allclose(q, P[[0, -1]], atol=1e-9) and np.allclose(qd, 0.0, atol=1e-6)
        _assert_within_limits(traj, rng)
        if method == "ruckig":
            assert timed.max_deviation_rad < 1e-9
            dense = traj.sample(np.linspace(0, traj.duration, 3000))[0]
            assert polyline_deviation(dense, P) < 1e-9     # between knots too


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 10),
       method=st.sampled_from(["toppra", "ruckig"]))
def test_property_limits_and_ends(seed, n, method):
    rng = np.random.default_rng(seed)
    P = _random_path(rng, n)
    traj = time_parameterize(P, NAMES, LIMITS, TimingConfig(method=method)).trajectory
    assert np.allclose(traj.positions[[0, -1]], P[[0, -1]], atol=1e-9)
    _assert_within_limits(traj, rng)


def test_sample_is_consistent_with_its_derivatives_and_knots():
    traj = time_parameterize(_random_path(np.random.default_rng(5), 4), NAMES, LIMITS).trajectory
    q, qd, qdd = traj.sample(traj.times)
    assert np.allclose(q, traj.positions) and np.allclose(qd, traj.velocities)
    assert np.allclose(qdd, traj.accelerations)
    t = np.linspace(0.1, traj.duration - 0.1, 50)
    eps = 1e-6
    (qa, va, _), (qb, vb, _) = traj.sample(t - eps), traj.sample(t + eps)
    _, v, a = traj.sample(t)
    assert np.allclose((qb - qa) / (2 * eps), v, atol=1e-5)
    assert np.allclose((vb - va) / (2 * eps), a, atol=1e-3)
    dense = traj.densify(3)
    assert np.allclose(dense.sample(t)[0], traj.sample(t)[0], atol=1e-12)   # same curve
    r = traj.resample(0.01)
    assert r.duration == pytest.approx(traj.duration) and np.all(np.diff(r.times) <= 0.01 + 1e-12)


def test_save_and_load_are_identical(tmp_path):
    traj = time_parameterize(_random_path(np.random.default_rng(6), 3), NAMES, LIMITS,
                             TimingConfig(method="ruckig")).trajectory
    path = traj.save(tmp_path / "t.npz")
    back = JointTrajectory.load(path)
    assert back.joint_names == traj.joint_names
    for f in ("times", "positions", "velocities", "accelerations"):
        assert np.array_equal(getattr(back, f), getattr(traj, f))


@pytest.mark.parametrize("change, match", [
    ({"times": [0.0, 0.2, 0.1]}, "'times': not strictly increasing at index 2"),
    ({"times": [0.1, 0.2, 0.3]}, "'times': must start at 0"),
    ({"positions": np.full((3, 2), np.nan)}, r"'positions': not finite at index \(0, 0\)"),
    ({"velocities": np.zeros((2, 2))}, r"'velocities': shape \(2, 2\), expected \(3, 2\)"),
])
def test_malformed_trajectories_name_the_field(change, match):
    fields = {"joint_names": ("a", "b"), "times": [0.0, 0.1, 0.2],
              "positions": np.zeros((3, 2)), "velocities": np.zeros((3, 2)),
              "accelerations": np.zeros((3, 2))}
    with pytest.raises(TrajectoryError, match=match):
        JointTrajectory(**{**fields, **change})


def test_a_bad_file_names_the_file(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(TrajectoryError, match=r"bad\.npz"):
        JointTrajectory.load(bad)
    with pytest.raises(TrajectoryError, match=r"TimingConfig\.method"):
        TimingConfig(method="linear")


@pytest.mark.parametrize("planner_name", ["Roadmap+TrajOpt", "RRTConnect"])
def test_a_planners_timed_answer_is_exactly_free_when_sampled_densely(world_of, planner_name):
    """plan() with timing set: the trajectory starts at the start and ends at the path's end,
    respects the robot's limits, and its samples every 2 ms — not its knots — are collision-free
    by the exact checker."""
    world = world_of("tabletop_pole")
    roadmap = build_roadmap(world, RoadmapConfig(n_nodes=150, n_region_nodes=20,
                                                 n_wrist_nodes=60, seed=3))
    planner = make_planner(planner_name, world, roadmap)
    planner.timing = TimingConfig()
    from chekhov.bench.cases import generate_cases
    cases = generate_cases(world, 3, seed=9)
    limits = joint_limits(world.robot.velocity_limit, planner.timing)
    for i in range(3):
        r = planner.plan(cases.q_start[i], cases.goal(i), 2.0)
        assert r.success, r.status
        traj = r.trajectory
        assert traj is not None and traj.joint_names == world.robot.joint_names
        assert np.allclose(traj.positions[0], r.path[0]) and np.allclose(traj.positions[-1],
                                                                          r.path[-1])
        ts = np.arange(0.0, traj.duration, 0.002) + 0.0007
        Q, V, A = traj.sample(ts)
        assert world.exact.valid(Q).all()
        assert world.robot.within_limits(Q).all()
        assert np.all(np.abs(V) <= limits.velocity * (1 + TOL))
        assert np.all(np.abs(A) <= limits.acceleration * (1 + TOL))
        assert r.info["timing_method"] in ("toppra", "ruckig")


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
