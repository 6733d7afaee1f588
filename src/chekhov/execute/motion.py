"""What the arm is commanded to do over time: a :class:`Motion`, pieces of motion laid end to
end on the executive's clock, and the three ways the executive makes one:

* :func:`join`: from any state (position, velocity, acceleration) onto a timed trajectory with
  Ruckig (jerk-limited, time-optimal, Berscheid & Kröger 2021): the trajectory's state some
  time into it is the target, so velocity and acceleration never jump;
* :func:`brake_along`: to rest **along the path** the arm is on, as fast as the limits allow
  (a time scaling s(t) of the current motion, decelerating greedily at each step);
* :func:`hold`: at rest at a configuration.

Units: rad, rad/s, rad/s², s. A motion's times are absolute (the executive's clock).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from ruckig import InputParameter, Result, Ruckig, Trajectory

from chekhov.timing import Limits
from chekhov.trajectory import JointTrajectory

Array = NDArray[np.float64]

JOIN_JERK_SCALE = 20.0
"""A join's jerk limit: this × the timing's (the timing's 30 rad/s³ makes joins slow; the
acceleration limits still hold)."""
BRAKE_DT_S = 0.002
"""s, the step of the braking time scaling."""
BRAKE_SHARE = 0.85
"""The share of the acceleration limits a brake uses: its greedy steps and their
interpolation stay within the limits."""


class Bounds(NamedTuple):
    """Joint position limits: lower (K,), upper (K,) rad."""

    lower: Array
    upper: Array


def _bound(inp: InputParameter, bounds: Bounds | None) -> None:
    if bounds is not None:
        inp.min_position, inp.max_position = list(bounds.lower), list(bounds.upper)


class State(NamedTuple):
    """The arm's state: q (K,) rad, qd (K,) rad/s, qdd (K,) rad/s²."""

    q: Array
    qd: Array
    qdd: Array


Sampler = Callable[[float], State]
"""A piece's state at a time (s) from the piece's own start."""
Batch = Callable[[Array], Array]
"""A piece's positions (N, K) rad at times (N,) s from its start (vectorised)."""


@dataclass(frozen=True)
class Piece:
    """One piece of a motion: ``sample(t - t_start)`` for t in [t_start, t_end] (s)."""

    t_start: float
    t_end: float
    sample: Sampler
    kind: str
    batch: Batch | None = None

    def positions(self, ts: Array) -> Array:
        """Positions (N, K) rad at clock times ts (N,) s within the piece."""
        local = np.clip(ts - self.t_start, 0.0, self.t_end - self.t_start)
        if self.batch is not None:
            return self.batch(local)
        return np.array([self.sample(float(u)).q for u in local])


@dataclass(frozen=True)
class Motion:
    """Pieces on the executive's clock, in order, each starting where the one before ends;
    after the last one the arm rests at its end (``sample`` beyond ``t_end`` returns that).

    Attributes:
        pieces: the pieces. goal_q: (K,) rad, where the motion ends.
    """

    pieces: tuple[Piece, ...]

    @property
    def t_start(self) -> float:
        return self.pieces[0].t_start

    @property
    def t_end(self) -> float:
        return self.pieces[-1].t_end

    @property
    def end(self) -> State:
        return self.sample(self.t_end)

    def sample(self, t: float) -> State:
        """The commanded state at time t (s): before the start the first state, after the end
        the last position at rest."""
        if t >= self.t_end:
            p = self.pieces[-1]
            s = p.sample(p.t_end - p.t_start)
            z = np.zeros_like(s.q)
            return State(s.q, z, z) if t > self.t_end else s
        for p in self.pieces:
            if t < p.t_end:
                return p.sample(max(t, p.t_start) - p.t_start)
        raise AssertionError("unreachable")

    def kind_at(self, t: float) -> str:
        for p in self.pieces:
            if t < p.t_end:
                return p.kind
        return "rest"

    def positions(self, t0: float, t1: float, dt: float) -> tuple[Array, Array]:
        """(times (N,), positions (N, K)) every ``dt`` s from t0 to t1 (both included)."""
        ts = np.arange(t0, t1, dt)
        ts = np.append(ts, t1) if len(ts) == 0 or ts[-1] < t1 else ts
        Q = np.empty((len(ts), len(self.pieces[0].sample(0.0).q)))
        done = np.zeros(len(ts), dtype=bool)
        for p in self.pieces:
            m = ~done & (ts < p.t_end)
            if p is self.pieces[-1]:
                m = ~done
            if m.any():
                Q[m] = p.positions(ts[m])
                done |= m
        return ts, Q

    def until(self, t: float) -> Motion:
        """This motion up to time t: the pieces that start before t, the last one cut at t."""
        kept = [p for p in self.pieces if p.t_start < t] or [self.pieces[0]]
        last = kept[-1]
        if last.t_end > t:
            kept[-1] = Piece(last.t_start, max(t, last.t_start), last.sample, last.kind,
                             last.batch)
        return Motion(tuple(kept))

    def rebased(self, t_from: float, t_new: float) -> Motion:
        """This motion from its time ``t_from`` on, moved to start at clock time ``t_new``."""
        shift = t_new - t_from
        out = []
        for p in self.pieces:
            if p.t_end <= t_from and p is not self.pieces[-1]:
                continue
            start = max(p.t_start, t_from)
            skip = start - p.t_start
            batch = p.batch
            out.append(Piece(start + shift, max(p.t_end, start) + shift,
                             _skipped(p.sample, skip), p.kind,
                             None if batch is None else _skipped_batch(batch, skip)))
        return Motion(tuple(out))

    def then(self, other: Motion) -> Motion:
        """This motion cut at ``other``'s start, followed by ``other``."""
        return Motion(self.until(other.t_start).pieces + other.pieces)


