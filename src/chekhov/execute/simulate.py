"""A simulated robot and sensor around an :class:`~chekhov.execute.executor.Executor`, on a
simulated clock (:func:`run_episode`): every control tick the robot is where the last command
put it (perfect tracking) unless a scripted kick displaces it, the sensor takes a frame of the
obstacles' true poses every ``sensor_period_s`` and delivers it ``sensor_latency_s`` later,
and goal changes arrive when scripted. The executed motion is recorded at the control rate
(:class:`EpisodeRecord`). Units: s, rad.

The executive's own compute is charged on the clock (``SimConfig.charge_compute``): a step
whose wall time (an inline worker's planning left out: that is charged by the worker) runs
past its tick misses every tick until the first one after it ends. Meanwhile the control loop
goes on commanding the motion the arm was following (the one the step before ended with), so
the arm follows that. A reaction starts ahead of its tick
(``ExecutorConfig.reaction_lead_s``) on a motion unchanged until then, so a step that ends by
then costs nothing; the reactions of one that ends later start no earlier than its end
(``t_reacted`` and ``t_resolved`` moved on), and the executive sees the arm off its new
motion at its next step, as a lagging arm, and joins back onto it (that reaction's kind is
"lag", not a disturbance: its time is already charged to the reaction that overran). A kicked
arm is not left to snap back onto its old motion meanwhile: the loop commands the
executive's unchecked join back (``Executor.immediate_motion``, Ruckig, well under a tick)
from the kick's tick. Scripted kicks and goal changes that fall on missed ticks arrive at the
next step.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.path_check import exact_path_decision
from chekhov.execute.executor import Executor
from chekhov.execute.interface import Counters, Observation, Reaction
from chekhov.execute.motion import Motion, State
from chekhov.execute.obstacles import MovingObstacle, Obstacles, obstacles_at
from chekhov.execute.script import EpisodeScript
from chekhov.execute.truth import TrueWorld
from chekhov.robot.goal import Goal
from chekhov.timing import Limits
from chekhov.world import World

Array = NDArray[np.float64]


@dataclass(frozen=True)
class SimConfig:
    """The simulated robot's clock and sensor.

    Attributes:
        sensor_period_s: s, between sensor frames (30 Hz).
        sensor_latency_s: s, from a frame's exposure to its delivery.
        kick_halvings: how often a kick that would put the arm in collision or outside its
            limits is halved before it is dropped.
        charge_compute: a step's own wall time is charged on the clock (module docstring);
            False: every step takes no time (deterministic, but optimistic).
        compute_scale: the executive's steps count this many times their wall time, as on a
            machine that many times slower (:func:`~chekhov.execute.benchmark.run_one` builds
            its executive with it; :func:`run_episode` refuses an executor built with another
            ``wall_scale``; the wall-clock budgets are not scaled).
    """

    sensor_period_s: float = 1.0 / 30.0
    sensor_latency_s: float = 0.04
    kick_halvings: int = 4
    charge_compute: bool = True
    compute_scale: float = 1.0


@dataclass(frozen=True, eq=False)
class EpisodeRecord:
    """What happened: ``times`` (N,) s; the executed ``q`` (N, K) rad and the commanded
    ``qd`` (N, K) rad/s and ``qdd`` (N, K) rad/s² at those times; ``kicked`` (N,) the ticks
    whose position a kick displaced; ``modes`` the motion's mode per tick; the episode's
    ``obstacles`` (their true motion), final goal, whether and when it was reached, the
    executor's reactions and counters, and the kicks applied (rad, after shrinking)."""

    times: Array
    q: Array
    qd: Array
    qdd: Array
    kicked: NDArray[np.bool_]
    modes: tuple[str, ...]
    obstacles: tuple[MovingObstacle, ...]
    goal: Goal
    reached: bool
    t_reached: float | None
    reactions: tuple[Reaction, ...]
    counters: Counters
    kicks_applied: tuple[Array, ...]


