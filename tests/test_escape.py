"""The executive's last resort (chekhov.execute.escape): of random escapes, the one that meets
the obstacles' predicted motion latest — checked against its statement sample by sample, and
against the obstacle's true motion with the exact checker."""

import numpy as np
import pytest

from chekhov.execute.escape import FINE_WINDOW_S, Escaper
from chekhov.execute.evade import Evader, EvadeSettings
from chekhov.execute.evaluate import TrueWorld
from chekhov.execute.interface import ExecutorConfig
from chekhov.execute.motion import Bounds, State, hold
from chekhov.execute.obstacles import MovingObstacle, ObstacleTracks, obstacles_at
from chekhov.execute.script import start_and_goal
from chekhov.scene.model import Shape
from chekhov.timing import joint_limits
from chekhov.world import World

EXECUTOR = ExecutorConfig()
DT = EXECUTOR.check_dt_s


@pytest.fixture(scope="module")
def world():
    return World.load("tabletop_pole")


@pytest.fixture(scope="module")
def limits(world):
    return joint_limits(world.robot.velocity_limit, EXECUTOR.timing)


def _ball_at_the_elbow(world, radius=0.08, speed=0.8):
    """The first task case's start q0, a ball of ``radius`` (m) flying at its elbow at
    ``speed`` (m/s) from 0.5 m away, and the tracks of two sensor frames of it by t0 = 0.1 s:
    (q0, ball, tracks, t0)."""
    q0, _ = start_and_goal(world, 0, 0)
    elbow = world.robot.compute_joint_placements(q0)[3, :3, 3]
    d = np.array([-1.0, 0.0, 0.0])
    ball = MovingObstacle("ball", Shape("sphere", (radius,)), np.eye(3), elbow - 0.5 * d,
                          elbow + 0.5 * d, 0.0, speed)
    tracks = ObstacleTracks()
    t0 = 0.1
    for stamp in (t0 - 1 / 30, t0):
        tracks.update(obstacles_at((ball,), stamp), stamp)
    return q0, ball, tracks, t0


def _escaper(world, tracks, limits, seed=5):
    c = EXECUTOR
    evader = Evader(world, tracks, EvadeSettings(c.horizon_s, c.margin_m, c.check_dt_s,
                                                 c.obstacle_speed_m_s),
                    limits, Bounds(world.robot.lower, world.robot.upper), seed=seed)
    return Escaper(evader)


def _first_meeting(world, escaper, motion, t0):
    """The first check step (s) from t0 (or the motion's start) to its end at which the
    motion meets the sweep of the fine window holding it (after the horizon, the last one) —
    each sample checked on its own, the window packed here (inf: none); -inf when it leaves
    the joint limits at any step."""
    from chekhov.execute.obstacles import predicted_primitives
    c = escaper.evader.settings
    edges = np.arange(0.0, c.horizon_s + 1e-9, FINE_WINDOW_S)
    t_from = max(motion.t_start, t0)
    ts, Q = motion.positions(t_from, max(t0 + edges[-1], motion.t_end), c.check_dt_s)
    if not world.robot.within_limits(Q).all():
        return -np.inf
    for t, q in zip(ts, Q, strict=True):
        k = min(max(int(np.searchsorted(edges, t - t0 + 1e-9, side="right")) - 1, 0),
                len(edges) - 2)
        packed = world.fast.packed_with(predicted_primitives(
            escaper.evader.tracks, t0 + edges[k], edges[k + 1] - edges[k], 0.0,
            speed_bound_m_s=c.obstacle_speed_m_s))
        if not world.fast.valid_in(packed, q[None])[0]:
            return float(t)
    return np.inf