def _skipped(sample: Sampler, skip: float) -> Sampler:
    return sample if skip == 0 else (lambda t: sample(t + skip))


def _skipped_batch(batch: Batch, skip: float) -> Batch:
    return batch if skip == 0 else (lambda ts: batch(ts + skip))


def trajectory_motion(traj: JointTrajectory, t0: float, *, offset: float = 0.0,
                      kind: str = "plan") -> Motion:
    """``traj`` from its time ``offset`` (s) on, started at clock time t0 (s)."""
    def sample(t: float) -> State:
        q, qd, qdd = traj.sample(offset + t)
        return State(q, qd, qdd)

    def batch(ts: Array) -> Array:
        return traj.sample(offset + ts)[0]
    return Motion((Piece(t0, t0 + max(traj.duration - offset, 0.0), sample, kind, batch),))


def hold(q: Array, t0: float) -> Motion:
    """At rest at q (K,) rad from clock time t0."""
    z = np.zeros_like(q)
    state = State(np.array(q, dtype=float), z, z)
    return Motion((Piece(t0, t0, lambda t: state, "rest"),))


def join(start: State, t0: float, target: Motion, t_target: float, limits: Limits,
         bounds: Bounds | None = None) -> Motion | None:
    """From ``start`` at clock time t0 onto ``target`` at its time ``t_target`` (s): a Ruckig
    piece to the target's state there, then the target from there on, shifted to follow. None
    when Ruckig finds no motion (e.g. a start state outside the limits)."""
    piece = ruckig_piece(start, target.sample(t_target), t0, limits, "join", bounds)
    if piece is None:
        return None
    return Motion((piece, *target.rebased(t_target, piece.t_end).pieces))


def ruckig_piece(start: State, goal: State, t0: float, limits: Limits, kind: str,
                 bounds: Bounds | None = None) -> Piece | None:
    """The time-optimal jerk-limited piece from ``start`` to ``goal`` starting at t0, within
    the joint position ``bounds`` when given."""
    dof = len(start.q)
    inp = InputParameter(dof)
    _bound(inp, bounds)
    inp.current_position, inp.current_velocity = list(start.q), list(start.qd)
    inp.current_acceleration = list(np.clip(start.qdd, -limits.acceleration,
                                            limits.acceleration))
    inp.target_position, inp.target_velocity = list(goal.q), list(goal.qd)
    a_goal = np.clip(goal.qdd, -limits.acceleration, limits.acceleration)
    inp.target_acceleration = list(np.where(np.abs(a_goal) < 1e-9, 0.0, a_goal))
    inp.max_velocity = list(limits.velocity)
    inp.max_acceleration = list(limits.acceleration)
    inp.max_jerk = list(limits.jerk * JOIN_JERK_SCALE)
    traj = Trajectory(dof)
    try:
        result = Ruckig(dof).calculate(inp, traj)
    except Exception:   # ruckig.RuckigError: no motion for these states
        return None
    if result not in (Result.Working, Result.Finished):
        return None

    def sample(t: float) -> State:
        q, qd, qdd = traj.at_time(min(max(t, 0.0), traj.duration))
        return State(np.asarray(q), np.asarray(qd), np.asarray(qdd))
    return Piece(t0, t0 + traj.duration, sample, kind)


