"""A simulated robot and sensor around an :class:`~chekhov.execute.executor.Executor`, on a
simulated clock (:func:`run_episode`): every control tick the robot is where the last command
put it (perfect tracking) unless a scripted kick displaces it, the sensor takes a frame of the
obstacles' true poses every ``sensor_period_s`` and delivers it ``sensor_latency_s`` later,
and goal changes arrive when scripted. The executed motion is recorded at the control rate
(:class:`EpisodeRecord`). Units: s, rad.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chekhov.execute.executor import Executor
from chekhov.execute.interface import Counters, Observation, Reaction
from chekhov.execute.obstacles import MovingObstacle, obstacles_at
from chekhov.execute.script import EpisodeScript
from chekhov.robot.goal import Goal
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
    """

    sensor_period_s: float = 1.0 / 30.0
    sensor_latency_s: float = 0.04
    kick_halvings: int = 4


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
    dt = executor.config.control_dt_s
    q = np.array(script.q_start, dtype=float)
    qd = np.zeros_like(q)
    rows: list[tuple[float, Array, Array, Array, bool, str]] = []
    kicks = list(script.kicks)
    changes = list(script.goal_changes)
    applied: list[Array] = []
    next_frame, reached_at = 0, None
    qdd = np.zeros_like(q)
    for i in range(int(np.ceil(deadline_s / dt)) + 1):
        t = i * dt
        kicked = False
        while kicks and kicks[0].t <= t + 1e-9:
            dq = shrunk_kick(world, q, qd, kicks.pop(0).dq, config.kick_halvings,
                              executor.limits.acceleration)
            if dq is not None:
                q, kicked = q + dq, True
                applied.append(dq)
        goal = changes.pop(0).goal if changes and changes[0].t <= t + 1e-9 else None
        frame, stamp = None, None
        if next_frame * config.sensor_period_s + config.sensor_latency_s <= t + 1e-9:
            while (next_frame + 1) * config.sensor_period_s + config.sensor_latency_s <= t + 1e-9:
                next_frame += 1
            stamp = next_frame * config.sensor_period_s
            frame = obstacles_at(script.obstacles, stamp)
            next_frame += 1
        cmd = executor.step(Observation(t, q, qd, frame, stamp, goal))
        rows.append((t, q.copy(), qd.copy(), qdd.copy(), kicked, cmd.mode))
        if executor.done and t >= script.last_event_s and not changes and not kicks:
            reached_at = t
            break
        q, qd, qdd = np.array(cmd.q), np.array(cmd.qd), np.array(cmd.qdd)
    return EpisodeRecord(
        np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
        np.array([r[2] for r in rows]), np.array([r[3] for r in rows]),
        np.array([r[4] for r in rows], dtype=bool), tuple(r[5] for r in rows),
        script.obstacles, executor.goal, reached_at is not None, reached_at,
        tuple(executor.reactions), executor.counters, tuple(applied))


def shrunk_kick(world: World, q: Array, qd: Array, dq: Array, halvings: int,
                 acceleration: Array) -> Array | None:
    """``dq`` (K,) rad, halved until q + dq is within the limits — and so is where it comes to
    rest braking at ``acceleration`` (K,) rad/s² from velocity ``qd`` (a bump does not throw
    the arm past a limit) — and free (exact checker, the world's obstacles), or None."""
    stop = qd * np.abs(qd) / (2 * acceleration)
    for _ in range(halvings + 1):
        q2 = q + dq
        if world.robot.within_limits(np.vstack([q2, q2 + stop])).all() and \
                world.exact.is_valid(q2):
            return dq
        dq = dq / 2
    return None
