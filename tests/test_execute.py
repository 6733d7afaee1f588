"""The reactive executive (chekhov.execute): joins and brakes within the limits, episodes that
reach their goal through kicks, goal changes and a forearm sweeping across, judged after the
fact by the exact checker against the obstacles' true poses; and ``chekhov react``."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from chekhov.cli import main
from chekhov.collision.path_check import exact_path_decision
from chekhov.execute.benchmark import ReactConfig, executive_planner, run_one
from chekhov.execute.evade import DODGE_CANDIDATES, STOP_APART_RAD, Evader, EvadeSettings
from chekhov.execute.evaluate import TrueWorld, evaluate_episode, limit_violations
from chekhov.execute.interface import ExecutorConfig
from chekhov.execute.motion import (
    Bounds,
    State,
    brake_along,
    hold,
    join,
    ruckig_piece,
    stop_from,
    trajectory_motion,
)
from chekhov.execute.near import ESCAPE_COST_S
from chekhov.execute.obstacles import MovingObstacle, ObstacleTracks
from chekhov.execute.script import (
    FIRST_APPEAR_S,
    SWEEP_M,
    EpisodeScript,
    GoalChange,
    Kick,
    make_script,
    start_and_goal,
)
from chekhov.execute.simulate import EpisodeRecord, SimConfig, escape_motions, shrunk_kick
from chekhov.execute.swerve import Swerver
from chekhov.robot.goal import Goal
from chekhov.scene.model import Shape
from chekhov.timing import TimingConfig, joint_limits, time_parameterize
from chekhov.world import World

CONFIG = ReactConfig(executor=ExecutorConfig(search_budget_s=None),
                     sim=SimConfig(charge_compute=False))
"""The executive's logic on a clock that does not charge its compute (its answers come on the
ticks the logic says, its searches unbounded in wall time); the charged clock has tests of its
own (``CHARGED``)."""
CHARGED = ReactConfig()
DT = CONFIG.executor.control_dt_s


@pytest.fixture(scope="module")
def world():
    # a world of its own: the executive sets its dynamic obstacles
    return World.load("tabletop_pole")


@pytest.fixture(scope="module")
def planner(world):
    return executive_planner("Roadmap+TrajOpt", world)


@pytest.fixture(scope="module")
def limits(world):
    return joint_limits(world.robot.velocity_limit, CONFIG.executor.timing)


def _fd_ok(ts, Q, V, limits, slack=1e-6):
    """Finite differences of positions and velocities within the limits (exact bounds by
    the mean value theorem)."""
    dt = np.diff(ts)[:, None]
    v = np.abs(np.diff(Q, axis=0)) / dt
    a = np.abs(np.diff(V, axis=0)) / dt
    return bool((v <= limits.velocity * (1 + slack)).all()
                and (a <= limits.acceleration * (1 + slack)).all())


def _sampled(motion, t0, t1, dt=1e-3):
    ts = np.arange(t0, t1, dt)
    S = [motion.sample(float(t)) for t in ts]
    return ts, np.array([s.q for s in S]), np.array([s.qd for s in S])


def test_join_from_a_moving_state_is_continuous_and_within_limits(world, limits, rng):
    robot = world.robot
    P = np.array([robot.lower * 0.3 + robot.upper * 0.7, robot.lower * 0.6 + robot.upper * 0.4])
    traj = time_parameterize(P, robot.joint_names, limits, TimingConfig(method="ruckig"))
    target = trajectory_motion(traj.trajectory, 0.0)
    qd = rng.uniform(-0.5, 0.5, robot.dof) * limits.velocity
    start = State(P[0] + 0.05, qd, np.zeros(robot.dof))
    joined = join(start, 1.0, target, 0.3, limits)
    assert joined is not None
    assert np.allclose(joined.sample(1.0).qd, qd, atol=1e-9)       # no velocity jump at start
    t_join = joined.pieces[0].t_end
    before, after = joined.sample(t_join - 1e-6), joined.sample(t_join + 1e-6)
    assert np.abs(before.qd - after.qd).max() < 1e-3               # none where it lands
    assert np.allclose(joined.end.q, P[1], atol=1e-6)
    ts, Q, V = _sampled(joined, 1.0, joined.t_end)
    assert _fd_ok(ts, Q, V, limits, slack=1e-3)


def test_brake_along_stays_on_the_path_and_stops_within_limits(world, limits):
    robot = world.robot
    P = np.array([robot.lower * 0.2 + robot.upper * 0.8, robot.lower * 0.7 + robot.upper * 0.3])
    z = np.zeros(robot.dof)
    piece = ruckig_piece(State(P[0], z, z), State(P[1], z, z), 0.0, limits, "plan")
    assert piece is not None
    from chekhov.execute.motion import Motion
    motion = Motion((piece,))
    t0 = 0.45 * piece.t_end
    brake = brake_along(motion, t0, limits)
    assert brake.t_end < piece.t_end - 1e-3                  # it stops before the end
    assert np.abs(brake.end.qd).max() == 0.0
    ts, Q, V = _sampled(brake, t0, brake.t_end)
    # on the motion's own path: near its positions sampled every 0.1 ms, in order
    _, path, _ = _sampled(motion, t0, piece.t_end, 1e-4)
    d = np.linalg.norm(Q[:, None, :] - path[None, :, :], axis=2)
    assert d.min(axis=1).max() < 1e-3
    assert np.all(np.diff(d.argmin(axis=1)) >= 0)             # never backwards
    assert _fd_ok(ts, Q, V, limits, slack=1e-3)
    assert np.allclose(brake.sample(t0).qd, motion.sample(t0).qd, atol=1e-9)


def test_brake_steps_resume_where_they_stopped(world, limits):
    """The compiled brake steps give the same rows whether they run on a grid sampled all at
    once with room for every row, or stop for more grid and more rows every few steps."""
    from chekhov.execute.brake_kernel import DONE, FULL, NEED_GRID, brake_steps
    from chekhov.execute.motion import (
        BRAKE_DT_S,
        BRAKE_END_SHARE,
        BRAKE_GRID_S,
        BRAKE_SHARE,
        Motion,
    )

    robot = world.robot
    P = np.array([robot.lower * 0.2 + robot.upper * 0.8, robot.lower * 0.7 + robot.upper * 0.3])
    z = np.zeros(robot.dof)
    piece = ruckig_piece(State(P[0], z, z), State(P[1], z, z), 0.0, limits, "plan")
    motion, t0 = Motion((piece,)), 0.4 * piece.t_end
    _, V, A = motion.states_at(t0 + BRAKE_GRID_S * np.arange(int(2 / BRAKE_GRID_S)))
    a, end_a = BRAKE_SHARE * limits.acceleration, BRAKE_END_SHARE * limits.acceleration

    def run(grid_rows, row_room):
        state, rows, n, g = np.array([0.0, t0, 1.0]), np.empty((row_room, 4)), 0, grid_rows
        whys = set()
        while True:
            n, why = brake_steps(V[:g], A[:g], t0, BRAKE_GRID_S, motion.t_end, a, end_a,
                                 BRAKE_DT_S, state, rows, n)
            whys.add(why)
            if why == DONE:
                return rows[:n], whys
            if why == NEED_GRID:
                g += grid_rows
            else:
                rows = np.vstack([rows, np.empty_like(rows)])

    whole, whys = run(len(V), 100_000)
    assert whys == {DONE} and len(whole) > 20 and whole[-1, 2] == 0.0
    pieces, whys = run(7, 3)
    assert whys == {DONE, NEED_GRID, FULL}
    assert np.array_equal(pieces, whole)


def test_brake_along_a_stiff_join_keeps_every_acceleration_within_the_limits(world, limits):
    """A brake of a Ruckig join (20x the timing's jerk: its acceleration changes fast) commands
    the exact state of its time scaling: accelerations within the limits at every instant,
    finite differences of the velocities too."""
    robot, rng = world.robot, np.random.default_rng(2)
    worst = 0.0
    for _ in range(40):
        P = robot.lower + rng.uniform(0.1, 0.9, (2, robot.dof)) * (robot.upper - robot.lower)
        traj = time_parameterize(P, robot.joint_names, limits, TimingConfig(method="ruckig"))
        start = State(P[0] + rng.uniform(-0.05, 0.05, robot.dof),
                      rng.uniform(-0.6, 0.6, robot.dof) * limits.velocity,
                      rng.uniform(-1, 1, robot.dof) * limits.acceleration)
        joined = join(start, 0.0, trajectory_motion(traj.trajectory, 0.0), 0.2, limits)
        assert joined is not None
        t0 = float(rng.uniform(0, joined.pieces[0].t_end))
        brake = brake_along(joined, t0, limits)
        ts, Q, V = _sampled(brake, t0, brake.t_end + 0.02, 2e-4)
        A = np.array([brake.sample(float(t)).qdd for t in ts])
        worst = max(worst, float((np.abs(A) / limits.acceleration).max()))
        assert _fd_ok(ts[::50], Q[::50], V[::50], limits)
        assert np.abs(brake.end.qd).max() < 1e-9
    assert worst <= 1 + 1e-9


def test_a_stop_after_a_kick_stays_within_the_position_limits(world, limits):
    """Ruckig does not keep position limits; a stop from a joint rushing at its upper limit
    (accelerating towards it, room to stop at full deceleration) stays within them."""
    robot = world.robot
    mid = (robot.lower + robot.upper) / 2
    qd = np.where(np.arange(robot.dof) % 2 == 0, 1.0, -1.2) * np.minimum(limits.velocity, 1.2)
    qd[0] = 1.2
    q = mid.copy()
    q[0] = robot.upper[0] - qd[0] ** 2 / (2 * limits.acceleration[0]) - 0.003
    qdd = np.zeros(robot.dof)
    qdd[0] = limits.acceleration[0]
    bounds = Bounds(robot.lower, robot.upper)
    stop = stop_from(State(q, qd, qdd), 0.0, limits, bounds)
    ts, Q, V = _sampled(stop, 0.0, stop.t_end + 0.01)
    assert robot.within_limits(Q, tol=1e-6).all(), float((Q - robot.upper).max())
    assert np.abs(stop.end.qd).max() < 1e-9
    assert _fd_ok(ts, Q, V, limits)


def test_a_moving_arm_whose_stop_hits_the_scene_escapes_exactly_free(world, limits):
    """Moving arms (random free configurations, 0.5-1× the slowest joint's limit) whose stop
    runs into the scene by the exact checker: within 400 states, one whose escape is free by
    the exact decision at 1 ms steps and within the limits (finite differences)."""
    robot = world.robot
    bounds = Bounds(robot.lower, robot.upper)
    evader = _scene_evader(world, limits)
    rng = np.random.default_rng(0)
    rescued = 0
    for _ in range(400):
        q = robot.sample_uniform(rng, 1)[0]
        d = rng.normal(size=robot.dof)
        qd = d / np.abs(d).max() * rng.uniform(0.5, 1.0) * limits.velocity.min()
        start = State(q, qd, np.zeros_like(q))
        if not world.fast.is_valid(q):
            continue
        stop = stop_from(start, 0.0, limits, bounds)
        _, Q, _ = _sampled(stop, 0.0, stop.t_end)
        if exact_path_decision(world.fast, world.exact, Q, 2).valid:
            continue
        for move in evader.escapes(start, 0.0):
            ts, Q, V = _sampled(move, 0.0, move.t_end + 0.01)
            if exact_path_decision(world.fast, world.exact, Q, 2).valid:
                assert robot.within_limits(Q, tol=1e-6).all() and _fd_ok(ts, Q, V, limits)
                rescued += 1
                break
        if rescued:
            break
    assert rescued == 1


def _scene_evader(world, limits):
    """An evader with the executive's settings (seed 0) in ``world`` holding no dynamic
    obstacles (the fast and the exact checker cleared)."""
    world.fast.set_obstacles({})
    world.exact.set_obstacles({})
    return _seeded_evader(world, ObstacleTracks(), limits, seed=0)


def _heading_into_the_scene(world, limits, rng, ahead_s=(0.01, 0.03)):
    """A moving arm ``ahead_s`` (10-30 ms) from the scene at 0.5-1x the slowest joint's
    velocity limit, heading straight at it (the first contact along a random direction, exact
    checker)."""
    robot = world.robot
    while True:
        q = robot.sample_uniform(rng, 1)[0]
        d = rng.normal(size=robot.dof)
        d /= np.abs(d).max()
        Q = q + np.arange(0.0, 1.0, 0.002)[:, None] * d
        if not world.exact.is_valid(q) or not robot.within_limits(Q).all():
            continue
        free = np.array([world.exact.is_valid(x) for x in Q])
        if free.all():
            continue
        speed = rng.uniform(0.5, 1.0) * limits.velocity.min()
        q0 = Q[int(np.argmin(free)) - 1] - d * speed * rng.uniform(*ahead_s)
        if world.exact.is_valid(q0) and robot.within_limits(q0[None]).all():
            return State(q0, d * speed, np.zeros_like(q0))


def test_a_kicked_arm_about_to_hit_the_scene_swerves_exactly_free(world, limits):
    """Arms heading into the scene 10-30 ms away, whose stop is in contact within a tick or
    two: the immediate motion (fast checks only) is a constant-acceleration swerve on some
    (at least 1 of 60 seeded states); every swerve is free by the exact decision at 1 ms
    steps over its swerve (its stop too, when one was found whose stop is safe), within the
    limits (finite differences) and at rest at its end."""
    robot = world.robot
    evader = _scene_evader(world, limits)
    swerver = Swerver(evader)
    rng = np.random.default_rng(0)
    swerves = 0
    for _ in range(60):
        start = _heading_into_the_scene(world, limits, rng)
        move = swerver.immediate([], start, 0.0, None)
        if move.pieces[0].kind != "swerve":
            assert move.pieces[0].kind == "brake"        # the stop, the last resort
            continue
        swerves += 1
        ts, Q, V = _sampled(move, 0.0, move.t_end + 0.01)
        whole = evader.safe_in_time([move], 0.0, 0.0)[0]
        span = ts <= (move.t_end if whole else move.pieces[0].t_end)
        assert exact_path_decision(world.fast, world.exact, Q[span], 2).valid
        assert robot.within_limits(Q, tol=1e-6).all() and _fd_ok(ts, Q, V, limits)
        assert np.abs(move.end.qd).max() < 1e-9
    assert swerves >= 1


def test_the_swerve_filter_keeps_every_swerve_that_is_safe_in_time(world, limits):
    """The swerves' first filter (the swerve alone against each window's sweep, no margin)
    saves work for the test of the whole swerve and stop (safe in time, no margin) and is
    never stricter: moving arms around the elbow a ball flies at — every random swerve safe in
    time passes it, and some are (at least 10 of 30 x 32). Against the whole horizon's
    sweep at once, as the filter had it, each of those would have been dropped."""
    from chekhov.execute.motion import Motion, accelerating
    from chekhov.execute.obstacles import predicted_obstacles
    from chekhov.execute.swerve import SWERVE_S
    q0, _, tracks, t0 = _ball_at_the_elbow(world, 0.06)
    c = CONFIG.executor
    bounds = Bounds(world.robot.lower, world.robot.upper)
    evader = _seeded_evader(world, tracks, limits)
    swerver = Swerver(evader)
    seen = predicted_obstacles(tracks, t0, c.horizon_s, c.margin_m)
    packs = evader.windows(t0, 0.0)
    world.fast.set_obstacles(seen)
    rng = np.random.default_rng(0)
    safe_total = dropped_by_union = 0
    for _ in range(30):
        d = rng.normal(size=len(q0))
        qd = d / np.abs(d).max() * rng.uniform(0.2, 1.0) * limits.velocity.min()
        now = State(q0 + rng.uniform(-0.1, 0.1, len(q0)), qd, np.zeros_like(q0))
        A = rng.uniform(-1.0, 1.0, (32, len(q0))) * limits.acceleration
        clear = swerver._swerves_clear(now, t0, A, packs)
        moves = []
        for a in A:
            piece = accelerating(now, t0, a, SWERVE_S, limits)
            stop = stop_from(piece.sample(SWERVE_S), piece.t_end, limits, bounds)
            moves.append(Motion((piece, *stop.pieces)))
        safe = evader.safe_in_time(moves, t0, 0.0)
        assert not (safe & ~clear).any()
        union = np.array([world.fast.valid(m.positions(t0, t0 + SWERVE_S, c.check_dt_s)[1])
                          .all() for m in moves])
        safe_total += int(safe.sum())
        dropped_by_union += int((safe & ~union).sum())
    world.fast.set_obstacles({})
    assert safe_total >= 10 and dropped_by_union == safe_total


def test_a_kick_never_throws_a_moving_arm_into_the_scene_faster_than_any_reaction(world,
                                                                                   limits):
    """Scripted kicks leave a way out: on arms heading into the scene 10-30 ms away, a kick
    of up to 0.1 rad per joint is dropped or shrunk so that the kicked arm going on at its
    velocity for 0.1 s is free (the exact checker at 1 ms of motion, not the decision the
    kick used); on arms at rest in free space, kicks that land free and within the limits are
    kept whole."""
    robot = world.robot
    world.fast.set_obstacles({})
    world.exact.set_obstacles({})
    rng = np.random.default_rng(5)
    dropped = 0
    for _ in range(20):
        start = _heading_into_the_scene(world, limits, rng)
        dq = shrunk_kick(world, start.q, start.qd, rng.uniform(-0.1, 0.1, robot.dof), 4,
                         limits)
        if dq is None:
            dropped += 1
            continue
        Q = start.q + dq + np.arange(0.0, 0.1 + 1e-9, 1e-3)[:, None] * start.qd
        assert all(world.exact.is_valid(q) for q in Q)
    whole = 0
    for _ in range(40):
        q = robot.sample_uniform(rng, 1)[0]
        dq = rng.uniform(-0.1, 0.1, robot.dof)
        z = np.zeros_like(q)
        if not (world.exact.is_valid(q + dq) and robot.within_limits((q + dq)[None]).all()):
            continue
        assert np.array_equal(shrunk_kick(world, q, z, dq, 4, limits), dq)
        whole += 1
    assert dropped >= 10 and whole >= 10


def test_a_kick_leaves_a_moving_arm_a_motion_within_the_limits_that_escapes(world, limits):
    """On arms heading into the scene at full speed 0.1-0.3 s away (going on for 0.1 s is
    free, stopping may not be), a kept kick leaves an escape: one of the escape motions (the
    brake, then constant accelerations) is exactly free at 1 ms steps for 0.5 s and within
    the joint limits; some kicks are shrunk or dropped for it."""
    robot = world.robot
    world.fast.set_obstacles({})
    world.exact.set_obstacles({})
    rng = np.random.default_rng(3)
    kept = changed = 0
    for _ in range(16):
        start = _heading_into_the_scene(world, limits, rng, ahead_s=(0.1, 0.3))
        qd = start.qd / np.abs(start.qd).max() * limits.velocity.min()   # full speed
        dq0 = rng.uniform(-0.1, 0.1, robot.dof)
        dq = shrunk_kick(world, start.q, qd, dq0, 4, limits)
        changed += dq is None or not np.array_equal(dq, dq0)
        if dq is None:
            continue
        kept += 1
        escapes = escape_motions(start.q + dq, qd, limits, 501, 256, np.random.default_rng(0),
                                 dt_s=1e-3)   # the kick's own motions, 10x finer
        assert any(robot.within_limits(Q).all() and all(world.exact.is_valid(q) for q in Q)
                   for Q in escapes)
    assert kept >= 4 and changed >= 4


def test_a_kick_never_throws_the_arm_into_the_forearms_way(world, limits):
    """A kick must leave the arm a way out of the forearm's true motion too: thrown where a
    ball (0.06 m, 1 m/s) passes 60 ms later — no motion within the limits from rest gets the
    hand 0.1 m aside that soon — the kick is shrunk or dropped, and what is kept leaves one
    of the kick's escape motions clear of the ball and the scene for 0.5 s (exact checker, 1
    ms steps); the same ball 1 m away changes no kick."""
    from chekhov.execute.truth import TrueWorld
    robot = world.robot
    world.fast.set_obstacles({})
    world.exact.set_obstacles({})
    rng = np.random.default_rng(5)
    ball = Shape("sphere", (0.06,))
    shrunk = 0
    for index in range(6):
        q = start_and_goal(world, 0, index)[0]
        dq = rng.uniform(-0.1, 0.1, robot.dof)
        zero = np.zeros(robot.dof)
        if not np.array_equal(shrunk_kick(world, q, zero, dq, 4, limits), dq):
            continue                         # shrunk for the scene alone: not this test's
        p_hand = robot.compute_ee_pose(q + dq)[:3, 3]
        way = np.array([1.0, 0.0, 0.0])
        for offset, near in ((np.zeros(3), True), (np.array([0.0, 0.0, 1.0]), False)):
            p = p_hand + offset
            truth = TrueWorld(world, (MovingObstacle("ball", ball, np.eye(3), p - 0.06 * way,
                                                     p + 0.5 * way, 0.0, 1.0),))
            kept = shrunk_kick(world, q, zero, dq, 4, limits, truth, 0.0)
            if not near:
                assert np.array_equal(kept, dq)
                continue
            assert kept is None or np.abs(kept).max() < np.abs(dq).max()
            shrunk += 1
            if kept is not None:         # a way out, at 10x finer steps
                ts = np.arange(0, 0.501, 1e-3)
                assert any(robot.within_limits(Q).all() and not any(
                    truth.collides(x, t) or not world.exact.is_valid(x) for x, t in
                    zip(Q, ts, strict=True)) for Q in escape_motions(
                    q + kept, zero, limits, len(ts), 256, np.random.default_rng(0), 1e-3))
    assert shrunk >= 3


def test_a_kicked_arm_whose_join_back_is_free_is_joined_back_at_once(world, limits):
    """The immediate motion after a kick in open space is the join back (the first smooth
    move the fast checker calls free), not a stop or a swerve."""
    rng = np.random.default_rng(3)
    robot = world.robot
    bounds = Bounds(robot.lower, robot.upper)
    swerver = Swerver(_scene_evader(world, limits))
    joined = 0
    for _ in range(20):
        q = robot.sample_uniform(rng, 1)[0]
        if not world.fast.is_valid(q):
            continue
        start = State(q + 0.01, np.zeros_like(q), np.zeros_like(q))
        back = join(start, 0.0, hold(q, 0.0), 0.0, limits, bounds)
        if back is None or not world.fast.valid(back.positions(0.0, back.t_end + 0.1,
                                                               0.01)[1]).all():
            continue
        assert swerver.immediate([back], start, 0.0, None) is back
        joined += 1
    assert joined >= 5


def _script(world, index, **kw):
    q0, goal = start_and_goal(world, 0, index)
    return EpisodeScript(index, q0, goal, "", **kw)


def _meets(world, q, goal):
    T = world.robot.compute_ee_pose(q)
    return float(np.linalg.norm(T[:3, 3] - goal.T_world_ee[:3, 3])) <= goal.position_tolerance


def test_undisturbed_episode_reaches_the_goal_within_limits(world, planner, limits):
    script = _script(world, 0)
    rec = run_one(world, planner, script, 20.0, CONFIG)
    assert rec.reached and rec.t_reached < 20.0
    assert _meets(world, rec.q[-1], script.goal)
    check = evaluate_episode(world, rec, limits, 0.1)
    assert not check.collision and check.limit_violations == 0
    assert rec.counters.replans == 1 and not rec.reactions


def _in_the_scene(world, q0):
    """A configuration within the limits just past the first contact with the static scene
    (exact checker) along a seeded random direction from q0 (K,) rad."""
    world.set_obstacles({})          # the static scene only (tests before may leave some)
    rng = np.random.default_rng(5)
    for _ in range(400):
        d = rng.normal(size=q0.shape)
        d /= np.linalg.norm(d)
        hits = [s for s in np.linspace(0.0, 0.8, 161)[1:]
                if not world.exact.is_valid(q0 + s * d)]
        q = q0 + (hits[0] + 0.01) * d if hits else None
        if q is not None and world.robot.within_limits(q[None])[0] and \
                not world.exact.is_valid(q):
            return q
    raise AssertionError("no configuration in the scene found")


def test_the_fast_checkers_false_alarms_are_not_taken_for_an_arm_in_the_scene(world, limits):
    """Configurations just short of the first contact with the static scene along seeded
    random directions (bisected on the exact checker to 1e-6 of the step): the fast checker
    calls some of them colliding (its "free" is proved, its "collision" is not), and those
    are not in the scene for the evader (which would spend a step finding a way out of a
    collision that is not there: ~100 ms in one kitchen step); the configurations just past
    the contact are."""
    world.set_obstacles({})
    evader = _seeded_evader(world, ObstacleTracks(), limits)
    robot, rng = world.robot, np.random.default_rng(1)
    false_alarms = 0
    for _ in range(200):
        q0 = robot.sample_uniform(rng, 1)[0]
        d = rng.normal(size=robot.dof)
        q1 = q0 + 0.8 * d / np.linalg.norm(d)
        if not (world.exact.is_valid(q0) and robot.within_limits(q1[None])[0]) or \
                world.exact.is_valid(q1):
            continue
        lo, hi = 0.0, 1.0
        while hi - lo > 1e-6:
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if world.exact.is_valid(q0 + mid * (q1 - q0)) else (lo, mid)
        free, hit = q0 + lo * (q1 - q0), q0 + hi * (q1 - q0)
        assert evader.in_scene(hit)
        if not world.fast.valid(free[None])[0]:
            assert not evader.in_scene(free)
            false_alarms += 1
            if false_alarms == 5:
                break
    assert false_alarms == 5


def test_an_arm_resting_in_the_scene_gets_out_and_reaches_its_goal(world, planner, limits):
    """A stop after a kick can leave the arm in contact with the scene: no plan starts there
    and every dodge starts in collision. The executive gets it out (exactly free within
    Evader.unstick's time, judged at 1 ms steps by the exact checker) and reaches the goal."""
    from chekhov.execute.evade import UNSTICK_S
    q0, goal = start_and_goal(world, 0, 0)
    stuck = _in_the_scene(world, q0)
    rec = run_one(world, planner, EpisodeScript(0, stuck, goal, ""), 20.0, CONFIG)
    assert rec.reached and _meets(world, rec.q[-1], goal)
    assert rec.counters.dodges >= 1
    ts = np.arange(0.0, rec.times[-1], 1e-3)
    Q = np.array([np.interp(ts, rec.times, rec.q[:, j]) for j in range(len(q0))]).T
    out = next(i for i, q in enumerate(Q) if world.exact.is_valid(q))
    assert ts[out] <= UNSTICK_S + 2 * DT
    free = exact_path_decision(world.fast, world.exact, Q[out + 1:], 1)
    assert free.valid
    assert evaluate_episode(world, rec, limits, 0.1).limit_violations == 0


def test_the_way_out_is_the_soonest_out_nearest_target_judged_one_by_one(world, limits):
    """``Evader.unstick`` (moves made and judged in chunks, stopping at one out at once)
    against its statement, target by target: of the moves from the stuck arm (moving) to the
    dodge targets that stay within the limits, the one whose configurations are free of
    their window's sweep (no margin) from the earliest check step on, within UNSTICK_S — the
    nearest target on a tie; with a ball flying at the arm. And with its deadline past, a
    way out of the first chunk that is one by the same statement."""
    from chekhov.execute.evade import UNSTICK_S, window_edges
    from chekhov.execute.motion import Motion
    q0, _, tracks, t0 = _ball_at_the_elbow(world, 0.06)
    stuck = _in_the_scene(world, q0)
    c = CONFIG.executor
    bounds = Bounds(world.robot.lower, world.robot.upper)
    z = np.zeros_like(q0)
    now = State(stuck, 0.1 * limits.velocity * np.sign(np.arange(len(q0)) % 2 - 0.5), z)

    def out_of(move, packs):       # the first check step from which all is free, or None
        edges = window_edges(c.horizon_s)
        ts, Q = move.positions(t0, max(t0 + edges[-1], move.t_end), c.check_dt_s)
        if not world.robot.within_limits(Q).all():
            return None
        free = [world.fast.valid_in(packs[min(int(np.searchsorted(
            edges, t - t0 + 1e-9, side="right")) - 1, len(packs) - 1)], q[None])[0]
            for t, q in zip(ts, Q, strict=True)]
        out = max([i + 1 for i, f in enumerate(free) if not f], default=0)
        return out if out < len(ts) and ts[out] - t0 <= UNSTICK_S else None

    reference = _seeded_evader(world, tracks, limits)
    packs = reference.windows(t0, 0.0)
    best = None
    for q in reference.targets(now, t0):
        if not world.fast.valid_in(packs[-1], q[None])[0]:
            continue
        piece = ruckig_piece(now, State(q, z, z), t0, limits, "dodge", bounds)
        out = None if piece is None else out_of(Motion((piece,)), packs)
        if out is not None and (best is None or out < best[0]):
            best = (out, q)
    move = _seeded_evader(world, tracks, limits).unstick(now, t0)
    assert best is not None and move is not None
    assert np.allclose(move.end.q, best[1])
    cut = _seeded_evader(world, tracks, limits).unstick(now, t0, deadline=0.0)
    if cut is not None:
        assert out_of(cut, packs) is not None


def test_a_kicked_arm_in_the_scene_gets_out_though_every_search_is_cut(world, planner):
    """A kick that leaves the arm in the static scene while an obstacle is tracked, and a
    search budget that every search overruns: no dodge can be safe from there (each starts in
    collision), so none is searched for and the way out (Evader.unstick) is taken at once.
    With the dodge search cut at every step, a replayed kitchen episode's arm had stood in the
    scene for ~1000 ticks."""
    import time

    from chekhov.execute.evade import UNSTICK_S
    from chekhov.execute.executor import Executor
    from chekhov.execute.obstacles import obstacles_at
    from chekhov.execute.worker import InlineWorker
    q0, goal = start_and_goal(world, 0, 0)
    stuck = _in_the_scene(world, q0)
    far = np.array([0.0, -2.5, 1.0])          # m: tracked, nowhere near the arm
    ball = MovingObstacle("ball", Shape("sphere", (0.05,)), np.eye(3), far,
                          far + np.array([0.3, 0.0, 0.0]), 0.0, 0.5)
    ex = Executor(world, InlineWorker(world, planner, CONFIG.executor.timing), goal,
                  replace(CONFIG.executor, search_budget_s=1e-9))
    t0 = 0.5
    for stamp in (t0 - 1 / 30, t0):
        ex.tracks.update(obstacles_at((ball,), stamp), stamp)
    ex._deadline = time.perf_counter()           # the step's budget: spent
    z = np.zeros_like(q0)
    move = ex._after_kick(State(stuck, z, z), t0)
    assert move.kind_at(t0 + DT) == "dodge" and ex.counters.safe_stops == 0
    _, Q = move.positions(t0, t0 + UNSTICK_S + DT, 1e-3)
    assert any(world.exact.is_valid(q) for q in Q)


def test_a_kick_is_rejoined_at_the_next_tick(world, planner, limits, rng):
    plain = run_one(world, planner, _script(world, 1), 20.0, CONFIG)
    dq = np.full(world.robot.dof, 0.04) * np.sign(rng.uniform(-1, 1, world.robot.dof))
    script = _script(world, 1, kicks=(Kick(0.5 * plain.t_reached, dq),))
    rec = run_one(world, planner, script, 20.0, CONFIG)
    assert len(rec.kicks_applied) == 1 and rec.kicked.sum() == 1
    kick = [r for r in rec.reactions if r.kind == "kick"]
    assert len(kick) == 1 and kick[0].t_reacted is not None
    assert kick[0].t_reacted - kick[0].t_observed <= DT + 1e-9
    assert rec.reached and _meets(world, rec.q[-1], script.goal)
    assert evaluate_episode(world, rec, limits, 0.1).limit_violations == 0


def test_a_goal_change_mid_motion_ends_at_the_new_goal(world, planner, limits):
    from chekhov.cases import task_targets
    plain = run_one(world, planner, _script(world, 2), 20.0, CONFIG)
    first = _script(world, 2)
    other = next(t for t in task_targets(world).pregrasps
                 if np.linalg.norm(t.T[:3, 3] - first.goal.T_world_ee[:3, 3]) > 0.1)
    new_goal = Goal.pose(other.T)
    script = _script(world, 2, goal_changes=(GoalChange(0.4 * plain.t_reached, new_goal,
                                                        other.label),))
    rec = run_one(world, planner, script, 20.0, CONFIG)
    assert rec.reached
    assert _meets(world, rec.q[-1], new_goal) and not _meets(world, rec.q[-1], first.goal)
    check = evaluate_episode(world, rec, limits, 0.1)
    assert not check.collision and check.limit_violations == 0


def test_scripted_episodes_never_collide_with_the_true_forearm(world, planner, limits):
    reached = 0
    for index in range(3):
        plain = run_one(world, planner, _script(world, index), 20.0, CONFIG)
        ee = world.robot.compute_ee_poses(plain.q)[:, :3, 3]
        script = make_script(world, 0, index, plain.t_reached, ee, plain.q)
        assert len(script.obstacles) == 3 and script.kicks and script.goal_changes
        task = script.task_only()           # the deadline's reference: the goal change only
        assert task.goal_changes == script.goal_changes and not (task.obstacles or task.kicks)
        t_in = script.obstacles[0].t_start       # it appears clear of the arm (coal's distance)
        q_then = plain.q[min(int(t_in / plain.t_reached * len(plain.q)), len(plain.q) - 1)]
        assert TrueWorld(world, script.obstacles).clearance(q_then, t_in) >= 0.1
        rec = run_one(world, planner, script, 3 * plain.t_reached + 4, CONFIG)
        check = evaluate_episode(world, rec, limits, 0.15)
        assert not check.collision, f"episode {index}: contact at {check.first_contact_s} s"
        assert check.limit_violations == 0
        assert check.min_clearance_m > 0
        reached += rec.reached
    assert reached >= 2


def test_charged_compute_episodes_stay_within_limits(world, planner, limits):
    """The same scripted episodes with the executive's own compute charged on the clock
    (steps that overrun miss ticks; the arm follows the motion it had, then joins back).

    The limits hold in every episode whatever this machine's speed: joins, brakes and dodges
    are built within them. Contact is not promised here: on the charged clock an episode
    depends on how fast this machine runs the executive. Episode 1's forearm stays within a
    few centimetres of the arm for about two seconds, and on this project's machine the least
    clearance there was 30, 47, 8 and 6 mm in four runs; a CI machine touched it (11 mm deep
    at 2.3 s). At most one episode in three may touch. On the unit's own clock, none does
    (``test_scripted_episodes_never_collide_with_the_true_forearm``); the rate of contact on
    the charged clock is measured by ``chekhov react`` (issue 18's target of none is not
    met)."""
    reached = touched = 0
    for index in range(3):
        plain = run_one(world, planner, _script(world, index), 20.0, CHARGED)
        ee = world.robot.compute_ee_poses(plain.q)[:, :3, 3]
        script = make_script(world, 0, index, plain.t_reached, ee, plain.q)
        rec = run_one(world, planner, script, 3 * plain.t_reached + 4, CHARGED)
        check = evaluate_episode(world, rec, limits, 0.15)
        assert check.limit_violations == 0, check.violation_kinds
        touched += check.collision
        reached += rec.reached
    assert touched <= 1 and reached >= 2


def test_a_step_that_overruns_its_tick_is_charged_on_the_clock(world, planner, limits):
    """Every step that changes the motion is made to take 35 ms (its measured wall time
    replaced): the arm follows the motion commanded before that step until the next step,
    4 ticks on, each reaction answered in it starts no earlier than 4 ticks after it was seen,
    the arm off the new motion is joined back ("lag", not counted as a disturbance), and
    the episode stays within the limits and reaches its goal."""
    from chekhov.execute.executor import Executor
    from chekhov.execute.simulate import run_episode
    from chekhov.execute.worker import InlineWorker

    class SlowExecutor(Executor):
        def __init__(self, *args):
            super().__init__(*args)
            self.before = {}

        def step(self, obs):
            motion = self.motion
            cmd = super().step(obs)
            if motion is not None and self.motion is not motion:
                # the loop's motion meanwhile: the join back after a kick, else the one it had
                self.before[round(obs.t / DT)] = self.immediate_motion or motion
                self.counters.step_wall_s[-1] = 0.035
            return cmd

    plain = run_one(world, planner, _script(world, 0), 20.0, CONFIG)
    ee = world.robot.compute_ee_poses(plain.q)[:, :3, 3]
    script = make_script(world, 0, 0, plain.t_reached, ee, plain.q)
    ex = SlowExecutor(world, InlineWorker(world, planner, CHARGED.executor.timing),
                      script.goal, CHARGED.executor)
    rec = run_episode(world, ex, script, 3 * plain.t_reached + 4, CHARGED.sim)
    ticks = {round(t / DT): i for i, t in enumerate(rec.times)}
    slow = [k for k in ex.before if k in ticks]
    assert len(slow) >= 3
    # until the next step, 4 ticks on, the arm follows the motion of the last step in time
    # (the one before a slow step, unless that step was slow too), or the join back after a
    # kick (or a lag) seen in the slow step
    kicked = {round(r.t_observed / DT) for r in rec.reactions if r.kind in ("kick", "lag")}
    followed = [k for k in slow if k + 4 in ticks and (k - 4 not in slow or k in kicked)]
    assert followed
    for k in followed:
        m = ex.before[k]
        for j in (1, 2, 3, 4):
            if rec.kicked[ticks[k + j]]:     # a scripted kick on a missed tick: from there
                break
            assert np.allclose(rec.q[ticks[k + j]], m.sample((k + j) * DT).q, atol=1e-12)
    answered = [r for r in rec.reactions if r.kind != "lag" and r.t_reacted is not None]
    assert answered and all(r.t_reacted - r.t_observed >= 4 * DT - 1e-9 for r in answered
                            if round(r.t_observed / DT) in slow)
    assert any(r.kind == "lag" for r in rec.reactions)
    check = evaluate_episode(world, rec, limits, 0.15)
    assert check.limit_violations == 0, check.violation_kinds
    assert rec.reached


def test_run_episode_refuses_an_executor_counted_at_another_scale(world, planner):
    """A SimConfig that asks for 3x-slower compute with an executor that counts 1x would
    silently simulate the fast machine: run_episode refuses it before the first tick."""
    from chekhov.execute.executor import Executor
    from chekhov.execute.simulate import run_episode
    from chekhov.execute.worker import InlineWorker

    script = _script(world, 0)
    ex = Executor(world, InlineWorker(world, planner, CHARGED.executor.timing), script.goal,
                  CHARGED.executor)
    with pytest.raises(ValueError, match="wall_scale=3"):
        run_episode(world, ex, script, 5.0, replace(CHARGED.sim, compute_scale=3.0))
    assert ex.counters.step_wall_s == []


def test_the_forearm_appears_clear_of_the_arm(world, planner):
    """Along three undisturbed motions, 20 scripts' forearms each appear at least 0.15 m from
    the arm by coal's distance (its whole body kept 0.3 m from the arm's skeleton: its centre
    alone had let forearms appear 8 cm from the arm here, and 5 cm in the Panda's cage, 90 ms
    from contact)."""
    gaps = []
    for episode in range(3):
        plain = run_one(world, planner, _script(world, episode), 20.0, CONFIG)
        ee = world.robot.compute_ee_poses(plain.q)[:, :3, 3]
        for index in range(20):
            script = make_script(world, 0, index, plain.t_reached, ee, plain.q)
            if not script.obstacles:
                continue
            t_in = script.obstacles[0].t_start
            q = plain.q[min(int(t_in / plain.t_reached * len(plain.q)), len(plain.q) - 1)]
            gaps.append(TrueWorld(world, script.obstacles).clearance(q, t_in))
    assert len(gaps) >= 45 and min(gaps) >= 0.15, sorted(gaps)[:3]


def test_the_forearm_enters_from_beyond_the_arms_reach(world, planner):
    """A forearm sets out where no configuration of the arm touches it — 400 random ones,
    free or not, so whatever route the executed arm has taken (coal's distance at the instant
    it appears) — or, when it would have had to set out before the episode began, is there at
    ``FIRST_APPEAR_S``, clear of the arm at its start. Two Panda scenes (the Panda's reach is
    short enough that some forearms set out within the episode) and the pole's table."""
    seen = {"far": 0, "early": 0}
    for name in ("panda_cage", "panda_table_shelf", "tabletop_pole"):
        w = world if name == world.scene.name else World.load(name)
        p = planner if w is world else executive_planner("Roadmap+TrajOpt", w)
        Q = w.robot.sample_uniform(np.random.default_rng(5), 400)
        plain = run_one(w, p, _script(w, 0), 20.0, CONFIG)
        ee = w.robot.compute_ee_poses(plain.q)[:, :3, 3]
        for index in range(8):
            arm = make_script(w, 0, index, plain.t_reached, ee, plain.q).obstacles
            assert arm, (name, index)
            truth, t_in = TrueWorld(w, arm), arm[0].t_start
            if t_in > FIRST_APPEAR_S:
                seen["far"] += 1
                assert min(truth.clearance(q, t_in) for q in Q) > 0.1, (name, index)
            else:
                seen["early"] += 1
                assert t_in == FIRST_APPEAR_S
                assert truth.clearance(plain.q[0], t_in) > 0.15, (name, index)
    assert seen["far"] >= 3 and seen["early"] >= 3, seen


def test_an_arm_at_rest_beside_a_still_obstacle_gets_its_plan(world, planner, limits):
    """A forearm standing still 2 cm from the resting arm (inside the 4 cm margin, no
    contact): evading finds nothing to do, and the plan asked for is not cancelled by it
    (it had been, on every sensor frame: the arm never left)."""
    from chekhov.execute.evaluate import TrueWorld
    from chekhov.execute.executor import Executor, Observation
    from chekhov.execute.obstacles import obstacles_at
    from chekhov.execute.worker import InlineWorker
    q0, goal = start_and_goal(world, 0, 0)
    elbow = world.robot.compute_joint_placements(q0)[3, :3, 3]

    def ball(d):
        p = elbow + np.array([0.0, 0.0, d])
        return MovingObstacle("ball", Shape("sphere", (0.05,)), np.eye(3), p,
                              p + np.array([1e-9, 0.0, 0.0]), 0.0, 1e-12)
    lo, hi = 0.0, 0.5                       # the height at which the ball is 2 cm clear
    for _ in range(30):
        mid = (lo + hi) / 2
        clear = TrueWorld(world, (ball(mid),)).clearance(q0, 0.0)
        lo, hi = (mid, hi) if clear < 0.02 else (lo, mid)
    still = (ball(hi),)
    executor = Executor(world, InlineWorker(world, planner, CONFIG.executor.timing), goal,
                        CONFIG.executor)
    q, qd = q0.copy(), np.zeros_like(q0)
    for i in range(300):
        t = i * DT
        frame = obstacles_at(still, t - 0.04) if i % 3 == 0 and t >= 0.04 else None
        cmd = executor.step(Observation(t, q, qd, frame, t - 0.04 if frame else None))
        q, qd = cmd.q, cmd.qd
    assert executor.counters.replans >= 1
    assert float(np.abs(q - q0).max()) > 0.05          # it left


def test_an_obstacle_seen_once_may_be_anywhere_its_speed_bound_takes_it():
    """A ball seen in one sensor frame (its velocity unknown) is predicted, with a speed
    bound, as one ball where it was seen, grown by the margin and by how far that speed takes
    it by the horizon's end; without a bound, as standing still. Once a second frame gives
    its velocity it is copies along its line, and a point behind it is no longer covered."""
    from chekhov.execute.obstacles import predicted_obstacles
    ball = Shape("sphere", (0.05,))
    T = np.eye(4)
    T[:3, 3] = (0.5, 0.0, 1.0)
    tracks = ObstacleTracks()
    tracks.update({"ball": (ball, T)}, 1.0)

    def covers(pred, point):
        return any(np.linalg.norm(point - P[:3, 3]) <= shape.size[0]
                   for shape, P in pred.values())
    bounded = predicted_obstacles(tracks, 1.1, 0.5, 0.04, speed_bound_m_s=1.0)
    assert len(bounded) == 1
    radius = 0.05 + 0.04 + 1.0 * (1.1 + 0.5 - 1.0)
    for d in np.eye(3):
        assert covers(bounded, T[:3, 3] + (radius - 1e-9) * d)
        assert covers(bounded, T[:3, 3] - (radius - 1e-9) * d)
    assert not covers(bounded, T[:3, 3] + (radius + 1e-6) * np.eye(3)[0])
    still = predicted_obstacles(tracks, 1.1, 0.5, 0.04)
    assert not covers(still, T[:3, 3] + 0.1 * np.eye(3)[0])
    T2 = T.copy()
    T2[0, 3] += 1.0 / 30                      # moving along +x at 1 m/s
    tracks.update({"ball": (ball, T2)}, 1.0 + 1.0 / 30)
    moving = predicted_obstacles(tracks, 1.1, 0.5, 0.04, speed_bound_m_s=1.0)
    assert len(moving) > 1
    assert covers(moving, T2[:3, 3] + 0.5 * np.eye(3)[0])     # ahead, within the horizon
    assert not covers(moving, T2[:3, 3] - 0.3 * np.eye(3)[0])  # behind it


def _ball_at_the_elbow(world, radius):
    """The first task case's start q0, a ball of ``radius`` (m) flying at its elbow at 0.5 m/s,
    and the tracks of two sensor frames of it by t0 = 0.5 s: (q0, ball, tracks, t0)."""
    from chekhov.execute.obstacles import obstacles_at
    q0, _ = start_and_goal(world, 0, 0)
    elbow = world.robot.compute_joint_placements(q0)[3, :3, 3]
    d = np.array([-1.0, 0.0, 0.0])
    ball = MovingObstacle("ball", Shape("sphere", (radius,)), np.eye(3), elbow - 0.6 * d,
                          elbow + 0.6 * d, 0.0, 0.5)
    tracks = ObstacleTracks()
    t0 = 0.5
    for stamp in (t0 - 1 / 30, t0):
        tracks.update(obstacles_at((ball,), stamp), stamp)
    return q0, ball, tracks, t0


def test_a_resting_arm_dodges_a_forearm_coming_at_it(world, limits):
    """A ball flying at the resting arm's elbow at 0.5 m/s: the directed dodge targets push the
    arm's points nearest its path away from it, and a dodge is found that is free at every
    step of the ball's predicted motion (time windows) — and of its true motion."""
    from chekhov.execute.evade import _arm_points
    from chekhov.execute.motion import Motion
    from chekhov.execute.obstacles import to_segment
    q0, ball, tracks, t0 = _ball_at_the_elbow(world, 0.06)
    c = CONFIG.executor
    evader = Evader(world, tracks, EvadeSettings(c.horizon_s, c.margin_m, c.check_dt_s), limits,
                    Bounds(world.robot.lower, world.robot.upper))
    a, b = ball.pose(t0)[:3, 3], ball.pose(t0 + c.horizon_s)[:3, 3]

    def gap(q):
        return float(np.linalg.norm(to_segment(_arm_points(world, q), a, b), axis=1).min())
    directed = evader.directed(q0, t0)
    assert len(directed) > 0
    assert max(gap(q) for q in directed) > gap(q0) + 0.08
    z = np.zeros_like(q0)
    move = evader.dodge(State(q0, z, z), t0)
    assert move is not None and isinstance(move, Motion)
    ts, Q = move.positions(t0, ball.t_end, DT)
    from chekhov.execute.evaluate import TrueWorld
    truth = TrueWorld(world, (ball,))
    assert any(truth.collides(q0, float(t)) for t in ts)          # staying put: contact
    assert not any(truth.collides(q, float(t)) for q, t in zip(Q, ts, strict=True))


def _seeded_evader(world, tracks, limits, seed=3):
    """An evader with the executive's settings and a fixed seed (the same targets each time)."""
    c = CONFIG.executor
    return Evader(world, tracks, EvadeSettings(c.horizon_s, c.margin_m, c.check_dt_s), limits,
                  Bounds(world.robot.lower, world.robot.upper), seed=seed)


def test_safe_in_time_is_each_samples_check_in_the_windows_holding_it(world, limits):
    """``safe_in_time`` (every motion's samples at once, coarse ones first, a motion dropped
    at its first unsafe window) against its statement sample by sample: a motion is safe when
    within the limits and each check step's configuration is free of the sweep of every
    window whose closed span holds it (the last window's from its start on) — moves to the
    dodge targets of an arm moving beside a ball flying at its elbow, some safe, some not."""
    from chekhov.execute.evade import window_edges
    from chekhov.execute.motion import Motion
    q0, _, tracks, t0 = _ball_at_the_elbow(world, 0.06)
    c = CONFIG.executor
    evader = _seeded_evader(world, tracks, limits)
    bounds = Bounds(world.robot.lower, world.robot.upper)
    rng = np.random.default_rng(21)
    z = np.zeros_like(q0)
    now = State(q0, rng.uniform(-0.2, 0.2, len(q0)) * limits.velocity, z)
    moves = [Motion((p,)) for p in (ruckig_piece(now, State(q, z, z), t0, limits, "dodge",
                                                 bounds) for q in evader.targets(now, t0))
             if p is not None]
    safe = evader.safe_in_time(moves, t0, 0.0)
    packs = evader.windows(t0, 0.0)
    edges = t0 + window_edges(c.horizon_s)
    expected = []
    for move in moves:
        ts, Q = move.positions(t0, max(edges[-1], move.t_end), c.check_dt_s)
        ok = bool(world.robot.within_limits(Q).all())
        for k, packed in enumerate(packs):
            last = k == len(packs) - 1
            held = (ts >= edges[k] - 1e-9) & ((ts <= edges[k + 1] + 1e-9) | last)
            ok = ok and all(world.fast.valid_in(packed, q[None])[0] for q in Q[held])
        expected.append(ok)
    assert np.array_equal(safe, expected)
    assert 5 <= int(safe.sum()) <= len(moves) - 5
    assert evader.safe_in_time([], t0, 0.0).shape == (0,)     # no moves (none made): none safe


def test_the_dodge_is_the_nearest_target_whose_move_is_safe_sample_by_sample(world, limits):
    """The dodge search drops targets early (rest in the last window's sweep, coarse samples
    first, chunks): its answer must still be the nearest target whose Ruckig move is within
    the limits and free of its window's sweep at every check step, each sample checked on
    its own."""
    from chekhov.execute.evade import window_edges
    q0, _, tracks, t0 = _ball_at_the_elbow(world, 0.08)
    c = CONFIG.executor
    bounds = Bounds(world.robot.lower, world.robot.upper)

    def evader():
        return _seeded_evader(world, tracks, limits)
    z = np.zeros_like(q0)
    now = State(q0, z, z)
    move = evader().dodge(now, t0)
    reference = evader()
    targets = reference.targets(now, t0)
    packs = reference.windows(t0)
    expected = None
    for q_r in targets:
        piece = ruckig_piece(now, State(q_r, z, z), t0, limits, "dodge", bounds)
        if piece is None:
            continue
        edges = window_edges(c.horizon_s)
        assert len(edges) == len(packs) + 1
        t_end = max(t0 + edges[-1], piece.t_end)
        ts = np.append(np.arange(t0, t_end, c.check_dt_s), t_end)
        safe = True
        for t in ts:
            q = piece.sample(min(t, piece.t_end) - t0).q
            k = min(int(np.searchsorted(edges, t - t0 + 1e-9, side="right")) - 1,
                    len(packs) - 1)
            inside = world.robot.within_limits(q[None])[0]
            if not (inside and world.fast.valid_in(packs[k], q[None])[0]):
                safe = False
                break
        if safe:
            expected = q_r
            break
    assert expected is not None and move is not None, (expected, move)
    assert np.allclose(move.end.q, expected, atol=1e-9)
    assert float(np.abs(expected - q0).max()) > 0.0     # a dodge that moves


def test_a_fast_arm_dodges_around_where_it_stops(world, planner, limits):
    """The arm at its fastest along an undisturbed plan, and a ball (0.6 m/s) that reaches
    the wrist of the configuration where braking stops it just as it stops: stopping hits the
    ball, and the dodge targets around the arm ask it to turn back through it: the dodge
    comes from the targets around the stop, which follow them. It is within the limits and
    free of the ball's true motion at every tick for 3 s."""
    from chekhov.execute.evaluate import TrueWorld
    from chekhov.execute.obstacles import obstacles_at
    plain = run_one(world, planner, _script(world, 1), 20.0, CONFIG)
    k = int(np.argmax(np.abs(plain.qd / limits.velocity).max(axis=1)))
    now, t0 = State(plain.q[k], plain.qd[k], plain.qdd[k]), 0.5
    stop = stop_from(now, t0, limits)
    wrist = world.robot.compute_joint_placements(stop.end.q)[5, :3, 3]
    d, speed = np.array([-1.0, 0.0, 0.0]), 0.6
    ball = MovingObstacle("ball", Shape("sphere", (0.05,)), np.eye(3),
                          wrist - speed * stop.t_end * d,
                          wrist + speed * (4.0 - stop.t_end) * d, 0.0, speed)
    tracks = ObstacleTracks()
    for stamp in (t0 - 1 / 30, t0):
        tracks.update(obstacles_at((ball,), stamp), stamp)
    truth = TrueWorld(world, (ball,))
    ts = np.arange(t0, t0 + 3.0, DT)
    assert any(truth.collides(stop.sample(float(t)).q, float(t)) for t in ts)
    evader = _seeded_evader(world, tracks, limits)
    assert float(np.abs(evader.stop_point(now, t0) - now.q).max()) > STOP_APART_RAD
    move = evader.dodge(now, t0)
    assert move is not None
    reference = _seeded_evader(world, tracks, limits)
    targets = reference.targets(now, t0)
    around_arm = DODGE_CANDIDATES + len(reference.directed(now.q, t0))
    picked = np.flatnonzero(np.abs(targets - move.end.q).max(axis=1) < 1e-9)
    assert len(picked) > 0 and picked[0] >= around_arm, (picked, around_arm)
    Q = move.states_at(ts)[0]
    assert world.robot.within_limits(Q).all()
    assert not any(truth.collides(q, float(t)) for q, t in zip(Q, ts, strict=True))


def test_a_dodge_search_cut_at_its_deadline_goes_on_to_the_same_answer(world, limits,
                                                                       monkeypatch):
    """A search past its deadline stops after one chunk of targets; resumed, it goes on with
    the same targets, skipping those found unsafe: chunk by chunk (a target each, here) it
    reaches the dodge the whole search finds."""
    monkeypatch.setattr("chekhov.execute.evade.DODGE_CHUNK", 1)
    q0, _, tracks, t0 = _ball_at_the_elbow(world, 0.08)

    def evader():
        return _seeded_evader(world, tracks, limits)
    z = np.zeros_like(q0)
    now = State(q0, z, z)
    whole = evader().dodge(now, t0)
    assert whole is not None
    cut, move, calls = evader(), None, 0
    while move is None and calls < 64:
        move = cut.dodge(now, t0, deadline=0.0, resume=calls > 0)   # always past
        calls += 1
    assert move is not None and np.allclose(move.end.q, whole.end.q, atol=1e-9)
    assert calls > 1, "the search never had to go on: the test shows nothing"
    fresh = evader()
    assert fresh.dodge(now, t0, deadline=0.0) is None and fresh.cut_short


def test_an_obstacle_on_the_goal_is_answered_at_once_by_holding_short_of_it(world, planner,
                                                                           limits):
    """A ball appears on the goal while the arm moves there and stays 2 s: no plan can reach
    the goal meanwhile (no free IK), so the executive holds short of the ball — the motion it
    commands changes on the tick after the frame, not when the conflict is near — waits
    there, and reaches the goal once the ball is gone. Judged by the exact checker against
    the ball's true pose. That with no speed bound on obstacles seen once; with the
    executive's (1 m/s), the ball's first frame makes it anywhere within 0.7 m, and the
    answer is a stop on the tick after it, or an escape away from where the ball was seen
    (judged against the sphere growing at half the bound, ``Escaper._slower_tie``), which
    starts on the tick its search is in by: no later than the step's own wall time (as
    measured; it depends on the machine and its load — 30 ms here alone, 40 ms beside two
    other runs) plus ESCAPE_COST_S, rounded up to a tick — the rest the same."""
    bounded = CONFIG.executor.obstacle_speed_m_s
    assert bounded > 0
    for speed in (0.0, bounded):
        config = replace(CONFIG, executor=replace(CONFIG.executor, obstacle_speed_m_s=speed))
        plain = run_one(world, planner, _script(world, 0), 20.0, config)
        first = _script(world, 0)
        p = first.goal.T_world_ee[:3, 3]
        t_in = 0.3 * plain.t_reached
        ball = MovingObstacle("ball", Shape("sphere", (0.06,)), np.eye(3), p,
                              p + np.array([1e-9, 0.0, 0.0]), t_in, 1e-9 / 2.0)
        script = _script(world, 0, obstacles=(ball,))
        rec = run_one(world, planner, script, t_in + 2.0 + plain.t_reached + 4.0, config)
        check = evaluate_episode(world, rec, limits, 0.15)
        assert not check.collision and check.limit_violations == 0
        seen = [r for r in rec.reactions if r.kind == "obstacle"]
        assert seen and seen[0].t_reacted is not None
        latency = seen[0].t_reacted - seen[0].t_observed
        if speed == 0.0:
            assert latency <= DT + 1e-9 and rec.counters.holds >= 1
        else:
            assert rec.counters.safe_stops + rec.counters.dodges >= 1
            wall = rec.counters.step_wall_s[round(seen[0].t_observed / DT)]
            lead = DT * max(1, round(config.executor.reaction_lead_s / DT))
            in_by = max(lead, DT * math.ceil((wall + ESCAPE_COST_S) / DT - 1e-9))
            assert latency <= DT + 1e-9 or \
                (rec.counters.dodges >= 1 and latency <= in_by + 1e-9)
        assert rec.counters.failed_plans >= 1              # the goal was out of reach a while
        assert rec.reached and _meets(world, rec.q[-1], first.goal)
        assert rec.t_reached > ball.t_end


def test_a_dodge_gone_unsafe_with_no_other_stops_when_stopping_is_safe(world, planner,
                                                                     limits):
    """A dodge heading into a still ball, no other dodge to be had: the executive stops (the
    stop safe of the ball without margin) instead of going on into it."""
    from chekhov.execute.executor import Executor
    from chekhov.execute.motion import Motion
    from chekhov.execute.obstacles import obstacles_at, predicted_obstacles
    from chekhov.execute.worker import InlineWorker
    q0, goal = start_and_goal(world, 0, 0)
    q1 = q0.copy()
    q1[0] = np.clip(q1[0] + 0.6, world.robot.lower[0], world.robot.upper[0])
    p = world.robot.compute_ee_pose(q1)[:3, 3]
    ball = MovingObstacle("ball", Shape("sphere", (0.08,)), np.eye(3), p,
                          p + np.array([1e-9, 0.0, 0.0]), 0.0, 1e-12)
    c = CONFIG.executor
    ex = Executor(world, InlineWorker(world, planner, c.timing), goal, c)
    z = np.zeros_like(q0)
    piece = ruckig_piece(State(q0, z, z), State(q1, z, z), 0.0, limits, "dodge",
                         Bounds(world.robot.lower, world.robot.upper))
    assert piece is not None
    ex.motion = Motion((piece,))
    t = 0.1
    for stamp in (t - 0.04 - 1 / 30, t - 0.04):     # two frames: its velocity known
        ex.tracks.update(obstacles_at((ball,), stamp), stamp)
    ex._seen = predicted_obstacles(ex.tracks, t, c.horizon_s, c.margin_m)
    ex.evader.dodge = lambda *args, **kw: None      # no other dodge to be had
    assert not ex._safe([ex.motion], t).all()
    ex._evade(t, t)          # the conflict as near as can be
    assert ex.motion.kind_at(t + 2 * DT) == "brake"
    ts, Q = ex.motion.positions(t, ex.motion.t_end, DT)
    from chekhov.execute.evaluate import TrueWorld
    truth = TrueWorld(world, (ball,))
    assert not any(truth.collides(q, float(s)) for q, s in zip(Q, ts, strict=True))
    assert truth.collides(q1, 1.0)          # where the dodge ends: contact


def test_a_dodge_found_after_its_tick_starts_where_the_arm_will_be(world, planner, limits):
    """A dodge from the state one tick ahead, found by a step that has already run 25 ms:
    made again from the tick the step's answer is in by (3 ticks on), from the state the
    motion is in there (position and velocity continuous), to the same target; a step that
    ends in its tick keeps the dodge as found."""
    import time

    from chekhov.execute.executor import Executor
    from chekhov.execute.motion import Motion
    from chekhov.execute.worker import InlineWorker
    q0, goal = start_and_goal(world, 0, 0)
    q1 = q0.copy()
    q1[0] = np.clip(q1[0] + 0.5, world.robot.lower[0], world.robot.upper[0])
    bounds = Bounds(world.robot.lower, world.robot.upper)
    c = CONFIG.executor
    ex = Executor(world, InlineWorker(world, planner, c.timing), goal, c)
    z = np.zeros_like(q0)
    going = ruckig_piece(State(q0, z, z), State(q1, z, z), 0.0, limits, "plan", bounds)
    assert going is not None
    ex.motion = Motion((going,))
    ex._seen = {}
    world.fast.set_obstacles({})
    t = 0.1
    aside = q0 + 0.2 * np.sign(np.random.default_rng(0).normal(size=len(q0)))
    aside = np.clip(aside, world.robot.lower, world.robot.upper)
    found = ruckig_piece(ex.motion.sample(t + DT), State(aside, z, z), t + DT, limits, "dodge",
                         bounds)
    assert found is not None
    move = Motion((found,))
    ex._wall0 = time.perf_counter() - 0.025
    again, t_in = ex._on_time(move, t, t + DT)
    assert again is not move        # made again (and safe: nothing but the scene is there)
    assert t_in == pytest.approx(t + 3 * DT)
    assert again.kind_at(t_in - 1e-6) == "plan" and again.kind_at(t_in + 1e-6) == "dodge"
    s_old, s_new = ex.motion.sample(t + 3 * DT), again.sample(t + 3 * DT)
    assert np.allclose(s_old.q, s_new.q) and np.allclose(s_old.qd, s_new.qd)
    assert np.allclose(again.end.q, aside)
    ex._wall0 = time.perf_counter()
    assert ex._on_time(move, t, t + DT) == (move, t + DT)


def test_after_a_step_over_its_tick_any_offset_is_a_lag_to_join_back(world, planner, limits):
    """An arm 1e-4 rad/s off the motion is within the kick tolerance; but after a step that ran
    past its tick it is a lagging arm (it followed the motion it had), joined back — commanding
    the new motion from there would be a velocity step the evaluation flags."""
    from chekhov.execute.executor import Executor
    from chekhov.execute.interface import Command, Observation
    from chekhov.execute.motion import Motion
    from chekhov.execute.worker import InlineWorker
    q0, goal = start_and_goal(world, 0, 0)
    q1 = q0.copy()
    q1[0] = np.clip(q1[0] + 0.6, world.robot.lower[0], world.robot.upper[0])
    z = np.zeros_like(q0)
    piece = ruckig_piece(State(q0, z, z), State(q1, z, z), 0.0, limits, "plan",
                         Bounds(world.robot.lower, world.robot.upper))
    assert piece is not None
    seen = []
    for wall in (0.001, 0.02):                  # within its tick, then over it
        ex = Executor(world, InlineWorker(world, planner, CONFIG.executor.timing), goal,
                      CONFIG.executor)
        ex.motion = Motion((piece,))
        s = ex.motion.sample(0.1)
        ex._last = Command(0.1, s.q, s.qd, s.qdd, "plan")
        ex.counters.step_wall_s.append(wall)
        ex._check_kick(Observation(0.1, s.q, s.qd + 1e-4))
        seen.append([r.kind for r in ex.reactions])
    assert seen == [[], ["kick"]]


def test_the_evaluation_sees_a_collision_and_a_velocity_jump(world, limits):
    """Not the executive's checks: a record driven straight through a sphere is a collision;
    a position jump without a kick is a limit violation."""
    q0, _ = start_and_goal(world, 0, 0)
    p = world.robot.compute_ee_pose(q0)[:3, 3]
    ball = MovingObstacle("ball", Shape("sphere", (0.05,)), np.eye(3), p - np.array([0.5, 0, 0]),
                          p + np.array([0.5, 0, 0]), 0.0, 1.0)
    n = 101
    times = np.arange(n) * DT
    Q = np.repeat(q0[None], n, axis=0)
    Z = np.zeros_like(Q)
    rec = EpisodeRecord(times, Q, Z, Z, np.zeros(n, dtype=bool), ("rest",) * n, (ball,),
                        Goal.configuration(q0), True, times[-1], (), None, ())
    check = evaluate_episode(world, rec, limits, 0.1)
    assert check.collision and abs(check.first_contact_s - 0.4) < 0.06
    assert check.min_clearance_m <= 0
    Q2 = Q.copy()
    Q2[50:] += 0.05                                   # 5 rad/s for one tick
    rec2 = EpisodeRecord(times, Q2, Z, Z, np.zeros(n, dtype=bool), ("rest",) * n, (),
                         Goal.configuration(q0), True, times[-1], (), None, ())
    assert limit_violations(world, rec2, limits) == 1


def test_react_command_prints_the_keys(capsys):
    assert main(["react", "--scenes", "tabletop_pole", "--episodes", "1", "--json"]) == 0
    row = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    for key in ("scene", "episodes", "success_rate", "collision_episodes", "min_clearance_m",
                "p5_clearance_m", "reaction_latency_ms_p50", "reaction_latency_ms_p95",
                "reaction_latency_ms_p99", "replans_per_episode", "safe_stops",
                "time_to_goal_ratio", "limit_violations"):
        assert key in row
    assert row["scene"] == "tabletop_pole" and row["episodes"] == 1
    assert row["compute_charged"] is True and row["compute_scale"] == 1.0


def test_an_episodes_script_is_the_same_in_every_run(world, planner):
    """``chekhov react`` times each episode's disturbances on an undisturbed run whose clock
    charges no compute and whose plans come one budget after they are asked for: two makings
    of the same episode give the same script, whatever the planner's wall time was — and the
    first plan's reply is taken on that budget's tick, not before."""
    from chekhov.execute.benchmark import episode_script
    config = ReactConfig(seed=0)
    a = episode_script(world, planner, config, 0)
    b = episode_script(world, planner, config, 0)
    assert a is not None and b is not None
    assert [k.t for k in a.kicks] == [k.t for k in b.kicks]
    assert all(np.array_equal(x.dq, y.dq) for x, y in zip(a.kicks, b.kicks, strict=True))
    assert [g.t for g in a.goal_changes] == [g.t for g in b.goal_changes]
    assert [(o.t_start, tuple(o.p_start), tuple(o.p_end)) for o in a.obstacles] == \
        [(o.t_start, tuple(o.p_start), tuple(o.p_end)) for o in b.obstacles]
    q0, goal = start_and_goal(world, 0, 0)
    rec = run_one(world, planner, EpisodeScript(0, q0, goal, ""), 20.0, CONFIG,
                  reply_after_s=0.05)
    moving = np.flatnonzero(np.abs(rec.qd).max(axis=1) > 0)
    assert rec.reached and rec.times[moving[0]] >= 0.05 - 1e-9


@pytest.mark.parametrize("argv, where", [
    (["--episodes", "0"], "--episodes"),
    (["--scenes", "no_such_scene"], "--scenes"),
    (["--planners", "NoSuchPlanner"], "--planners"),
    (["--compute-scale", "0"], "--compute-scale"),
    (["--compute-scale", "nan"], "--compute-scale"),
    (["--free-compute", "--compute-scale", "2"], "--compute-scale"),
])
def test_react_command_refuses_bad_arguments(argv, where, capsys):
    with pytest.raises(SystemExit) as e:
        code = main(["react", *argv])
        raise SystemExit(code)
    assert e.value.code == 2
    assert where in capsys.readouterr().err


def test_a_worker_refuses_a_planner_of_another_world(planner):
    from chekhov.errors import ChekhovError
    from chekhov.execute.worker import InlineWorker, ThreadWorker
    other = World.load("tabletop_pole")
    for kind in (InlineWorker, ThreadWorker):
        with pytest.raises(ChekhovError, match="another World"):
            kind(other, planner, CONFIG.executor.timing)


def test_a_thread_worker_closes_cleanly(world, planner):
    """close(wait=True) returns once the planning thread has ended; no reply comes after."""
    import threading
    import time as _time

    from chekhov.execute.worker import PlanRequest, ThreadWorker
    worker = ThreadWorker(world, planner, CONFIG.executor.timing)
    q0, goal = start_and_goal(world, 0, 0)
    z = np.zeros_like(q0)
    worker.submit(PlanRequest(0.0, 0.05, State(q0, z, z), goal, ({},), 0.2, 0))
    worker.close(wait=True)
    assert not any(t.name.startswith("chekhov-plan") and t.is_alive()
                   for t in threading.enumerate())
    _time.sleep(0.05)
    assert worker.poll(10.0) is None


def test_warmup_loads_the_reaction_kernels_and_changes_nothing(world, planner):
    from chekhov.execute.executor import Executor
    from chekhov.execute.worker import InlineWorker
    script = _script(world, 0)
    ex = Executor(world, InlineWorker(world, planner, CONFIG.executor.timing), script.goal,
                  CONFIG.executor)
    world.fast.set_obstacles({"box": (Shape("box", (0.1, 0.1, 0.1)), np.eye(4))})
    version = world.fast.obstacles_version
    assert ex.warmup() >= 0.0
    assert ex.motion is None and not ex.reactions and ex.counters.safe_stops == 0
    assert world.fast.obstacles_version == version and "box" in world.fast.obstacle_names
    world.fast.set_obstacles({})


def test_the_evaluators_escape_motions_stay_within_the_limits(limits):
    """The unavoidability verdict tries constant-acceleration motions: their positions must be
    reachable within the limits — mean velocities within the velocity limits, and the first
    step's displacement from the start velocity no more than half the acceleration limit
    × dt² (integrating with the step's end velocity moved twice that)."""
    from chekhov.execute.simulate import constant_acceleration_path
    rng = np.random.default_rng(0)
    dt = 0.01
    for _ in range(20):
        v0 = rng.uniform(-1, 1, len(limits.velocity)) * limits.velocity
        acc = rng.choice([-1.0, 1.0], len(v0)) * limits.acceleration
        Q = constant_acceleration_path(np.zeros(len(v0)), v0, acc, 40, dt, limits)
        v_mean = np.diff(Q, axis=0) / dt
        assert (np.abs(v_mean) <= limits.velocity * (1 + 1e-9)).all()
        a_first = 2 * (v_mean[0] - v0) / dt
        assert (np.abs(a_first) <= limits.acceleration * (1 + 1e-9)).all()
        a_mean = np.diff(v_mean, axis=0) / dt
        assert (np.abs(a_mean) <= limits.acceleration * (1 + 1e-9)).all()


def test_the_way_out_motions_stay_within_the_limits_and_come_to_rest(limits):
    """The scripts' way-out rule tries motions that accelerate for a while, then brake to
    rest (:func:`go_stop_path`): mean velocities within the velocity limits, their changes
    within the acceleration limits, and at rest once a full stop from the velocity limit has
    had time."""
    from chekhov.execute.simulate import go_stop_path
    rng = np.random.default_rng(1)
    dt, t_go = 0.01, 0.5
    n = round((t_go + (limits.velocity / limits.acceleration).max()) / dt) + 3
    for _ in range(20):
        v0 = rng.uniform(-1, 1, len(limits.velocity)) * limits.velocity
        acc = rng.uniform(-1, 1, len(v0)) * limits.acceleration
        Q = go_stop_path(np.zeros(len(v0)), v0, acc, rng.uniform(0, t_go), n, dt, limits)
        v_mean = np.diff(Q, axis=0) / dt
        assert (np.abs(v_mean) <= limits.velocity * (1 + 1e-9)).all()
        assert (np.abs(np.diff(v_mean, axis=0)) / dt <= limits.acceleration * (1 + 1e-9)).all()
        assert np.array_equal(Q[-1], Q[-2])


def test_a_join_from_full_velocity_and_outward_acceleration_keeps_the_velocity_limit(limits):
    """A timed plan's cruise begins at full velocity with the ramp's full acceleration (its
    acceleration switches there); joined from that state, Ruckig first had to bring the
    acceleration down at its jerk limit and overshot the velocity limit (1.2% for 0.63 rad/s)."""
    K = len(limits.velocity)
    v, a = -limits.velocity, -limits.acceleration
    piece = ruckig_piece(State(np.zeros(K), v, a), State(np.full(K, -2.0), np.zeros(K),
                                                          np.zeros(K)), 0.0, limits, "join")
    assert piece is not None
    ts = np.linspace(0.0, min(piece.t_end, 0.5), 2001)
    V = np.array([piece.sample(t).qd for t in ts])
    assert (np.abs(V) <= limits.velocity * (1 + 1e-9)).all()
    # away from the limit the start's acceleration is kept (no jump)
    half = State(np.zeros(K), 0.5 * v, a)
    piece = ruckig_piece(half, State(np.full(K, -2.0), np.zeros(K), np.zeros(K)), 0.0,
                         limits, "join")
    assert piece is not None and np.allclose(piece.sample(0.0).qdd, a)


def test_an_exact_check_past_its_budget_answers_not_free(world, planner):
    """``check_budget_s`` bounds the executive's exact checks: a check cut by it is answered
    the safe way (not free) and counted; without a budget the same motion is free."""
    from chekhov.execute.executor import Executor
    from chekhov.execute.worker import InlineWorker
    q0, goal = start_and_goal(world, 0, 0)
    Q = np.array([q0, q0])              # standing at the task's start, exactly free
    assert world.exact.path_valid(Q, 4)
    for budget, free in ((None, True), (0.0, False)):
        c = replace(CONFIG.executor, check_budget_s=budget)
        ex = Executor(world, InlineWorker(world, planner, c.timing), goal, c)
        assert ex.checks.exact_free(Q, 4, {}) is free
        assert ex.counters.undecided_checks == (0 if free else 1)


def test_a_search_budget_starts_no_unit_that_would_end_past_its_deadline(monkeypatch):
    import chekhov.execute.swerve as swerve_mod

    clock = [0.0]
    monkeypatch.setattr(swerve_mod.time, "perf_counter", lambda: clock[0])
    expected: dict[str, float] = {}
    budget = swerve_mod._Budget(0.010, expected)
    starts = []
    while budget.room("judge"):
        starts.append(clock[0])
        with budget.unit("judge"):
            clock[0] += 0.003            # each unit takes 3 ms
    assert starts == pytest.approx([0.0, 0.003, 0.006])
    assert clock[0] <= 0.010             # the fourth would have ended at 12 ms: not begun
    # the next search knows what a unit takes: 2 ms left are not enough to begin one
    clock[0] = 0.0
    assert not swerve_mod._Budget(0.002, expected).room("judge")
    assert swerve_mod._Budget(0.004, expected).room("judge")
    assert swerve_mod._Budget(None, expected).room("judge")
    assert swerve_mod._Budget(0.002, expected).room("draw")   # another kind: not yet timed
    # a quick unit halves what a slow one taught, no more
    with swerve_mod._Budget(None, expected).unit("judge"):
        clock[0] += 0.0005
    assert expected["judge"] == pytest.approx(0.0015)


def test_a_trajopt_reply_is_timed_along_its_curve_not_at_rest_at_every_waypoint(world):
    """A reply with many waypoints (TrajOpt's: 30 along a curve) is timed with toppra's
    blended corners, not with Ruckig at rest at each waypoint (``reply_timing``): the same
    certified path moves several times faster, within the limits, and its trajectory passes
    the exact check at finer steps than the certification's."""
    from chekhov.execute.worker import (
        RUCKIG_MAX_WAYPOINTS,
        PlanRequest,
        plan_motion,
        reply_timing,
    )
    from chekhov.planners.timed import timed_trajectory

    timing = CONFIG.executor.timing
    assert timing.method == "ruckig"
    trajopt = executive_planner("TrajOpt", World.load("tabletop_pole"))
    q0, goal = start_and_goal(trajopt.world, 0, 1)
    # planned once first: the reply's budget is wall time, and a first call in a fresh process
    # also loads the compiled kernels (a CI run under load timed out here)
    path = trajopt.plan(q0, goal, 2.0).path
    request = PlanRequest(0.0, 0.0, State(q0, np.zeros_like(q0), np.zeros_like(q0)), goal,
                          ({},), 2.0, 0)
    reply = plan_motion(trajopt.world, trajopt, request, timing)
    assert reply.trajectory is not None, reply.status
    assert len(path) > RUCKIG_MAX_WAYPOINTS
    at_rest = timed_trajectory(trajopt.world, path, timing).trajectory
    traj = reply.trajectory
    assert traj.duration < 0.5 * at_rest.duration, (traj.duration, at_rest.duration)
    assert reply_timing(path, timing).method == "toppra"
    assert reply_timing(path[[0, len(path) // 2, -1]], timing) is timing
    limits = joint_limits(world.robot.velocity_limit, timing)
    ts = np.arange(0.0, traj.duration, 1e-3)
    Q, V, _ = traj.sample(ts)
    assert _fd_ok(ts, Q, V, limits, slack=1e-3)
    assert exact_path_decision(trajopt.world.fast, trajopt.world.exact, traj.positions,
                               4).valid


def test_the_forearm_is_aimed_at_the_motion_with_the_goal_change(world, planner):
    """With ``follow``, the forearm and the kick are placed against the task's motion with its
    goal change (the arm goes elsewhere after it). Over five episodes: the forearm passes its
    crossing point (half a sweep before its end) within 0.18 m of the end effector as it is
    then in *that* motion (the point is drawn within 0.1 m a coordinate of it), where one
    aimed at the undisturbed motion misses it by more in some episode; it appears at least
    0.15 m (coal's
    distance) from that arm; the kick falls within that motion; the goal change and the
    kick's displacement are the draws made without ``follow`` (each part its own stream)."""
    asked, gaps, misses, aimed = [], [], [], []
    for index in range(5):
        plain = run_one(world, planner, _script(world, index), 20.0, CONFIG)
        ee = world.robot.compute_ee_poses(plain.q)[:, :3, 3]
        runs = {}

        def follow(task, runs=runs):
            asked.append(task)
            rec = run_one(world, planner, task, 20.0, CONFIG)
            if rec.t_reached is None:
                return None
            runs["moved"] = rec
            return rec.t_reached, rec.q

        script = make_script(world, 0, index, plain.t_reached, ee, plain.q, follow=follow)
        alone = make_script(world, 0, index, plain.t_reached, ee, plain.q)
        assert [g.t for g in script.goal_changes] == [g.t for g in alone.goal_changes]
        assert np.array_equal(script.kicks[0].dq, alone.kicks[0].dq)
        assert asked[-1].goal_changes == script.goal_changes
        assert not (asked[-1].obstacles or asked[-1].kicks)
        moved = runs["moved"]
        ee_moved = world.robot.compute_ee_poses(moved.q)[:, :3, 3]
        assert 0.1 * moved.t_reached <= script.kicks[0].t <= 0.9 * moved.t_reached
        for s, out in ((script, aimed), (alone, misses)):
            o = s.obstacles[0]                   # the forearm's body, its axis on the sweep
            t_cross = o.t_end - SWEEP_M / 2 / o.speed_mps   # half a sweep before its end
            k = min(round(t_cross / DT), len(ee_moved) - 1)
            out.append(float(np.linalg.norm(ee_moved[k] - o.pose(t_cross)[:3, 3])))
        t_in = script.obstacles[0].t_start
        q_then = moved.q[min(int(t_in / moved.t_reached * len(moved.q)), len(moved.q) - 1)]
        gaps.append(TrueWorld(world, script.obstacles).clearance(q_then, t_in))
    assert len(asked) == 5 and min(gaps) >= 0.15, gaps
    assert max(aimed) <= 0.18 < max(misses), (aimed, misses)


def _capsule_along(p_start, p_end, t_start, speed):
    """The script's forearm (body, elbow, wrist) with its axis vertical, from p_start to p_end
    (3,) m at ``speed`` m/s from ``t_start`` s."""
    from chekhov.execute.script import FOREARM_LENGTH_M, FOREARM_RADIUS_M
    half = np.array([0.0, 0.0, FOREARM_LENGTH_M / 2])
    body = Shape("cylinder", (FOREARM_RADIUS_M, FOREARM_LENGTH_M))
    ball = Shape("sphere", (FOREARM_RADIUS_M,))
    return tuple(MovingObstacle(n, shape, np.eye(3), p_start + k * half, p_end + k * half,
                                t_start, speed)
                 for n, shape, k in (("forearm", body, 0.0), ("elbow", ball, -1.0),
                                     ("wrist", ball, 1.0)))


def test_a_forearm_that_leaves_the_arm_no_way_out_is_drawn_again(world, planner, limits):
    """The scripts leave the arm a way out (:func:`forearm_way_out`). A forearm that meets the
    end effector of a motion 0.08 s after it appears, before any reaction can begin (one
    reaction window: 0.123 s), is rejected — and, by another mechanism, braking at the limits
    from the state it appears in does hit it; one whose sweep stays 1 m above the motion is
    accepted. ``make_script`` takes the stream's first draw the rule accepts: with a rule that
    rejects the first three draws, the fourth, and none when the rule rejects every draw."""
    from chekhov.execute import benchmark

    rule = benchmark.script_way_out(world, ReactConfig())
    plain = run_one(world, planner, _script(world, 0), 20.0, CONFIG)
    Q, T = plain.q, plain.t_reached
    ee = world.robot.compute_ee_poses(Q)[:, :3, 3]
    k = len(Q) // 2
    v = (ee[k + 1] - ee[k - 1]) / (2 * DT)
    u = v / np.linalg.norm(v)
    meets = _capsule_along(ee[k] + 0.08 * u, ee[k] - 1.0 * u, k * DT - 0.08, 1.0)
    assert TrueWorld(world, meets).collides(Q[k], k * DT)
    assert not rule(meets, T, Q)
    i0 = k - 8
    brake = next(escape_motions(Q[i0], (Q[i0 + 1] - Q[i0 - 1]) / (2 * DT), limits, 40, 0,
                                np.random.default_rng(0), DT))
    assert any(TrueWorld(world, meets).collides(q, (i0 + j) * DT) for j, q in enumerate(brake))
    lift = np.array([0.0, 0.0, 1.0])
    assert rule(_capsule_along(ee[k] + lift - u, ee[k] + lift + u, 0.05, 1.0), T, Q)

    verdicts = []

    def first_three_rejected(arm, duration_s, q_path):
        verdicts.append(arm)
        return len(verdicts) > 3

    script = make_script(world, 0, 0, T, ee, Q, way_out=first_three_rejected)
    assert len(verdicts) == 4 and script.obstacles is verdicts[-1]
    plain_draws = make_script(world, 0, 0, T, ee, Q).obstacles
    assert plain_draws[0].p_start.tolist() == verdicts[0][0].p_start.tolist()
    assert make_script(world, 0, 0, T, ee, Q, way_out=lambda *a: False).obstacles == ()


def test_the_way_out_must_hold_until_the_forearm_is_gone(world, planner, limits):
    """A forearm that crosses a motion and then ends its sweep on the arm's shoulder, where
    every configuration touches it (coal, 200 free ones) — as a drawn one had ended beside
    the shoulder of shelf_boxes' arm, which came to rest there and was hit in every run. An
    escape from the motion one reaction window after it appears is free of it until 0.3 s
    after the motion's first contact; the rule asks for a way out until the forearm is gone,
    and rejects it."""
    from chekhov.execute import benchmark
    from chekhov.execute.evaluate import ESCAPE_AFTER_S, escapes

    config = ReactConfig()
    plain = run_one(world, planner, _script(world, 0), 20.0, CONFIG)
    Q, T = plain.q, plain.t_reached
    ee = world.robot.compute_ee_poses(Q)[:, :3, 3]
    shoulder = world.robot.reach[0]
    k = len(Q) // 2                  # from 0.6 m along +x of the motion's middle, at 1 m/s
    arm = _capsule_along(ee[k] + np.array([0.6, 0.0, 0.0]), shoulder, k * DT - 0.6, 1.0)
    truth = TrueWorld(world, arm)
    hit = next(i for i in range(len(Q)) if truth.collides(Q[i], i * DT))
    i0 = math.ceil((arm[0].t_start + benchmark.reaction_window_s(config)) / DT)
    assert i0 < hit
    assert escapes(truth, Q[i0], (Q[i0 + 1] - Q[i0 - 1]) / (2 * DT), i0 * DT,
                   hit * DT + ESCAPE_AFTER_S, limits, np.random.default_rng(hit), hit * DT)
    free = world.robot.sample_uniform(np.random.default_rng(0), 400)
    free = free[[world.exact.is_valid(q) for q in free]][:200]
    assert len(free) == 200
    assert all(truth.collides(q, arm[0].t_end) for q in free)
    assert not benchmark.script_way_out(world, config)(arm, T, Q)


def test_while_no_plan_to_a_new_goal_exists_the_arm_brakes(world, planner):
    """A goal change whose every plan fails (a worker that answers ``no_ik`` for the new
    goal): the arm brakes to a stop along its motion and waits, instead of going on to the
    goal no longer wanted (it had, and so reached the old goal); the goal's reaction is that
    brake, one planning budget and a tick or two after the change. By the executed motion
    itself: at rest within a second of the change, short of the old goal."""
    from chekhov.execute.benchmark import checking_world
    from chekhov.execute.executor import Executor
    from chekhov.execute.simulate import run_episode
    from chekhov.execute.worker import InlineWorker

    goal = _script(world, 0).goal
    plain = run_one(world, planner, _script(world, 0), 20.0, CONFIG)
    t_change = 0.4 * plain.t_reached
    new_goal = start_and_goal(world, 0, 1)[1]

    class RefusesNewGoal(InlineWorker):
        def poll(self, now):
            reply = super().poll(now)
            if reply is not None and reply.request.goal is new_goal:
                return replace(reply, trajectory=None, status="no_ik")
            return reply

    script = _script(world, 0, goal_changes=(GoalChange(t_change, new_goal, "new"),))
    worker = RefusesNewGoal(world, planner, CONFIG.executor.timing)
    executor = Executor(checking_world(world), worker, goal, CONFIG.executor)
    rec = run_episode(world, executor, script, t_change + 2.0, CONFIG.sim)
    assert not rec.reached and rec.counters.failed_plans >= 2
    (r,) = [r for r in rec.reactions if r.kind == "goal"]
    assert r.t_reacted is not None and r.t_reacted - r.t_observed <= 0.08
    after = rec.times >= t_change + 1.0
    assert np.abs(rec.qd[after]).max() < 1e-6
    assert not _meets(world, rec.q[-1], goal)
    assert np.abs(rec.q[-1] - plain.q[-1]).max() > 0.05
