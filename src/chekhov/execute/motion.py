"""What the arm is commanded to do over time: a :class:`Motion`, pieces of motion laid end to
end on the executive's clock, and the three ways the executive makes one:

* :func:`join`: from any state (position, velocity, acceleration) onto a timed trajectory with
  Ruckig (jerk-limited, time-optimal, Berscheid & Kröger 2021): the trajectory's state some
  time into it is the target, so velocity and acceleration never jump;
* :func:`brake_along`: to rest **along the path** the arm is on, as fast as the limits allow
  (a time scaling s(t) of the current motion, decelerating greedily at each step; the
  commanded state is the scaling's exact one, so positions stay on the path and within the
  joint limits where it is);
* :func:`stop_from`: to rest off any path (after a kick), each joint braking on its own and
  kept within the joint position limits;
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

from chekhov.execute.brake_kernel import DONE, NEED_GRID, brake_steps
from chekhov.execute.ruckig_batch import batch_sampler
from chekhov.timing import Limits
from chekhov.trajectory import JointTrajectory

Array = NDArray[np.float64]

JOIN_JERK_SCALE = 20.0
"""A join's jerk limit: this × the timing's (the timing's 30 rad/s³ makes joins slow; the
acceleration limits still hold)."""
BRAKE_DT_S = 0.002
"""s, the step of the braking time scaling."""
BRAKE_SHARE = 0.85
"""The share of the acceleration limits a brake's greedy steps aim at (at the start of each
step; :data:`BRAKE_END_SHARE` at its end)."""
BRAKE_END_SHARE = 0.95
"""The share of the acceleration limits a brake step may reach at its end (a step is
halved until it does): a margin for the finite-difference checks of the executed motion."""
BRAKE_GRID_S = 5e-4
"""s, the grid of the braked motion's own time on which a brake reads q̇ and q̈."""
BRAKE_CHUNK_S = 0.25
"""s, how much of that grid is sampled at once."""
STOP_JERK_SCALE = 1e5
"""A stop's jerk limit when the join's would carry a joint past its position limit: this ×
the timing's (near a step in acceleration; accelerations still within their limits)."""


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
Batch = Callable[[Array], tuple[Array, Array, Array]]
"""A piece's states at times (N,) s from its start (vectorised): q (N, K) rad, q̇ (N, K)
rad/s, q̈ (N, K) rad/s²."""


@dataclass(frozen=True)
class Piece:
    """One piece of a motion: ``sample(t - t_start)`` for t in [t_start, t_end] (s)."""

    t_start: float
    t_end: float
    sample: Sampler
    kind: str
    batch: Batch | None = None

    def states(self, ts: Array) -> tuple[Array, Array, Array]:
        """(q, q̇, q̈), each (N, K), at clock times ts (N,) s within the piece."""
        local = np.clip(ts - self.t_start, 0.0, self.t_end - self.t_start)
        if self.batch is not None:
            return self.batch(local)
        S = [self.sample(float(u)) for u in local]
        return (np.array([x.q for x in S]), np.array([x.qd for x in S]),
                np.array([x.qdd for x in S]))


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
        return ts, self.states_at(ts)[0]

    def states_at(self, ts: Array) -> tuple[Array, Array, Array]:
        """(q, q̇, q̈), each (N, K), at clock times ts (N,) s (like :meth:`sample`; after the
        end at rest at its last position)."""
        after = ts > self.t_end
        if len(self.pieces) == 1:   # a dodge, stop or plan: no piece to tell apart
            q, qd, qdd = self.pieces[0].states(ts)
            qd[after], qdd[after] = 0.0, 0.0
            return q, qd, qdd
        k = len(self.pieces[0].sample(0.0).q)
        out = (np.empty((len(ts), k)), np.zeros((len(ts), k)), np.zeros((len(ts), k)))
        done = np.zeros(len(ts), dtype=bool)
        for p in self.pieces:
            m = ~done & (ts < p.t_end)
            if p is self.pieces[-1]:
                m = ~done
            if m.any():
                for a, b in zip(out, p.states(ts[m]), strict=True):
                    a[m] = b
                done |= m
        out[1][after], out[2][after] = 0.0, 0.0
        return out

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

    def batch(ts: Array) -> tuple[Array, Array, Array]:
        return traj.sample(offset + ts)
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
    """The time-optimal jerk-limited piece from ``start`` to ``goal`` starting at t0. The
    joint position ``bounds`` are handed to Ruckig, but the community Ruckig does not keep
    them (a piece may pass a limit): callers check the positions."""
    dof = len(start.q)
    inp = InputParameter(dof)
    _bound(inp, bounds)
    inp.current_position, inp.current_velocity = list(start.q), list(start.qd)
    inp.current_acceleration = list(braking_room(start, limits, limits.jerk * JOIN_JERK_SCALE))
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
    return Piece(t0, t0 + traj.duration, sample, kind, batch_sampler(traj))


