"""What a kicked arm does until the executive's exact checks are judged (:class:`Swerver`,
on an :class:`~chekhov.execute.evade.Evader`): the first join back or stop that the fast
checker calls free (:meth:`Swerver.immediate`), else a swerve (:meth:`Swerver.swerve`) — a
constant acceleration for a moment, then a stop, the first ones drawn around the acceleration
that pushes the arm away from what it touches (:meth:`Swerver._away`).

Units: s, rad, m.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.packed import PackedWorld
from chekhov.collision.trajectory_distances import TrajectoryDistances
from chekhov.execute.evade import Evader, Samples
from chekhov.execute.motion import (
    Motion,
    State,
    accelerating,
    accelerating_states,
    stop_from,
)

Array = NDArray[np.float64]

IMMEDIATE_LOOK_S = 0.1
"""s, how far past a kicked arm's join back (or stop) :meth:`Swerver.immediate` looks: a
step overran its tick by up to ~0.1 s."""
SWERVE_TRIES = 512
"""Random constant accelerations :meth:`Swerver.swerve` tries at most."""
SWERVE_CHUNK = 16
"""Swerves tried at a time."""
SWERVE_S = 0.1
"""s, how long a swerve keeps its acceleration before it stops."""
SWERVE_FIRST = 3
"""How many of a swerve's first samples (every check step) are checked first, for all."""
AWAY_MARGIN_M = 0.03
"""m: the fast model's pairs closer than this at a swerve's contact push it away."""
AWAY_PAIRS = 8
"""How many of those closest pairs push it."""
SWERVE_JUDGED = 4
"""Swerves (with their stops) judged in time at once."""


class _Budget:
    """Units of work against a deadline (a ``time.perf_counter()`` time; None: none): a unit
    of a kind starts only when it would end before the deadline if it takes as long as that
    kind's expected time (``expected``, s by kind: the longest lately, updated in place, so
    an owner keeps it from one search to the next) — a search stops *before* the unit that
    would overrun its deadline, not after it. A kicked Panda's swerve search had overrun a
    7 ms deadline by up to 6 ms: a whole filter or judgment begun just before it."""

    def __init__(self, deadline: float | None, expected: dict[str, float]) -> None:
        self.deadline = deadline
        self.expected = expected

    def room(self, kind: str) -> bool:
        """Whether a unit of ``kind`` may start now."""
        return self.deadline is None or \
            time.perf_counter() + self.expected.get(kind, 0.0) < self.deadline

    @contextmanager
    def unit(self, kind: str) -> Iterator[None]:
        """Time one unit of ``kind``: its expected time becomes the longer of this one and
        half the one before (a slow unit is remembered, a while)."""
        t = time.perf_counter()
        yield
        self.expected[kind] = max(time.perf_counter() - t, 0.5 * self.expected.get(kind, 0.0))