def test_the_latest_meeting_is_each_samples_check_in_its_window(world, limits):
    """``Escaper._latest`` (coarse samples first, then the motions latest first until none
    can beat the best) against its statement: of the motions within the joint limits to
    their end, the one whose first sample meeting its fine window's sweep comes latest, each
    sample checked on its own — escapes of an arm moving at the ball, some meeting it soon,
    some late, some never."""
    q0, _, tracks, t0 = _ball_at_the_elbow(world)
    escaper = _escaper(world, tracks, limits)
    rng = np.random.default_rng(8)
    z = np.zeros_like(q0)
    now = State(q0, rng.uniform(-0.3, 0.3, len(q0)) * limits.velocity, z)
    moves = escaper.evader.escape_moves(now, t0, 24)
    c = escaper.evader.settings
    edges = np.arange(0.0, c.horizon_s + 1e-9, FINE_WINDOW_S)
    packs = escaper.evader.windows(t0, 0.0, FINE_WINDOW_S)
    expected = [_first_meeting(world, escaper, m, t0) for m in moves]
    i, t_i = escaper._latest(moves, t0, packs, edges)
    assert t_i == max(expected)
    assert expected[i] == t_i
    finite = [t for t in expected if np.isfinite(t)]
    assert len(finite) >= 3 and len(set(finite)) >= 2        # the search had work to do
    assert escaper._latest(moves, t0, packs, edges, beat=np.inf) == (-1, np.inf)
    for move, t in zip(moves, expected, strict=True):     # each one's own time, to the step
        assert escaper._latest([move], t0, packs, edges) == ((0, t) if t > -np.inf
                                                             else (-1, -np.inf))
    meeting = [m for m, t in zip(moves, expected, strict=True) if np.isfinite(t)]
    i, t_i = escaper._latest(meeting, t0, packs, edges)
    assert t_i == max(t for t in expected if np.isfinite(t))
    outside = [m for m, t in zip(moves, expected, strict=True) if t == -np.inf]
    assert outside     # an escape leaving the limits is never taken, however late it meets
    assert escaper._latest(outside, t0, packs, edges) == (-1, -np.inf)


def test_an_arm_in_the_balls_way_escapes_and_stays_clear_of_its_true_motion_longer(world,
                                                                                  limits):
    """A resting arm with a ball flying at its elbow: staying put meets the ball's predicted
    motion; the escape found meets it later (or never), starts where it was asked to, ends at
    rest within the limits — and is free of the ball's *true* motion (the exact checker) for
    as long as it says, longer than staying put is."""
    q0, ball, tracks, t0 = _ball_at_the_elbow(world)
    escaper = _escaper(world, tracks, limits)
    staying = hold(q0, t0)
    t_e = t0 + 0.02
    move, t_move, t_stay = escaper.latest(staying, t0, t_e)
    assert t_e < t_stay < np.inf
    assert move is not None and t_move >= t_stay + 0.05
    assert move.t_start == pytest.approx(t_e)
    assert np.allclose(move.sample(t_e).q, q0) and np.allclose(move.end.qd, 0.0, atol=1e-9)
    truth = TrueWorld(world, (ball,))
    horizon = t0 + EXECUTOR.horizon_s
    ts = np.arange(t_e, min(t_move, horizon), 0.005)
    assert not any(truth.collides(move.sample(float(t)).q, float(t)) for t in ts)
    assert world.robot.within_limits(move.positions(t_e, move.t_end, 0.005)[1]).all()
    hit = [float(t) for t in np.arange(t0, horizon, 0.005) if truth.collides(q0, float(t))]
    assert hit and hit[0] >= t_stay - FINE_WINDOW_S - 1e-9    # the prediction is conservative
    assert hit[0] < min(t_move, horizon)


def test_no_escape_is_sought_for_a_motion_that_never_meets_the_obstacles_or_too_soon(
        world, limits):
    """A motion free of the predicted obstacles over the horizon needs no escape (a ball
    flying away from the arm, 1 m off); one that meets them before the escape could start
    cannot be helped by one."""
    q0, _, tracks, t0 = _ball_at_the_elbow(world)
    staying = hold(q0, t0)
    move, t_move, t_stay = _escaper(world, tracks, limits).latest(staying, t0, t0 + 0.59)
    assert move is None and t_move == -np.inf and t0 < t_stay <= t0 + 0.59
    elbow = world.robot.compute_joint_placements(q0)[3, :3, 3]
    away = MovingObstacle("ball", Shape("sphere", (0.08,)), np.eye(3),
                          elbow + np.array([0.0, 0.0, 1.0]), elbow + np.array([0.0, 0.0, 2.0]),
                          0.0, 0.8)
    gone = ObstacleTracks()
    for stamp in (t0 - 1 / 30, t0):
        gone.update(obstacles_at((away,), stamp), stamp)
    move, t_move, t_stay = _escaper(world, gone, limits).latest(staying, t0, t0 + 0.02)
    assert move is None and t_stay == np.inf


class _NoPlans:
    """A worker that is never asked for a plan here (the escape is the step's own answer)."""

    def submit(self, request):
        raise AssertionError("no plan is asked for")

    def poll(self, now):
        return None

    def cancel(self):
        pass