def stop_from(start: State, t0: float, limits: Limits, bounds: Bounds | None = None
              ) -> Motion:
    """To rest from ``start`` (off any path: after a kick) by Ruckig's velocity interface,
    each joint braking at once (within the position ``bounds`` when given)."""
    from ruckig import ControlInterface
    dof = len(start.q)
    inp = InputParameter(dof)
    _bound(inp, bounds)
    inp.control_interface = ControlInterface.Velocity
    inp.current_position, inp.current_velocity = list(start.q), list(start.qd)
    inp.current_acceleration = list(np.clip(start.qdd, -limits.acceleration,
                                            limits.acceleration))
    inp.target_velocity, inp.target_acceleration = [0.0] * dof, [0.0] * dof
    inp.max_velocity = list(limits.velocity)
    inp.max_acceleration = list(limits.acceleration)
    inp.max_jerk = list(limits.jerk * JOIN_JERK_SCALE)
    traj = Trajectory(dof)
    try:
        Ruckig(dof).calculate(inp, traj)
    except Exception:   # ruckig.RuckigError: a joint too near its bound to stop within it
        if bounds is None:
            raise
        return stop_from(start, t0, limits, None)

    def sample(t: float) -> State:
        q, qd, qdd = traj.at_time(min(max(t, 0.0), traj.duration))
        return State(np.asarray(q), np.asarray(qd), np.asarray(qdd))
    return Motion((Piece(t0, t0 + traj.duration, sample, "brake"),))


def brake_along(motion: Motion, t0: float, limits: Limits) -> Motion:
    """``motion`` from clock time t0, slowed to rest along its own path as fast as the limits
    allow: s(t) with ṡ(t0) = 1 and s̈ ≤ 0 the most negative keeping every joint's acceleration
    q̈(s) ṡ² + q̇(s) s̈ within its limit (q̇, q̈ the motion's own), stepped every
    :data:`BRAKE_DT_S`. The positions stay on the motion's path; the velocity (q̇ ṡ) never
    exceeds the motion's own."""
    s, sd = t0, 1.0
    times, Q, V = [0.0], [], []
    first = motion.sample(t0)
    Q.append(first.q)
    V.append(first.qd)
    while sd > 0 and s < motion.t_end:
        m = motion.sample(s)
        sdd = _deceleration(m, sd, limits.acceleration * BRAKE_SHARE)
        step = min(BRAKE_DT_S, sd / sdd) if sdd > 0 else BRAKE_DT_S
        if step < 1e-6:
            break
        s = s + sd * step - 0.5 * sdd * step * step
        sd = max(sd - sdd * step, 0.0)
        n = motion.sample(min(s, motion.t_end))
        times.append(times[-1] + step)
        Q.append(n.q)
        V.append(n.qd * sd)
    V[-1] = np.zeros_like(V[-1])
    traj = JointTrajectory.from_velocities(tuple(f"j{i}" for i in range(len(first.q))),
                                           np.array(times), np.array(Q), np.array(V))
    return trajectory_motion(traj, t0, kind="brake")


def _deceleration(m: State, sd: float, a: Array) -> float:
    """The largest k ≥ 0 with |q̈ ṡ² - q̇ k| ≤ a (K,) for every joint (0 when none is)."""
    base = m.qdd * sd * sd
    hi = np.inf
    lo = 0.0
    for v, b, lim in zip(m.qd, base, a, strict=True):
        if abs(v) < 1e-9:
            continue
        k1, k2 = (b - lim) / v, (b + lim) / v
        lo, hi = max(lo, min(k1, k2)), min(hi, max(k1, k2))
    return float(hi) if hi >= lo and np.isfinite(hi) else 0.0


def stop_time(state: State, limits: Limits) -> float:
    """s, about how long braking from ``state`` takes (the slowest joint at full
    deceleration)."""
    return float(np.max(np.abs(state.qd) / limits.acceleration, initial=0.0))