def run_episode(world: World, executor: Executor, script: EpisodeScript, deadline_s: float,
                config: SimConfig | None = None) -> EpisodeRecord:
    """Run ``script`` with ``executor`` (built for ``script.q_start``'s episode) until the goal
    is reached and every disturbance is over, or until ``deadline_s`` (s)."""
    config = config if config is not None else SimConfig()
    if config.charge_compute and config.compute_scale != executor.wall_scale:
        raise ValueError(f"SimConfig.compute_scale is {config.compute_scale:g} but the executor "
                         f"counts its steps {executor.wall_scale:g}x: build it with "
                         f"Executor(..., wall_scale={config.compute_scale:g})")
    dt = executor.config.control_dt_s
    q = np.array(script.q_start, dtype=float)
    qd = np.zeros_like(q)
    rows: list[tuple[float, Array, Array, Array, bool, str]] = []
    kicks = list(script.kicks)
    changes = list(script.goal_changes)
    applied: list[Array] = []
    next_frame, reached_at, lagged = 0, None, False
    following: Motion | None = None     # what the arm is tracking (the loop's commands)
    qdd = np.zeros_like(q)
    truth = TrueWorld(world, script.obstacles) if script.obstacles and kicks else None
    i, n_ticks = 0, int(np.ceil(deadline_s / dt)) + 1
    while i < n_ticks:
        t = i * dt
        kicked = False
        while kicks and kicks[0].t <= t + 1e-9:
            dq = shrunk_kick(world, q, qd, kicks.pop(0).dq, config.kick_halvings,
                             executor.limits, truth, t)
            if dq is not None:
                q, kicked = q + dq, True
                applied.append(dq)
        goal = changes.pop(0).goal if changes and changes[0].t <= t + 1e-9 else None
        frame, stamp, next_frame = _frame_due(script, config, next_frame, t)
        seen = _answered(executor.reactions)
        cmd = executor.step(Observation(t, q, qd, frame, stamp, goal))
        if lagged:
            _relabel_lag(executor.reactions, len(seen), kicked)
        rows.append((t, q.copy(), qd.copy(), qdd.copy(), kicked, cmd.mode))
        if executor.done and t >= script.last_event_s and not changes and not kicks:
            reached_at = t
            break
        missed = _missed_ticks(executor, dt) if config.charge_compute else 0
        lagged = missed > 0 and following is not None
        if not lagged:
            q, qd, qdd = np.array(cmd.q), np.array(cmd.qd), np.array(cmd.qdd)
            following = executor.motion
            i += 1
            continue
        # meanwhile the loop commands what it had (after a kick: the join back, unchecked,
        # at once — the step's checks are what overran); then what the step installed
        meanwhile = executor.immediate_motion or following
        assert meanwhile is not None
        _charge(executor.reactions, seen, t + missed * dt)
        now = _follow(meanwhile, t, missed, dt, rows)
        following = executor.motion
        q, qd, qdd = now.q.copy(), now.qd.copy(), now.qdd.copy()
        i += missed
    return EpisodeRecord(
        np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
        np.array([r[2] for r in rows]), np.array([r[3] for r in rows]),
        np.array([r[4] for r in rows], dtype=bool), tuple(r[5] for r in rows),
        script.obstacles, executor.goal, reached_at is not None, reached_at,
        tuple(executor.reactions), executor.counters, tuple(applied))


def _frame_due(script: EpisodeScript, config: SimConfig, next_frame: int, t: float
               ) -> tuple[Obstacles | None, float | None, int]:
    """The latest sensor frame delivered by clock time t (s) and not handed over yet — its
    obstacles' true poses and its stamp (s) — or (None, None); and the next frame's number."""
    period, latency = config.sensor_period_s, config.sensor_latency_s
    if next_frame * period + latency > t + 1e-9:
        return None, None, next_frame
    while (next_frame + 1) * period + latency <= t + 1e-9:
        next_frame += 1
    stamp = next_frame * period
    return obstacles_at(script.obstacles, stamp), stamp, next_frame + 1


def _follow(following: Motion, t: float, missed: int, dt: float,
            rows: list[tuple[float, Array, Array, Array, bool, str]]) -> State:
    """The ticks after t (s) that a step missed: the arm follows ``following`` (recorded in
    ``rows``); its state at the tick of the next step."""
    for j in range(1, missed):
        s = following.sample(t + j * dt)
        rows.append((t + j * dt, s.q, s.qd, s.qdd, False, following.kind_at(t + j * dt)))
    return following.sample(t + missed * dt)


