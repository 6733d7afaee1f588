"""An executed episode judged after the fact, by other means than the executive's own checks
(:func:`evaluate_episode`):

* collision: every recorded configuration (control rate) with the exact checker (coal on the
  URDF meshes) against the scene and each moving obstacle at its **true** pose at that instant;
* clearance: coal distances from the robot's moving geometry to the moving obstacles;
* limits: positions within the joint limits; velocities from finite differences of the
  executed positions and accelerations from finite differences of the commanded velocities
  (both exact bounds by the mean value theorem), ticks displaced by a kick left out;
* unavoidable contact (only for an episode with a collision): from the executed state one
  reaction window (sensor period + latency + planning budget) before the first contact (or
  from the kicked state, when a kick came after that),
  :data:`ESCAPES` random motions within the limits (each joint at a constant acceleration
  drawn within its limit, velocities clipped) are tried against the obstacles' true motion
  until :data:`ESCAPE_AFTER_S` after the contact; none collision-free means no motion within
  the limits could have avoided it.

The scripts' rule that a forearm leaves the arm a way out (:func:`forearm_way_out`) is judged
by the same escapes, before the episode runs.

Units: s, rad, m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chekhov.execute.obstacles import MovingObstacle
from chekhov.execute.script import WayOut
from chekhov.execute.simulate import EpisodeRecord, escape_motions
from chekhov.execute.truth import TrueWorld
from chekhov.timing import Limits
from chekhov.world import World

Array = NDArray[np.float64]

ESCAPES = 256
ESCAPE_AFTER_S = 0.3
REL_TOL = 1e-6


@dataclass(frozen=True)
class EpisodeCheck:
    """The after-the-fact verdict: ``collision`` (any recorded configuration in collision),
    ``first_contact_s``, ``min_clearance_m`` to the moving obstacles (inf when none came),
    the per-tick clearances (N,) m, ``limit_violations`` (ticks breaking a limit) and
    ``unavoidable`` (a collision no motion within the limits could have avoided)."""

    collision: bool
    first_contact_s: float | None
    min_clearance_m: float
    clearances: Array
    limit_violations: int
    unavoidable: bool
    violation_kinds: tuple[str, ...] = ()


def evaluate_episode(world: World, record: EpisodeRecord, limits: Limits,
                     window_s: float) -> EpisodeCheck:
    """Judge ``record`` (module docstring); ``window_s``: the reaction window (s)."""
    truth = TrueWorld(world, record.obstacles)
    hits = [i for i, (t, q) in enumerate(zip(record.times, record.q, strict=True))
            if truth.collides(q, float(t))]
    clear = np.array([truth.clearance(q, float(t))
                      for t, q in zip(record.times, record.q, strict=True)])
    first = float(record.times[hits[0]]) if hits else None
    unavoidable = bool(hits) and not _escapable(truth, record, hits[0], limits, window_s)
    kinds = violation_kinds(world, record, limits)
    return EpisodeCheck(bool(hits), first, float(clear.min(initial=np.inf)), clear,
                        limit_violations(world, record, limits), unavoidable, kinds)


def limit_violations(world: World, record: EpisodeRecord, limits: Limits) -> int:
    """Ticks breaking a position, velocity or acceleration limit (module docstring)."""
    if len(record.times) < 2:
        return 0
    bad = ~world.robot.within_limits(record.q, tol=1e-6)
    dt = np.diff(record.times)[:, None]
    v = np.abs(np.diff(record.q, axis=0)) / dt
    a = np.abs(np.diff(record.qd, axis=0)) / dt
    kicked = record.kicked[1:]
    v_bad = (v > limits.velocity * (1 + REL_TOL) + 1e-9).any(axis=1) & ~kicked
    a_bad = (a > limits.acceleration * (1 + REL_TOL) + 1e-9).any(axis=1)
    cmd_bad = ((np.abs(record.qd) > limits.velocity * (1 + REL_TOL) + 1e-9).any(axis=1)
               | (np.abs(record.qdd) > limits.acceleration * (1 + REL_TOL) + 1e-6).any(axis=1))
    bad[1:] |= v_bad | a_bad
    bad |= cmd_bad
    return int(bad.sum())


def violation_kinds(world: World, record: EpisodeRecord, limits: Limits) -> tuple[str, ...]:
    """Which limits are broken and where first: "position@t", "velocity@t", ... (s, mode)."""
    out = []
    if len(record.times) < 2:
        return ()
    dt = np.diff(record.times)[:, None]
    tests = {
        "position": ~world.robot.within_limits(record.q, tol=1e-6),
        "velocity": np.r_[False, ((np.abs(np.diff(record.q, axis=0)) / dt > limits.velocity
                                   * (1 + REL_TOL) + 1e-9).any(axis=1) & ~record.kicked[1:])],
        "acceleration": np.r_[False, (np.abs(np.diff(record.qd, axis=0)) / dt
                                      > limits.acceleration * (1 + REL_TOL) + 1e-9).any(axis=1)],
        "commanded": ((np.abs(record.qd) > limits.velocity * (1 + REL_TOL) + 1e-9).any(axis=1)
                      | (np.abs(record.qdd) > limits.acceleration * (1 + REL_TOL) + 1e-6)
                      .any(axis=1)),
    }
    for name, bad in tests.items():
        if bad.any():
            i = int(np.argmax(bad))
            out.append(f"{name}@{record.times[i]:.2f}s({record.modes[i]}, {int(bad.sum())})")
    return tuple(out)


def _escapable(truth: TrueWorld, record: EpisodeRecord, hit: int, limits: Limits,
               window_s: float) -> bool:
    """Whether one of :data:`ESCAPES` random motions within the limits from the state one
    reaction window before tick ``hit`` — or, when a kick displaced the arm after that, from
    the kicked state (no motion undoes a displacement the script imposes) — stays free until
    :data:`ESCAPE_AFTER_S` after it."""
    t_hit = float(record.times[hit])
    i0 = int(np.searchsorted(record.times, t_hit - window_s))
    kicked = np.flatnonzero(record.kicked[i0:hit + 1])
    if len(kicked):
        i0 += int(kicked[-1])
    return escapes(truth, record.q[i0], record.qd[i0], float(record.times[i0]),
                   t_hit + ESCAPE_AFTER_S, limits, np.random.default_rng(hit), t_hit)


def escapes(truth: TrueWorld, q0: Array, v0: Array, t0: float, t_until: float,
            limits: Limits, rng: np.random.Generator, t_first: float | None = None, *,
            go_s: float | None = None) -> bool:
    """Whether one of :data:`ESCAPES` random motions within the limits (each joint at a
    constant acceleration drawn within its limit, velocities clipped; with ``go_s``, for a
    time drawn up to ``go_s`` s, then braking to rest: :func:`escape_motions`) from q0 (K,)
    rad at v0 (K,) rad/s at time t0 stays within the joint limits and free of ``truth`` at
    every 10 ms step until ``t_until`` (s); each checked nearest ``t_first`` (s, a contact
    expected then) first (:meth:`TrueWorld.meets`)."""
    ts = t0 + np.arange(0.0, t_until - t0, 0.01)[1:]
    for Q in escape_motions(q0, v0, limits, len(ts) + 1, ESCAPES, rng, 0.01, brake=False,
                            go_s=go_s):
        Q = Q[1:]
        if truth.robot.within_limits(Q, tol=0.0).all() and \
                not truth.meets(Q, ts, t0 if t_first is None else t_first):
            return True
    return False


def forearm_way_out(world: World, window_s: float, limits: Limits) -> WayOut:
    """The script's rule that a forearm leaves the arm a way out
    (:data:`~chekhov.execute.script.WayOut`): the arm going on along the motion the forearm is
    aimed at (resting at its end once there) never touches it, or, from that motion's state
    at one of :data:`WAY_OUT_STARTS` instants (:func:`_way_out_ticks`) between one reaction
    window (``window_s`` s: sensor period + latency + planning budget) after the forearm
    appears — before any reaction to it can have begun — and one before the motion's first
    contact, one of :data:`ESCAPES` motions within ``limits`` (each joint at a constant
    acceleration drawn within its limit for up to :data:`WAY_OUT_GO_S`, then braking to rest)
    is free of it until it is gone. A forearm that enters from beyond the arm's reach is seen
    seconds before it arrives; an arm braking to rest as soon as it is seen would often sit
    where it passes, and the way out is to go on and get away later. A
    forearm appearing 0.3 m from an arm moving towards it had left none (panda_cage seed 0
    episode 0, tabletop_pole seed 1 episode 2: 0 of 256 constant accelerations escaped from
    there); nor had one whose sweep ends beside the shoulder, where 64% of the arm's free
    configurations touch it (shelf_boxes seed 1 episode 3: an escape from its first contact
    met it later)."""
    def leaves_way_out(arm: tuple[MovingObstacle, ...], duration_s: float,
                       q_path: Array) -> bool:
        dt = duration_s / max(len(q_path) - 1, 1)
        t_start, t_end = min(m.t_start for m in arm), max(m.t_end for m in arm)
        truth = TrueWorld(world, arm)
        n = int(np.ceil(max(t_end, duration_s) / dt)) + 1

        def at(i: int) -> Array:
            """The motion's configuration at tick i, resting at its end once there."""
            return q_path[min(i, len(q_path) - 1)]

        hit = next((i for i in range(int(t_start / dt), n)
                    if truth.collides(at(i), i * dt)), None)
        if hit is None:
            return True
        first = int(np.ceil((t_start + window_s) / dt))
        last = hit - int(np.ceil(window_s / dt))
        rng = np.random.default_rng(hit)
        for i0 in _way_out_ticks(first, max(last, first), hit):
            v0 = (at(i0 + 1) - at(i0 - 1)) / (2 * dt)
            if escapes(truth, at(i0), v0, i0 * dt, t_end + dt, limits, rng, hit * dt,
                       go_s=WAY_OUT_GO_S):
                return True
        return False
    return leaves_way_out


def _way_out_ticks(first: int, last: int, hit: int) -> list[int]:
    """The ticks from which :func:`forearm_way_out` looks for a way out: up to
    :data:`WAY_OUT_STARTS` evenly from ``first`` to ``last`` (earliest first), all before the
    contact tick ``hit``: going on along the motion until one of them, which is free of the
    forearm until ``hit``, is a motion within the limits too."""
    ticks = np.unique(np.linspace(first, last, WAY_OUT_STARTS).round().astype(int))
    return [int(i) for i in ticks if i < hit]


WAY_OUT_GO_S = 0.5
"""s, the longest a way-out motion accelerates before it brakes to rest
(:func:`forearm_way_out`)."""
WAY_OUT_STARTS = 4
"""How many states along the aimed motion :func:`forearm_way_out` looks for a way out from."""
