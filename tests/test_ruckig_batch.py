"""The compiled batch sampler of Ruckig trajectories gives Trajectory.at_time's states, on
random moves with and without a brake pre-phase (a start faster than the velocity limit)."""

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory

from chekhov.execute.ruckig_batch import batch_sampler


def _move(rng, dof, fast_start):
    inp = InputParameter(dof)
    inp.current_position = list(rng.uniform(-1, 1, dof))
    v0 = rng.uniform(-0.8, 0.8, dof)
    if fast_start:
        v0[0] = 1.6 * np.sign(v0[0] or 1.0)
    inp.current_velocity = list(v0)
    inp.current_acceleration = list(rng.uniform(-1.5, 1.5, dof))
    inp.target_position = list(rng.uniform(-1, 1, dof))
    inp.target_velocity = list(rng.uniform(-0.3, 0.3, dof))
    inp.target_acceleration = [0.0] * dof
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [1.0] * dof, [2.0] * dof, [10.0] * dof
    traj = Trajectory(dof)
    assert Ruckig(dof).calculate(inp, traj) in (Result.Working, Result.Finished)
    return traj


def test_batch_states_equal_at_time():
    rng = np.random.default_rng(4)
    braked = 0
    for i in range(60):
        traj = _move(rng, 7, fast_start=i % 2 == 1)
        braked += any(p.brake.duration > 0 for p in traj.profiles[0])
        sample = batch_sampler(traj)
        assert sample is not None
        ts = np.concatenate([np.linspace(0.0, traj.duration, 97), [traj.duration + 0.3]])
        q, qd, qdd = sample(ts)
        for n, t in enumerate(ts):
            ref = [np.asarray(x) for x in traj.at_time(float(t))]
            np.testing.assert_allclose(q[n], ref[0], atol=1e-9)
            np.testing.assert_allclose(qd[n], ref[1], atol=1e-9)
            np.testing.assert_allclose(qdd[n], ref[2], atol=1e-9)
    assert braked >= 20


def test_batch_states_equal_at_time_for_unsynchronised_stops():
    """The executive's stops: Ruckig's velocity interface, each joint on its own."""
    from chekhov.execute.motion import State, stop_from
    from chekhov.timing import Limits

    rng = np.random.default_rng(8)
    limits = Limits(np.full(7, 1.0), np.full(7, 2.0), np.full(7, 10.0))
    for _ in range(30):
        start = State(rng.uniform(-1, 1, 7), rng.uniform(-1, 1, 7), rng.uniform(-2, 2, 7))
        piece = stop_from(start, 0.0, limits).pieces[0]
        assert piece.batch is not None
        ts = np.linspace(0.0, piece.t_end, 41)
        q, qd, qdd = piece.states(ts)
        for n, t in enumerate(ts):
            s = piece.sample(float(t))
            np.testing.assert_allclose(q[n], s.q, atol=1e-9)
            np.testing.assert_allclose(qd[n], s.qd, atol=1e-9)
            np.testing.assert_allclose(qdd[n], s.qdd, atol=1e-9)
