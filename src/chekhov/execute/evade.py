"""Getting out of a moving obstacle's way when there is no time to wait for a plan
(:class:`Evader`): motions judged against the obstacles' predicted motion window by window
(:meth:`Evader.safe_in_time`), and dodges (:meth:`Evader.dodge`) — Ruckig moves to nearby
configurations: some pushed away from the predicted obstacles through the Jacobians of the
arm's points nearest them, the rest random — of which the nearest safe one is taken — and,
when neither a dodge nor a stop is safe, escapes (:meth:`Evader.escapes`). What a kicked arm
does until those are judged (a join back, the stop, or a swerve) is
:mod:`chekhov.execute.swerve`'s, on top of this module.

Units: s, rad, m.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.packed import PackedWorld
from chekhov.collision.primitives import pack_primitives
from chekhov.execute.motion import (
    Bounds,
    Motion,
    State,
    brake_along,
    ruckig_piece,
    stop_from,
    stop_time,
)
from chekhov.execute.obstacles import ObstacleTracks, predicted_primitives, to_segment
from chekhov.timing import Limits
from chekhov.world import World

Array = NDArray[np.float64]

DODGE_CANDIDATES = 64
"""Random dodge targets tried besides the directed ones."""
DODGE_CHUNK = 8
"""Dodge targets checked at a time (nearest first) before looking further (the answer does
not depend on it). Measured on the free clock (6 episodes each of panda_cage, shelf_boxes and
tabletop_pole, one run per size, alternating): dodges that found a move took 11.6 / 7.6 /
29.6 ms (mean / p50 / p95) at 16, 10.0 / 5.3 / 25.8 at 8; at 4, 8.9 / 3.8 / 25.3 against
10.5 / 7.2 / 24.3 at 8, but dodges that found none took longer."""
DODGE_RAD = 0.7
"""rad, the largest joint offset of a dodge's target."""
DODGE_STEPS_M = (0.12, 0.25, 0.4)
"""m, how far a directed dodge moves the arm's point nearest an obstacle (first order)."""
DODGE_POINTS = 3
"""How many of the arm's points nearest the predicted obstacles directed dodges push."""
DAMPING = 0.05
"""The damping of the least-squares Jacobian steps (m)."""
WINDOW_S = 0.1
"""s, the time windows of :meth:`Evader.safe_in_time` after the first."""
FIRST_WINDOW_S = 0.03
"""s, the first window (:func:`window_edges`): an arm a tick late onto a dodge found a tick
earlier is often inside the sweep of the forearm's next 0.1 s (it is in the forearm's way:
that is why it dodges), and every move from there was judged unsafe at its first sample."""
"""s, the time windows of :meth:`Evader.safe_in_time`."""
FD_RAD = 1e-4
"""rad, the finite-difference step of the points' Jacobians."""
HOLD_STEP_S = 0.1
"""s, how much earlier each next brake start :meth:`Evader.hold_short` tries is."""
HOLD_TRIES = 5
"""How many brake starts :meth:`Evader.hold_short` tries."""
UNSTICK_S = 0.3
"""s, how soon :meth:`Evader.unstick`'s move must be out of the collision it starts in."""
COARSE = 4
"""Every how many samples of a motion :meth:`Evader.safe_in_time` checks first."""
STOP_APART_RAD = 0.1
"""rad: an arm that would stop farther than this from where it is (any joint) gets dodge
targets around its stop too."""
ESCAPE_TRIES = 64
"""Random constant accelerations :meth:`Evader.escapes` tries."""
ESCAPE_S = 0.3
"""s, how long an escape follows its acceleration before it stops."""


def window_edges(horizon_s: float, window_s: float | None = None) -> Array:
    """s from a window set's start: 0, :data:`FIRST_WINDOW_S`, then every :data:`WINDOW_S`
    to the horizon (at least one window); with ``window_s`` (s), every ``window_s`` from 0
    to the horizon instead."""
    if window_s is not None:
        return np.arange(0.0, horizon_s + 1e-9, window_s)
    rest = np.arange(WINDOW_S, horizon_s + WINDOW_S - 1e-9, WINDOW_S)
    return np.concatenate([[0.0], [min(FIRST_WINDOW_S, rest[0])], rest[rest > FIRST_WINDOW_S]])