def accelerating(start: State, t0: float, acc: Array, duration_s: float, limits: Limits
                 ) -> Piece:
    """From ``start`` at clock time t0 (s), each joint at the constant acceleration ``acc``
    (K,) rad/s² (within the limits) for ``duration_s`` s — until its velocity limit, then at
    that velocity. Its acceleration steps at t0 (no jerk limit: the swerve of a kicked arm
    :meth:`~chekhov.execute.swerve.Swerver.swerve`, when every smooth move is in contact
    within a tick or two)."""
    a = np.asarray(acc, dtype=float)

    def batch(us: Array) -> tuple[Array, Array, Array]:
        q, qd, qdd = accelerating_states(start, a[None], np.asarray(us, dtype=float), limits)
        return q[0], qd[0], qdd[0]

    def sample(u: float) -> State:
        q, qd, qdd = batch(np.array([u]))
        return State(q[0], qd[0], qdd[0])
    return Piece(t0, t0 + duration_s, sample, "swerve", batch)


def accelerating_states(start: State, A: Array, us: Array, limits: Limits
                        ) -> tuple[Array, Array, Array]:
    """(q, q̇, q̈), each (N, M, K), of N :func:`accelerating` moves from ``start`` at the
    accelerations A (N, K) rad/s², at times us (M,) s from their start."""
    v0 = np.clip(np.asarray(start.qd, dtype=float), -limits.velocity, limits.velocity)
    a = A[:, None, :]
    v_cap = np.where(a > 0, limits.velocity, -limits.velocity)
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = np.where(a != 0, (v_cap - v0) / a, np.inf)   # s, until the velocity limit
    u = us[None, :, None]
    ua = np.minimum(u, tau)
    q = start.q + v0 * ua + 0.5 * a * ua * ua + (v0 + a * ua) * (u - ua)
    return q, v0 + a * ua, np.where(u < tau, a, 0.0)


def braking_room(start: State, limits: Limits, jerk: Array) -> Array:
    """start's acceleration (K,) rad/s², within the limits and such that bringing it to 0 at
    ``jerk`` (K,) rad/s³ keeps the velocity within its limit: where it pushes the velocity
    outwards, |q̈| ≤ sqrt(2 j (v_max - |q̇|)) (0 at the limit). A timed plan leaves a cruise's
    first instant at full velocity with the ramp's full acceleration (its acceleration switches
    there); a join from that state overshot the velocity limit by 1.2% (a Kinova Jaco's
    0.63 rad/s joint: 0.636 rad/s)."""
    a = np.clip(start.qdd, -limits.acceleration, limits.acceleration)
    cap = np.sqrt(2 * jerk * np.maximum(limits.velocity - np.abs(start.qd), 0.0))
    outwards = a * start.qd > 0
    return np.where(outwards, np.clip(a, -cap, cap), a)


def stop_from(start: State, t0: float, limits: Limits, bounds: Bounds | None = None
              ) -> Motion:
    """To rest from ``start`` (off any path: after a kick) by Ruckig's velocity interface,
    each joint braking at once on its own (no time synchronisation: the shortest stop of
    every joint). Ruckig does not enforce position limits, so with ``bounds`` a stop that
    would pass one is made again with :data:`STOP_JERK_SCALE` × the jerk (the acceleration
    limits still hold; only a stop that no braking within them keeps inside is left out)."""
    best: tuple[float, Trajectory] | None = None
    for scale in (JOIN_JERK_SCALE, STOP_JERK_SCALE):
        traj = _velocity_stop(start, limits, scale)
        over = 0.0 if bounds is None else _overshoot(traj, bounds)
        if best is None or over < best[0]:
            best = (over, traj)
        if over <= 0.0:
            break
    assert best is not None
    traj = best[1]

    def sample(t: float) -> State:
        q, qd, qdd = traj.at_time(min(max(t, 0.0), traj.duration))
        return State(np.asarray(q), np.asarray(qd), np.asarray(qdd))
    return Motion((Piece(t0, t0 + traj.duration, sample, "brake", batch_sampler(traj)),))


def _velocity_stop(start: State, limits: Limits, jerk_scale: float) -> Trajectory:
    """Ruckig's unsynchronised stop from ``start`` at ``jerk_scale`` × the jerk limits."""
    from ruckig import ControlInterface, Synchronization
    dof = len(start.q)
    inp = InputParameter(dof)
    inp.control_interface = ControlInterface.Velocity
    inp.synchronization = Synchronization.No
    inp.current_position, inp.current_velocity = list(start.q), list(start.qd)
    inp.current_acceleration = list(braking_room(start, limits, limits.jerk * jerk_scale))
    inp.target_velocity, inp.target_acceleration = [0.0] * dof, [0.0] * dof
    inp.max_velocity = list(limits.velocity)
    inp.max_acceleration = list(limits.acceleration)
    inp.max_jerk = list(limits.jerk * jerk_scale)
    traj = Trajectory(dof)
    Ruckig(dof).calculate(inp, traj)
    return traj