def _missed_ticks(executor: Executor, dt: float) -> int:
    """Ticks the last step missed: 0 when its compute (s) fit in its tick, else the ticks
    until the first one after it ended."""
    walls = executor.counters.step_wall_s
    w = walls[-1] if walls else 0.0
    return 0 if w <= dt else int(np.ceil(w / dt - 1e-9))


def _answered(reactions: list[Reaction]) -> list[tuple[float | None, float | None]]:
    return [(r.t_reacted, r.t_resolved) for r in reactions]


def _charge(reactions: list[Reaction], seen: list[tuple[float | None, float | None]],
            t_in: float) -> None:
    """Reactions answered in an overrunning step start no earlier than ``t_in`` (s), the
    tick the step's answer is in by."""
    for k, r in enumerate(reactions):
        was = seen[k] if k < len(seen) else (None, None)
        if r.t_reacted is not None and was[0] is None:
            r.t_reacted = max(r.t_reacted, t_in)
        if r.t_resolved is not None and was[1] is None:
            r.t_resolved = max(r.t_resolved, t_in)


def _relabel_lag(reactions: list[Reaction], first_new: int, kicked: bool) -> None:
    """The arm off its motion after an overrunning step lagged; it was not kicked (unless a
    scripted kick came on this tick too)."""
    if kicked:
        return
    for r in reactions[first_new:]:
        if r.kind == "kick":
            r.kind = "lag"


def shrunk_kick(world: World, q: Array, qd: Array, dq: Array, halvings: int,
                limits: Limits, truth: TrueWorld | None = None, t: float = 0.0
                ) -> Array | None:
    """``dq`` (K,) rad, halved until q + dq is within the limits — and so is where it comes to
    rest braking at ``limits.acceleration`` from velocity ``qd`` (a bump does not throw the arm
    past a limit) — and the kicked arm has a way out: going on at ``qd`` for
    :data:`KICK_GO_ON_S` is free (the exact decision on that straight motion, the world's
    obstacles: a bump does not throw a moving arm into the scene faster than any reaction:
    kitchen episodes 2 and 8 had the arm 20 ms from a cabinet at 1.4-2.2 rad/s), and so is
    one of :func:`escape_motions` for :data:`KICK_ESCAPE_S` (fast checker, which is
    conservative: tabletop_container episode 16 had the arm kicked at 1.5 rad/s towards the
    container, where going on for 0.1 s was free but no brake or other motion within the
    limits was, and it hit the container) — with ``truth`` (the episode's moving obstacles;
    the kick comes at time ``t`` s), free of their true motion too (exact checker:
    shelf_boxes seed 3 episode 8 had the arm kicked 0.1 s from the forearm, where no motion
    escaped it); or None."""
    stop = qd * np.abs(qd) / (2 * limits.acceleration)
    for _ in range(halvings + 1):
        q2 = q + dq
        if world.robot.within_limits(np.vstack([q2, q2 + stop])).all() and \
                world.exact.is_valid(q2) and _goes_on_free(world, q2, qd) and \
                _can_escape(world, q2, qd, limits, truth, t):
            return dq
        dq = dq / 2
    return None


KICK_GO_ON_S = 0.1
"""s: how long a kicked arm going on at its velocity must stay free (:func:`shrunk_kick`)."""
KICK_ESCAPE_S = 0.5
"""s: how long one of a kicked arm's escape motions must stay free (:func:`shrunk_kick`)."""
KICK_ESCAPES = 256
"""Random escape motions tried from a kicked state (:func:`escape_motions`)."""
ESCAPE_DT_S = 0.01
"""s: the step of a kicked state's escape motions' positions (:func:`escape_motions`)."""