@dataclass(frozen=True)
class _CutSearch:
    """A dodge search stopped at its deadline: its targets (N, K) rad, and which of them were
    found unsafe, per margin (None: the settings')."""

    targets: Array
    tried: dict[float | None, NDArray[np.bool_]]


@dataclass(frozen=True)
class EvadeSettings:
    """What an :class:`Evader` needs of the executive's configuration: ``horizon_s`` (s) of
    prediction, ``margin_m`` (m) of inflation, ``check_dt_s`` (s) between checked
    configurations, ``obstacle_speed_m_s`` (m/s) the speed bound of an obstacle seen once
    (:func:`~chekhov.execute.obstacles.predicted_obstacles`)."""

    horizon_s: float
    margin_m: float
    check_dt_s: float
    obstacle_speed_m_s: float = 0.0


class Samples(NamedTuple):
    """Several motions' configurations, one after another: time ``t`` (N,) s, positions ``Q``
    (N, K) rad, ``owner`` (N,) the motion's index, ``step`` (N,) the sample's index within
    its motion."""

    t: Array
    Q: Array
    owner: NDArray[np.int64]
    step: NDArray[np.int64]

    @classmethod
    def of(cls, samples: list[tuple[Array, Array]]) -> Samples:
        """From each motion's (times (n,), positions (n, K)), in order (one motion at
        least)."""
        n = np.array([len(ts) for ts, _ in samples], dtype=np.int64)
        return cls(np.concatenate([ts for ts, _ in samples]),
                   np.vstack([Q for _, Q in samples]), np.repeat(np.arange(len(n)), n),
                   np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n))