def _overshoot(traj: Trajectory, bounds: Bounds) -> float:
    """rad, how far the Ruckig trajectory goes past ``bounds`` at most (0 when it does not)."""
    ext = traj.position_extrema
    lo = np.array([e.min for e in ext])
    hi = np.array([e.max for e in ext])
    return float(max(np.max(bounds.lower - lo), np.max(hi - bounds.upper), 0.0))


@dataclass(frozen=True, eq=False)
class _Scaling:
    """A braking time scaling: from clock times ``t`` (N,) s on, the path parameter (the
    braked motion's own time) is ``s`` (N,) s at rate ``sd`` (N,) and decreases its rate at
    ``sdd`` (N,) 1/s until the next time (constant within each step); at rest after the
    last."""

    motion: Motion
    t: Array
    s: Array
    sd: Array
    sdd: Array

    def _at(self, u: Array) -> tuple[Array, Array, Array]:
        """(s, ṡ, -s̈), each (N,), at times u (N,) s from the scaling's start."""
        k = np.clip(np.searchsorted(self.t, u, side="right") - 1, 0, len(self.t) - 1)
        last = k == len(self.t) - 1
        tau = np.where(last, 0.0, np.clip(u - self.t[k], 0.0, None))
        sdd = np.where(last, 0.0, self.sdd[k])
        s = np.minimum(self.s[k] + self.sd[k] * tau - 0.5 * sdd * tau * tau, self.motion.t_end)
        return s, np.maximum(self.sd[k] - sdd * tau, 0.0), sdd

    def sample(self, u: float) -> State:
        s, sd, sdd = (float(x[0]) for x in self._at(np.array([u])))
        m = self.motion.sample(s)
        return State(m.q, m.qd * sd, m.qdd * sd * sd - m.qd * sdd)

    def batch(self, us: Array) -> tuple[Array, Array, Array]:
        s, sd, sdd = self._at(np.asarray(us, dtype=float))
        Q, V, A = self.motion.states_at(s)
        return Q, V * sd[:, None], A * (sd * sd)[:, None] - V * sdd[:, None]


class _Grid:
    """The braked motion's q̇ and q̈ (each (G, K)) on a grid of its own time every
    :data:`BRAKE_GRID_S` from ``s0``, sampled in chunks of :data:`BRAKE_CHUNK_S` as the
    brake's steps need them."""

    def __init__(self, motion: Motion, s0: float) -> None:
        self.motion, self.s0 = motion, s0
        k = len(motion.sample(s0).q)
        self.V, self.A = np.empty((0, k)), np.empty((0, k))

    def extend(self) -> None:
        n = len(self.V)
        k = np.arange(n, n + round(BRAKE_CHUNK_S / BRAKE_GRID_S), dtype=float)
        _, V, A = self.motion.states_at(self.s0 + BRAKE_GRID_S * k)
        self.V, self.A = np.vstack([self.V, V]), np.vstack([self.A, A])


def brake_along(motion: Motion, t0: float, limits: Limits) -> Motion:
    """``motion`` from clock time t0, slowed to rest along its own path as fast as the limits
    allow: s(t) with ṡ(t0) = 1 and s̈ ≤ 0, constant over each :data:`BRAKE_DT_S` step and the
    most negative keeping every joint's acceleration q̈(s) ṡ² + q̇(s) s̈ within
    :data:`BRAKE_SHARE` of its limit at the start of the step and :data:`BRAKE_END_SHARE` at
    its end (q̇, q̈ the motion's own, interpolated on a grid; a step is halved until it is,
    at most four times). The commanded state is the exact one of that scaling: positions on
    the motion's path (within the joint limits where it is), velocity q̇ ṡ never above the
    motion's own. The steps run compiled (:mod:`~chekhov.execute.brake_kernel`)."""
    a = np.ascontiguousarray(limits.acceleration * BRAKE_SHARE)
    end_a = np.ascontiguousarray(limits.acceleration * BRAKE_END_SHARE)
    grid = _Grid(motion, t0)
    state = np.array([0.0, t0, 1.0])
    rows, n = np.empty((512, 4)), 0
    while True:
        n, why = brake_steps(grid.V, grid.A, t0, BRAKE_GRID_S, motion.t_end, a, end_a,
                             BRAKE_DT_S, state, rows, n)
        if why == DONE:
            break
        if why == NEED_GRID:
            grid.extend()
        else:
            rows = np.vstack([rows, np.empty_like(rows)])
    done = rows[:n]
    ts = np.concatenate([[0.0], done[:, 0]])
    ss = np.concatenate([[t0], done[:, 1]])
    sds = np.concatenate([[1.0], done[:, 2]])
    sds[-1] = 0.0
    sdds = np.concatenate([done[:, 3], [0.0]])
    scaling = _Scaling(motion, ts, ss, sds, sdds)
    return Motion((Piece(t0, t0 + ts[-1], scaling.sample, "brake", scaling.batch),))


def stop_time(state: State, limits: Limits) -> float:
    """s, about how long braking from ``state`` takes (the slowest joint at full
    deceleration)."""
    return float(np.max(np.abs(state.qd) / limits.acceleration, initial=0.0))