def _goes_on_free(world: World, q: Array, qd: Array) -> bool:
    """Whether the straight motion q → q + qd·:data:`KICK_GO_ON_S` (rad) is free by the exact
    decision (at most 0.01 rad apart)."""
    end = q + np.asarray(qd) * KICK_GO_ON_S
    substeps = max(1, int(np.ceil(float(np.abs(end - q).max()) / 0.01)))
    return bool(exact_path_decision(world.fast, world.exact, np.vstack([q, end]),
                                    substeps).valid)


def _can_escape(world: World, q: Array, qd: Array, limits: Limits,
                truth: TrueWorld | None = None, t: float = 0.0) -> bool:
    """Whether one of :func:`escape_motions` from (q, qd) stays within the joint limits and
    fast-free (so exactly free) for :data:`KICK_ESCAPE_S`, at 10 ms steps — and, with
    ``truth``, free of its moving obstacles' true motion from time ``t`` (s)."""
    n = round(KICK_ESCAPE_S / ESCAPE_DT_S) + 1
    robot = world.robot
    for Q in escape_motions(q, qd, limits, n, KICK_ESCAPES, np.random.default_rng(0)):
        if robot.within_limits(Q).all() and world.fast.valid(Q).all() and (
                truth is None or not truth.meets(Q[1:], t + ESCAPE_DT_S * np.arange(1.0, n),
                                                 while_present=True)):
            return True
    return False


def escape_motions(q0: Array, v0: Array, limits: Limits, n: int, count: int,
                   rng: np.random.Generator, dt_s: float = ESCAPE_DT_S, *,
                   brake: bool = True, go_s: float | None = None) -> Iterator[Array]:
    """Motions within the limits from q0 (K,) rad at v0 (K,) rad/s, (n, K) each at ``dt_s``
    (s) steps: the brake (each joint decelerating at its limit; with ``brake``), then
    ``count`` with each joint at a constant acceleration drawn uniformly within its limit
    (:func:`constant_acceleration_path`) — with ``go_s``, for a time drawn uniformly up to
    ``go_s`` (s), then braking to rest and resting (:func:`go_stop_path`)."""
    v0 = np.asarray(v0, dtype=float)
    if brake:
        yield constant_acceleration_path(q0, v0, -np.sign(v0) * limits.acceleration, n,
                                         dt_s, limits)
    for _ in range(count):
        acc = rng.uniform(-1, 1, len(q0)) * limits.acceleration
        if go_s is None:
            yield constant_acceleration_path(q0, v0, acc, n, dt_s, limits)
        else:
            yield go_stop_path(q0, v0, acc, float(rng.uniform(0.0, go_s)), n, dt_s, limits)


def go_stop_path(q0: Array, v0: Array, acc: Array, t_go: float, n: int, dt: float,
                 limits: Limits) -> Array:
    """(n, K) rad: from q0 (K,) rad at velocity v0 (K,) rad/s, each joint at constant
    acceleration ``acc`` (K,) rad/s² (velocities clipped at their limits) for ``t_go`` s,
    then decelerating at its limit to rest, and resting; every dt (s), positions advanced by
    each step's mean velocity (:func:`constant_acceleration_path`: why)."""
    Q = np.empty((n, len(q0)))
    Q[0], v = q0, np.asarray(v0, dtype=float)
    for k in range(1, n):
        if k * dt <= t_go:
            v_next = np.clip(v + acc * dt, -limits.velocity, limits.velocity)
        else:
            v_next = v - np.sign(v) * np.minimum(np.abs(v), limits.acceleration * dt)
        Q[k] = Q[k - 1] + 0.5 * (v + v_next) * dt
        v = v_next
    return Q


def constant_acceleration_path(q0: Array, v0: Array, acc: Array, n: int, dt: float,
                               limits: Limits) -> Array:
    """(n, K) rad: from q0 (K,) rad at velocity v0 (K,) rad/s, each joint at constant
    acceleration ``acc`` (K,) rad/s² until its velocity limit, every dt (s). Exact for that
    motion (velocity linear over each step: its positions advance by the step's mean
    velocity), so it stays within the acceleration limits; integrating with the step's end
    velocity would move up to twice as far in the first step (:func:`go_stop_path` that
    never stops)."""
    return go_stop_path(q0, v0, acc, np.inf, n, dt, limits)