class Swerver:
    """A kicked arm's immediate motion and swerves, judged with ``evader``'s settings, limits
    and predicted windows, drawn from its random generator (one stream with its dodges)."""

    def __init__(self, evader: Evader) -> None:
        self.evader = evader
        self._distances = TrajectoryDistances(evader.world.fast)
        self._unit_s: dict[str, float] = {}   # s: the swerve search's expected unit times

    def immediate(self, backs: list[Motion], now: State, t0: float,
                  deadline: float | None) -> Motion:
        """What a control loop commands a kicked arm (``now`` at clock time t0, s) until the
        executive's exact checks are done: the first of the joins back ``backs`` and the stop
        whose positions (every check step, to :data:`IMMEDIATE_LOOK_S` past the join) stay
        within the joint limits and that the fast checker calls free of the scene and of the
        predicted obstacles it holds (microseconds, not the exact checks'
        milliseconds); else a swerve (:meth:`swerve`, until ``deadline``); else, of those
        within the limits, the one whose first fast alarm comes latest. A join back straight
        into a cabinet had been commanded for the two ticks a kicked step overran."""
        ev = self.evader
        stop = stop_from(now, t0, ev.limits, ev.bounds)
        best, best_t, q_hit = stop, -math.inf, now.q
        for m in [*backs, stop]:
            ts, Q = m.positions(t0, min(m.t_end, m.pieces[0].t_end + IMMEDIATE_LOOK_S),
                                ev.settings.check_dt_s)
            if m is not stop and not ev.world.robot.within_limits(Q).all():
                continue
            ok = ev.world.fast.valid(Q)
            if ok.all():
                return m
            i = int(np.argmin(ok))
            if m is stop:
                q_hit = Q[i]
            if float(ts[i]) > best_t:
                best, best_t = m, float(ts[i])
        swerve = self.swerve(now, t0, deadline, q_hit=q_hit)
        return swerve if swerve is not None else best

    def swerve(self, now: State, t0: float,
               deadline: float | None = None, *, q_hit: Array | None = None
               ) -> Motion | None:
        """An arm ``now`` (at clock time t0, s) whose every smooth move (join, stop, escape)
        is in contact within a tick or two: the first of up to :data:`SWERVE_TRIES` moves at a
        constant acceleration drawn at random (each joint up to its limit; the acceleration
        steps at once) for :data:`SWERVE_S`, then a stop, that is safe in time with no margin
        (:meth:`Evader.safe_in_time <chekhov.execute.evade.Evader.safe_in_time>`: the fast
        checker, sampled — not a certificate); else the first judged whose swerve alone is
        safe in time and that stays within the limits (it buys time: its stop runs into
        something later, the executive's monitor sees it coming); else None. Drawn
        :data:`SWERVE_CHUNK` at a time, the swerves' first samples checked first
        (:meth:`_swerves_clear`), then :data:`SWERVE_JUDGED` at a time the rest of them and
        with their stops (:meth:`_judged`), until ``deadline`` (a ``time.perf_counter()``
        time): a draw or a judgment starts only when it would end before it, taking as long
        as such units lately took (:class:`_Budget`). The first
        chunk is drawn around the acceleration that pushes the arm away from what it touches
        at ``q_hit`` (rad; :meth:`_away`). A kicked kitchen arm moving at 1.4 rad/s 10 ms from
        a cabinet had none but such a swerve (1 of 256 random ones free at 1 ms steps)."""
        ev = self.evader
        packs = ev.windows(t0, 0.0)
        budget = _Budget(deadline, self._unit_s)
        buys_time: Motion | None = None
        for c0 in range(0, SWERVE_TRIES, SWERVE_CHUNK):
            if not budget.room("draw"):
                break
            with budget.unit("draw"):
                A = ev.rng.uniform(-1.0, 1.0, (SWERVE_CHUNK, len(now.q))) * ev.limits.acceleration
                if c0 == 0 and q_hit is not None:
                    A = self._away(q_hit, A)
                A = self._braking_at_limits(now, A)
                A = A[self._swerves_clear(now, t0, A, packs, rest=False)]
            for k in range(0, len(A), SWERVE_JUDGED):
                if not budget.room("judge"):
                    return buys_time
                with budget.unit("judge"):
                    moves = self._judged(now, t0, A[k:k + SWERVE_JUDGED], packs)
                safe = [m for m, ok in moves if ok]
                if safe:
                    return safe[0]
                buys_time = buys_time or next((m for m, _ in moves if self._within_limits(m)),
                                              None)
        return buys_time

    def _judged(self, now: State, t0: float, A: Array, packs: list[PackedWorld]
                ) -> list[tuple[Motion, bool]]:
        """The swerves from ``now`` (clock time t0, s) at accelerations A (N, K) rad/s² whose
        first samples passed :meth:`_swerves_clear`, those whose rest passes too, each with
        its stop, and whether it is safe in time with no margin."""
        ev = self.evader
        moves = []
        for acc in A[self._swerves_clear(now, t0, A, packs, first=False)]:
            piece = accelerating(now, t0, acc, SWERVE_S, ev.limits)
            stop = stop_from(piece.sample(SWERVE_S), piece.t_end, ev.limits, ev.bounds)
            moves.append(Motion((piece, *stop.pieces)))
        if not moves:
            return []
        safe = ev.safe_in_time(moves, t0, 0.0, windows=packs)
        return list(zip(moves, (bool(x) for x in safe), strict=True))

    def _braking_at_limits(self, now: State, A: Array) -> Array:
        """The swerve accelerations A (N, K) rad/s² from ``now``, each joint that would
        otherwise stop past a position limit after its swerve braking at full deceleration
        instead (a kicked arm rushing at a limit has no room to swerve on that joint)."""
        ev = self.evader
        acc, bounds = ev.limits.acceleration, ev.bounds
        q, v, _ = accelerating_states(now, A, np.array([SWERVE_S]), ev.limits)
        rest = q[:, 0] + v[:, 0] * np.abs(v[:, 0]) / (2 * acc)
        past_limit = (rest > bounds.upper) | (rest < bounds.lower)
        return np.where(past_limit, -np.sign(now.qd) * acc, A)

    def _within_limits(self, motion: Motion) -> bool:
        _, Q = motion.positions(motion.t_start, motion.t_end, self.evader.settings.check_dt_s)
        return bool(self.evader.world.robot.within_limits(Q).all())

    def _away(self, q_hit: Array, A: Array) -> Array:
        """Accelerations (N, K) rad/s² around the one that pushes the arm away from what it
        touches at ``q_hit`` (K,) rad: the fast model's closest pairs there (within
        :data:`AWAY_MARGIN_M`), their signed-distance gradients weighted by depth, scaled to
        put one joint at its limit — plus the noise ``A`` (N, K) (random accelerations)
        times 0, 1/4, 1/2 and 1 in turn, clipped to the limits. ``A`` itself when nothing is
        that close."""
        dist, grad = self._distances.waypoints(q_hit[None], AWAY_MARGIN_M, AWAY_PAIRS)
        w = np.clip(AWAY_MARGIN_M - dist[0], 0.0, None)
        g = (w[:, None] * grad[0]).sum(axis=0)
        acc = self.evader.limits.acceleration
        if not np.abs(g).max(initial=0.0) > 0:
            return A
        push = g / np.abs(g / acc).max()
        scale = np.resize([0.0, 0.25, 0.5, 1.0], len(A))[:, None]
        return np.clip(push + scale * A, -acc, acc)

    def _swerves_clear(self, now: State, t0: float, A: Array, packs: list[PackedWorld], *,
                       first: bool = True, rest: bool = True) -> NDArray[np.bool_]:
        """Which of the swerves from ``now`` at clock time t0 (s) at accelerations A (N, K)
        rad/s² stay within the limits and free of each window's predicted sweep ``packs``
        (:meth:`Evader.windows <chekhov.execute.evade.Evader.windows>`, no margin; the scene
        included) for :data:`SWERVE_S`, every check step — the test
        :meth:`Evader.safe_in_time <chekhov.execute.evade.Evader.safe_in_time>` then applies
        to the whole swerve and stop, on the swerve alone: with ``first``, the limits and the
        first :data:`SWERVE_FIRST` samples (they drop most); with ``rest``, the other samples.
        Against the whole horizon's sweep at once (what the fast checker holds), every
        swerve of an arm beside the forearm was dropped, where 256 of 256 random ones were
        safe in time."""
        if not len(A):
            return np.zeros(0, dtype=bool)
        ev = self.evader
        dt, robot = ev.settings.check_dt_s, ev.world.robot
        us = np.arange(dt, SWERVE_S + 1e-9, dt)
        Q = accelerating_states(now, A, us, ev.limits)[0]
        ok = np.ones(len(A), dtype=bool)
        if first:
            ok &= robot.within_limits(Q.reshape(-1, len(now.q))).reshape(len(A), -1).all(axis=1)
        samples = Samples.of([(t0 + us, Qi) for Qi in Q])
        is_first = samples.step < SWERVE_FIRST
        for pick, on in ((is_first, first), (~is_first, rest)):
            if on:
                ev.drop_unsafe(ok, samples, pick, packs, t0)
        return ok