def test_an_overrunning_steps_escape_starts_where_the_loop_has_the_arm(world, limits):
    """A kicked arm beside a ball flying at its elbow, in a step that has run past its tick:
    until the step's answer is in, the loop commands the kick's immediate motion (here a
    join on, away from where the stop goes), not the stop the step installed. The escape
    must follow that motion to the tick the answer is in by and start from its state there
    — one started from the installed stop had the arm off it at the next step (a lag), and
    the lag's stop replaced it: tabletop_pole, seed 2, episode 1 at ``--compute-scale 2``
    collided in 3 of 3 replays (2 of 4 after)."""
    import time

    from chekhov.execute.executor import Executor
    from chekhov.execute.motion import Motion, ruckig_piece, stop_from
    q0, ball, _, t0 = _ball_at_the_elbow(world)
    _, goal = start_and_goal(world, 0, 0)
    ex = Executor(world, _NoPlans(), goal, EXECUTOR)
    for stamp in (t0 - 1 / 30, t0):
        ex.tracks.update(obstacles_at((ball,), stamp), stamp)
    bounds = Bounds(world.robot.lower, world.robot.upper)
    z = np.zeros_like(q0)
    kicked = State(q0, -0.1 * limits.velocity, z)
    join = ruckig_piece(kicked, State(q0 - 0.1, z, z), t0, limits, "join", bounds)
    assert join is not None
    ex.immediate_motion = hold(q0, 0.0).then(Motion((join,)))       # what the loop commands
    ex.motion = ex._step_motion = hold(q0, 0.0).then(stop_from(kicked, t0, limits, bounds))
    ex._wall0, ex._submit_wall = time.perf_counter() - 0.03, 0.0      # 30 ms spent
    assert ex._escape(t0, None)
    dt = EXECUTOR.control_dt_s
    t_e = min(p.t_start for p in ex.motion.pieces if p.kind == "dodge")
    assert t_e >= t0 + 5 * dt - 1e-9        # 30 ms spent and the search's 15: 5 ticks on
    for t in np.arange(t0, t_e + 1e-9, dt):
        a, b = ex.motion.sample(float(t)), ex.immediate_motion.sample(float(t))
        assert np.allclose(a.q, b.q, atol=1e-12) and np.allclose(a.qd, b.qd, atol=1e-12)
    assert not np.allclose(ex.motion.sample(t_e + 5 * dt).q,
                           ex.immediate_motion.sample(t_e + 5 * dt).q)
    _, Q = ex.motion.positions(t0, ex.motion.t_end, 0.005)
    assert world.robot.within_limits(Q).all() and np.allclose(ex.motion.end.qd, 0.0, atol=1e-9)


def test_a_ball_seen_once_is_fled_though_its_worst_case_ties_every_escape(world, limits):
    """A ball flying at a resting arm's elbow from 0.35 m, seen in one sensor frame only (its
    velocity unknown: a sphere growing at the speed bound): judged against that alone, no
    escape meets it a judging window later than staying put does. The escape taken is the
    one that meets the sphere growing at half the bound latest — and against the ball's
    *true* motion (the exact checker) it is in contact later than staying put is."""
    q0, _ = start_and_goal(world, 0, 1)
    elbow = world.robot.compute_joint_placements(q0)[3, :3, 3]
    d = np.array([-1.0, 0.0, 0.0])
    ball = MovingObstacle("ball", Shape("sphere", (0.06,)), np.eye(3), elbow - 0.35 * d,
                          elbow + 0.5 * d, 0.0, 0.8)
    t0, t_e = 0.1, 0.12
    tracks = ObstacleTracks()
    tracks.update(obstacles_at((ball,), t0), t0)
    assert not tracks.tracks["ball"].velocity_known
    staying = hold(q0, t0)
    worst_only = _escaper(world, tracks, limits)
    worst_only._slower_tie = lambda *args: None           # type: ignore[method-assign]
    _, t_move, t_stay = worst_only.latest(staying, t0, t_e)
    assert t_move < t_stay + FINE_WINDOW_S                # the worst case ties them all
    move, t_move, t_stay = _escaper(world, tracks, limits).latest(staying, t0, t_e)
    assert move is not None and t_move >= t_stay + FINE_WINDOW_S
    assert move.t_start == pytest.approx(t_e) and np.allclose(move.sample(t_e).q, q0)
    assert world.robot.within_limits(move.positions(t_e, move.t_end, 0.005)[1]).all()
    truth = TrueWorld(world, (ball,))
    ts = np.arange(t_e, t0 + 0.6, 0.005)
    hit_stay = next(float(t) for t in ts if truth.collides(q0, float(t)))
    hit_move = next((float(t) for t in ts
                     if truth.collides(move.sample(float(t)).q, float(t))), np.inf)
    assert hit_move > hit_stay