class Evader:
    """Judges and makes evasive motions in ``world`` (its fast checker is not changed: the
    predicted sweeps are packed beside its obstacles, ``FastChecker.packed_with``)."""

    def __init__(self, world: World, tracks: ObstacleTracks, settings: EvadeSettings,
                 limits: Limits, bounds: Bounds, seed: int = 0) -> None:
        self.world, self.tracks, self.settings = world, tracks, settings
        self.limits, self.bounds = limits, bounds
        self.rng = np.random.default_rng(seed)
        self._windows: dict[tuple[float, float, float | None, float], list[PackedWorld]] = {}
        self._windows_of: object = None
        self._cut: _CutSearch | None = None

    def windows(self, t0: float, margin_m: float | None = None,
                window_s: float | None = None, *,
                speed_bound_m_s: float | None = None) -> list[PackedWorld]:
        """The fast checker's packed world holding each window's (:func:`window_edges`, of
        ``window_s`` when given) predicted sweep from t0 (s) over the horizon (inflated by
        ``margin_m``, m; the settings' by default; a track seen once moving at up to
        ``speed_bound_m_s``, m/s, the settings' by default), for :meth:`safe_in_time`; the checker
        itself is not changed (``FastChecker.packed_with``). Kept until the tracks change (a
        sensor frame): a tick's reactions ask for the same windows several times."""
        c, fast = self.settings, self.world.fast
        margin = c.margin_m if margin_m is None else margin_m
        bound = c.obstacle_speed_m_s if speed_bound_m_s is None else speed_bound_m_s
        if self._windows_of is not self.tracks.tracks:
            self._windows, self._windows_of = {}, self.tracks.tracks
        key = (t0, margin, window_s, bound)
        kept = self._windows.get(key)
        if kept is not None:
            return kept
        edges = window_edges(c.horizon_s, window_s)
        packs = [fast.packed_with(predicted_primitives(self.tracks, t0 + a, b - a, margin,
                                                       speed_bound_m_s=bound))
                 for a, b in itertools.pairwise(edges)]
        if len(self._windows) >= 8:
            self._windows.clear()
        self._windows[key] = packs
        return packs

    def safe_in_time(self, motions: list[Motion], t0: float,
                     margin_m: float | None = None, *,
                     windows: list[PackedWorld] | None = None) -> NDArray[np.bool_]:
        """Which ``motions`` (all starting at t0, s) are within the limits and free of the
        obstacles' predicted motion, window by window: over each window of the horizon
        (:func:`window_edges`) the fast checker (conservative) holds the sweep of that window only
        (:meth:`windows`, made here unless given), and the motions' configurations of that
        window are checked against it; the last window's sweep also holds for the rest of
        each motion."""
        if not motions:
            return np.zeros(0, dtype=bool)
        packs = windows if windows is not None else self.windows(t0, margin_m)
        dt, robot = self.settings.check_dt_s, self.world.robot
        # each motion sampled once, every dt from t0 to past the horizon; every COARSE-th
        # sample checked first (most candidates collide, and are dropped on fewer checks),
        # then the rest of those still in the running — each window's configurations of
        # every such motion in one call
        t_horizon = t0 + window_edges(self.settings.horizon_s)[-1]
        samples = [m.positions(t0, max(t_horizon, m.t_end), dt) for m in motions]
        flat = Samples.of(samples)
        ok = np.ones(len(motions), dtype=bool)
        ok[flat.owner[~robot.within_limits(flat.Q)]] = False
        coarse = flat.step % COARSE == 0
        for pick in (coarse, ~coarse):
            self.drop_unsafe(ok, flat, pick, packs, t0)
        return ok

    def drop_unsafe(self, ok: NDArray[np.bool_], samples: Samples, pick: NDArray[np.bool_],
                    packs: list[PackedWorld], t0: float) -> None:
        """Set ``ok[i]`` False for each motion i still ok whose ``samples`` picked (``pick``
        (N,)) collide with their window's sweep (the last window's from its start on); a
        sample on the edge of two windows is checked in both."""
        fast, edges = self.world.fast, window_edges(self.settings.horizon_s)
        ts = samples.t
        for k, packed in enumerate(packs):
            if not ok.any():
                return
            a, b = t0 + edges[k] - 1e-9, t0 + edges[k + 1] + 1e-9
            rows = pick & ok[samples.owner] & (ts >= a)
            if k < len(packs) - 1:
                rows &= ts <= b
            rows = np.flatnonzero(rows)
            if len(rows):
                free = fast.valid_in(packed, samples.Q[rows])
                ok[samples.owner[rows[~free]]] = False

    @property
    def cut_short(self) -> bool:
        """Whether the last dodge search stopped at its deadline (it can be resumed)."""
        return self._cut is not None

    def dodge(self, now: State, t0: float,
              deadline: float | None = None, resume: bool = False) -> Motion | None:
        """A Ruckig move from ``now`` at clock time t0 (s) to the nearest of the dodge targets
        (:meth:`targets`) that is safe in time (:meth:`safe_in_time`) with the margin, else
        with none (an arm already inside the margin gets out); None when none is. A target
        where the arm would rest in the last window's sweep is dropped before its move is
        made (that move cannot be safe); the rest are tried nearest first,
        :data:`DODGE_CHUNK` at a time, so the search ends at the first chunk holding a safe
        one (the answer is the same as trying all).

        Past ``deadline`` (a ``time.perf_counter()`` time) the search stops before its next
        chunk (after one at least), with None; called again with ``resume``, it goes on with
        the targets of the search cut short, skipping those already found unsafe (from the
        earlier state)."""
        z = np.zeros_like(now.q)
        cut = self._cut if resume else None
        self._cut = None
        targets = cut.targets if cut is not None else self.targets(now, t0)
        tried = cut.tried if cut is not None else {m: np.zeros(len(targets), dtype=bool)
                                                   for m in (None, 0.0)}
        made: dict[int, Motion | None] = {}
        chunks = 0
        for margin in (None, 0.0):
            packs = self.windows(t0, margin)
            live = np.flatnonzero(self.world.fast.valid_in(packs[-1], targets) &
                                  ~tried[margin])
            for c0 in range(0, len(live), DODGE_CHUNK):
                if chunks and past(deadline):
                    self._cut = _CutSearch(targets, tried)
                    return None
                chunks += 1
                chunk = live[c0:c0 + DODGE_CHUNK]
                for i in chunk:
                    if i not in made:
                        piece = ruckig_piece(now, State(targets[i], z, z), t0, self.limits,
                                             "dodge", self.bounds)
                        made[i] = None if piece is None else Motion((piece,))
                moves = [m for m in (made[i] for i in chunk) if m is not None]
                safe = self.safe_in_time(moves, t0, windows=packs)
                if safe.any():
                    return moves[int(np.argmax(safe))]
                tried[margin][chunk] = True
        return None

    def forget_cut(self) -> None:
        """Drop a dodge search cut short (the next search starts afresh)."""
        self._cut = None

    def in_scene(self, q: Array) -> bool:
        """Whether configuration q (K,) rad is in collision with the static scene: the fast
        checker without dynamic obstacles (the scene's own aside) says so, and the exact
        checker does not call q free (with whatever dynamic obstacles it holds, a free answer
        is free of the static scene too). The fast checker's collisions can be false alarms
        (it proves "free" only): a kicked arm beside a kitchen cabinet, free by the exact
        checker, was taken as in it, and its way out searched for ~100 ms in one step while
        the loop ran the arm into the cabinet."""
        fast = self.world.fast
        alarm = not bool(fast.valid_in(fast.packed_with(pack_primitives([])), q[None])[0])
        return alarm and not self.world.exact.is_valid(q)

    def unstick(self, now: State, t0: float, deadline: float | None = None
                ) -> Motion | None:
        """Out of a collision with the static scene the arm is already in (a stop after a
        kick can end in it; then no dodge is safe, since each starts in collision, and no
        plan starts; see :meth:`in_scene`):
        of the Ruckig moves from ``now`` (clock time t0, s) to the dodge targets
        (:meth:`targets`), the one that is out soonest — every configuration from then on
        free of its window's sweep with no margin, and within the limits — the nearest
        target on a tie, out within :data:`UNSTICK_S`; None when none is. The moves are made
        and judged :data:`DODGE_CHUNK` at a time, nearest first, until one is out at once
        (no farther target can beat it) or, past ``deadline`` (a ``time.perf_counter()``
        time; after one chunk at least), with the soonest out so far: an unbounded search
        of 100-200 targets had taken 60-90 ms in one control step (tabletop_container)."""
        z = np.zeros_like(now.q)
        targets = self.targets(now, t0)
        packs = self.windows(t0, 0.0)
        edges = window_edges(self.settings.horizon_s)
        live = np.flatnonzero(self.world.fast.valid_in(packs[-1], targets))
        best: tuple[int, Motion] | None = None
        for c0 in range(0, len(live), DODGE_CHUNK):
            if c0 and past(deadline):
                break
            pieces = (ruckig_piece(now, State(targets[i], z, z), t0, self.limits, "dodge",
                                   self.bounds) for i in live[c0:c0 + DODGE_CHUNK])
            moves = [Motion((p,)) for p in pieces if p is not None]
            for out, move in zip(self._outs(moves, t0, packs, edges), moves, strict=True):
                if out >= 0 and (best is None or out < best[0]):
                    best = (out, move)
            if best is not None and best[0] == 0:
                break
        return None if best is None else best[1]

    def _outs(self, moves: list[Motion], t0: float, packs: list[PackedWorld], edges: Array
              ) -> list[int]:
        """For each of ``moves`` (from clock time t0, s): the index of its first check step
        from which every configuration is free of its window's sweep (``packs``, window
        ``edges`` s from t0; a step on an edge in the later window), -1 when that is not
        within :data:`UNSTICK_S` or a step leaves the joint limits."""
        if not moves:
            return []
        dt, fast = self.settings.check_dt_s, self.world.fast
        flat = Samples.of([m.positions(t0, max(t0 + edges[-1], m.t_end), dt) for m in moves])
        win = np.minimum(np.searchsorted(edges, flat.t - t0 + 1e-9, side="right") - 1,
                         len(packs) - 1)
        free = np.ones(len(flat.t), dtype=bool)
        for w in np.unique(win):
            free[win == w] = fast.valid_in(packs[w], flat.Q[win == w])
        inside = self.world.robot.within_limits(flat.Q)
        outs = []
        for i in range(len(moves)):
            mine = flat.owner == i
            ts, bad = flat.t[mine], np.flatnonzero(~free[mine])
            out = 0 if len(bad) == 0 else int(bad[-1]) + 1
            ok = inside[mine].all() and out < len(ts) and ts[out] - t0 <= UNSTICK_S
            outs.append(out if ok else -1)
        return outs

    def escapes(self, now: State, t0: float,
                deadline: float | None = None) -> Iterator[Motion]:
        """The last resort when no dodge is safe and neither is stopping: Ruckig moves from
        ``now`` (at clock time t0, s) to the state that a constant acceleration drawn at
        random (each joint up to its limit) reaches :data:`ESCAPE_S` later, then a stop —
        those of :data:`ESCAPE_TRIES` that are safe in time with no margin
        (:meth:`safe_in_time`, sampled: the caller checks the one it takes exactly), made
        and judged :data:`DODGE_CHUNK` at a time until ``deadline`` (a
        ``time.perf_counter()`` time) is past (one chunk at least). Of moving arms in
        collision-free random configurations whose stop ran into the static scene, 8%
        (tabletop_pole), 5% (panda_cage) and 13% (kitchen) had one."""
        for c0 in range(0, ESCAPE_TRIES, DODGE_CHUNK):
            if c0 and past(deadline):
                return
            moves = self.escape_moves(now, t0, DODGE_CHUNK)
            safe = self.safe_in_time(moves, t0, 0.0)
            yield from (m for m, ok in zip(moves, safe, strict=True) if ok)

    def escape_moves(self, now: State, t0: float, n: int) -> list[Motion]:
        """``n`` escapes from ``now`` at clock time t0 (s), unjudged: Ruckig moves to the
        state that a constant acceleration drawn at random (each joint up to its limit)
        reaches :data:`ESCAPE_S` later, then a stop (those Ruckig makes)."""
        lim, robot = self.limits, self.world.robot
        A = self.rng.uniform(-1.0, 1.0, (n, len(now.q))) * lim.acceleration
        V = np.clip(now.qd + A * ESCAPE_S, -lim.velocity, lim.velocity)
        Q = np.clip(now.q + 0.5 * (now.qd + V) * ESCAPE_S, robot.lower, robot.upper)
        moves = []
        for q, v in zip(Q, V, strict=True):
            piece = ruckig_piece(now, State(q, v, np.zeros_like(q)), t0, lim, "dodge",
                                 self.bounds)
            if piece is not None:
                end = piece.sample(piece.t_end - piece.t_start)
                stop = stop_from(end, piece.t_end, lim, self.bounds)
                moves.append(Motion((piece, *stop.pieces)))
        return moves

    def hold_short(self, motion: Motion, t0: float, t_hit: float) -> Motion | None:
        """A brake along ``motion`` (:func:`~chekhov.execute.motion.brake_along`) that starts
        as late before the conflict at ``t_hit`` (s) as it can and leaves the motion safe in
        time from t0 (s) (:meth:`safe_in_time`, the motion up to the brake included): starts
        tried from about one stopping time before t_hit back to t0, :data:`HOLD_STEP_S`
        apart, at most :data:`HOLD_TRIES`; None when none is safe."""
        t_b = t_hit - HOLD_STEP_S - stop_time(motion.sample(t_hit), self.limits)
        packs = self.windows(t0)
        for _ in range(HOLD_TRIES):
            t_b = max(t_b, t0)
            brake = brake_along(motion, t_b, self.limits)
            if self.safe_in_time([motion.then(brake)], t0, windows=packs).all():
                return brake
            if t_b <= t0:
                break
            t_b -= HOLD_STEP_S
        return None

    def targets(self, now: State, t0: float) -> Array:
        """Dodge targets (N, K) rad within the joint limits: around the arm, nearest it first
        — directed ones (:meth:`directed`) and :data:`DODGE_CANDIDATES` random ones within
        :data:`DODGE_RAD` — and then, for an arm that would stop more than
        :data:`STOP_APART_RAD` from where it is (:meth:`stop_point`), as many more around
        that stop, nearest it first. A target beside a fast arm asks it to turn back, and its
        move can overshoot into what it dodges (tabletop_container, an arm at 1.2 rad/s:
        none of 87 moves to targets around the arm was safe of the forearm, 7 of 99 around
        its stop were); centred on the stop alone, dodges that the targets around the arm
        found were lost (tabletop_pole: an avoidable collision in 2 of 2 runs)."""
        q_stop = self.stop_point(now, t0)
        blocks = [self._around(now.q, t0)]
        if float(np.abs(q_stop - now.q).max()) > STOP_APART_RAD:
            blocks.append(self._around(q_stop, t0))
        return np.vstack(blocks)

    def _around(self, q: Array, t0: float) -> Array:
        """Directed and random targets (N, K) rad around q, nearest it first."""
        robot = self.world.robot
        D = self.rng.uniform(-DODGE_RAD, DODGE_RAD, (DODGE_CANDIDATES, robot.dof))
        D *= self.rng.uniform(0.2, 1.0, (DODGE_CANDIDATES, 1))
        C = np.clip(np.vstack([q + D, self.directed(q, t0)]), robot.lower, robot.upper)
        return C[np.argsort(np.linalg.norm(C - q, axis=1))]

    def stop_point(self, now: State, t0: float) -> Array:
        """(K,) rad: where the arm stops from ``now`` braking each joint at once within the
        limits and bounds (``now.q`` itself at rest)."""
        if not now.qd.any() and not now.qdd.any():
            return now.q
        stop = stop_from(now, t0, self.limits, self.bounds)
        return np.clip(stop.end.q, self.world.robot.lower, self.world.robot.upper)

    def directed(self, q: Array, t0: float) -> Array:
        """Targets (N, K) rad that move the :data:`DODGE_POINTS` points of the arm nearest the
        obstacles' predicted paths (over the horizon from t0, s) away from them — straight
        away, up, down, and away and up or down — by each of :data:`DODGE_STEPS_M`, through
        damped least squares on the points' Jacobians (offsets capped at
        :data:`DODGE_RAD`)."""
        if not self.tracks.tracks:
            return np.empty((0, len(q)))
        P = _arm_points(self.world, q)
        paths = [(self.tracks.pose(n, t0)[:3, 3],
                  self.tracks.pose(n, t0 + self.settings.horizon_s)[:3, 3])
                 for n in self.tracks.tracks]
        D = np.stack([to_segment(P, a, b) for a, b in paths])      # (paths, N, 3)
        near = D[np.argmin(np.linalg.norm(D, axis=2), axis=0), np.arange(len(P))]
        order = np.argsort(np.linalg.norm(near, axis=1))[:DODGE_POINTS]
        J = _point_jacobians(self.world, q, P)
        up = np.array([0.0, 0.0, 1.0])
        out = []
        for i in order:
            away = near[i] / max(float(np.linalg.norm(near[i])), 1e-9)
            Ji = J[i]
            inv = Ji.T @ np.linalg.inv(Ji @ Ji.T + DAMPING ** 2 * np.eye(3))
            for d in (away, up, -up, away + up, away - up):
                dq = inv @ (d / max(float(np.linalg.norm(d)), 1e-9))
                n = float(np.abs(dq).max())
                if n < 1e-9:
                    continue
                for step in DODGE_STEPS_M:
                    out.append(q + dq * min(step, DODGE_RAD / n))
        return np.array(out) if out else np.empty((0, len(q)))


def past(deadline: float | None) -> bool:
    """Whether the wall clock (``time.perf_counter()``) is past ``deadline`` (None: never)."""
    return deadline is not None and time.perf_counter() >= deadline


def _arm_points(world: World, q: Array) -> Array:
    """(M, 3) m: the joint origins, the end effector, and the midpoints between them."""
    pts = np.vstack([world.robot.compute_joint_placements(q)[:, :3, 3],
                     world.robot.compute_ee_pose(q)[:3, 3]])
    return np.vstack([pts, (pts[:-1] + pts[1:]) / 2])


def _point_jacobians(world: World, q: Array, P: Array) -> Array:
    """(M, 3, K): d(point)/dq of :func:`_arm_points` at q (forward differences)."""
    J = np.empty((len(P), 3, len(q)))
    for j in range(len(q)):
        dq = np.zeros_like(q)
        dq[j] = FD_RAD
        J[:, :, j] = (_arm_points(world, q + dq) - P) / FD_RAD
    return J
