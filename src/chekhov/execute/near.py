"""What the executive (:class:`~chekhov.execute.executor.Executor`) does about a conflict
with the obstacles' predicted motion, on top of its state (:class:`NearConflicts`, the
executor's base): one not near yet is held short of (a brake along the path at the latest
safe moment, while the plan asked for comes); one too near to wait for a plan is braked
for when braking is safe, else dodged (:class:`~chekhov.execute.evade.Evader`), else escaped
(:class:`~chekhov.execute.escape.Escaper`: the escape meeting the predicted obstacles
latest), else braked for anyway — and the motions it commands are installed and their
reactions recorded here. Units: s, rad, m.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from chekhov.execute.checks import MotionChecks
from chekhov.execute.escape import FINE_WINDOW_S, Escaper
from chekhov.execute.evade import Evader
from chekhov.execute.interface import Counters, ExecutorConfig, Reaction
from chekhov.execute.motion import Bounds, Motion, State, brake_along, ruckig_piece, stop_from
from chekhov.execute.obstacles import Obstacles, ObstacleTracks
from chekhov.execute.worker import PlanRequest, Worker
from chekhov.timing import Limits
from chekhov.world import World

ON_TIME_MARGIN_S = 0.002
"""s of wall time a step takes after its dodge (:meth:`NearConflicts._on_time`)."""
LATER_S = FINE_WINDOW_S
"""s: an escape replaces the motion when it meets the predicted obstacles this much later —
one of the windows it is judged in, the least difference the judgement resolves. At 0.05 s,
tabletop_container seed 1 episode 2 braked into the forearm in every run (an escape 40 ms
later was left); at 0.02, 0 of 3 replays collided."""
ESCAPE_COST_S = 0.015
"""s of wall time an escape search is expected to take (its escape starts after it)."""
MOVING_ASIDE = ("dodge", "swerve")
"""The kinds of motion piece that move the arm out of the way (no plan, no brake)."""


class NearConflicts:
    """The executor's answers to conflicts and its bookkeeping of the motion it commands;
    the state is the :class:`~chekhov.execute.executor.Executor`'s (made in its
    ``__init__``)."""

    world: World
    worker: Worker
    config: ExecutorConfig
    wall_scale: float
    limits: Limits
    bounds: Bounds
    tracks: ObstacleTracks
    motion: Motion | None
    immediate_motion: Motion | None
    _step_motion: Motion | None
    reactions: list[Reaction]
    counters: Counters
    checks: MotionChecks
    evader: Evader
    escaper: Escaper
    _need: str | None
    _pending: PlanRequest | None
    _token: int
    _seen: Obstacles
    _submit_wall: float
    _held: int
    _deadline: float | None
    _search_again: bool
    _resuming: bool
    _wall0: float

    def _hold_short(self, t: float, t_hit: float) -> None:
        """A conflict not near yet: the motion kept until the latest moment from which
        braking along it is safe of the predicted motion (:meth:`Evader.hold_short`), so the
        arm holds short of the conflict while the plan asked for comes, and stays short of it
        should none come. A plan asked for from a state before the brake stays good."""
        assert self.motion is not None
        if self._held == self._token or \
                self.motion.kind_at(t) in ("rest", "brake", *MOVING_ASIDE):
            return
        t1 = self._t_react(t)
        held = self.evader.hold_short(self.motion, t1, t_hit)
        if held is None:
            return
        pending = self._pending
        self._install(held)
        self._held = self._token
        self.counters.holds += 1
        if pending is not None and held.t_start >= pending.t_handoff:
            self._pending = replace(pending, token=self._token)
        elif pending is not None:
            self._cancel()
            self._need = "obstacle"
        self._react(t1, ("obstacle",))

    def _evade(self, t: float, t_hit: float) -> None:
        """The conflict at ``t_hit`` (s) is too near to wait for a plan: keep a dodge that
        still holds, else brake along the path if that is free of the predicted motion, else
        dodge, else brake anyway (a dodge gone unsafe: stop, if that is safer) — unless the
        dodge search was cut short by its budget and braking a tick later still stops short of
        the conflict: then the motion stands while the search goes on."""
        assert self.motion is not None
        t_r = self._t_react(t)
        kind = self.motion.kind_at(t)
        if kind in MOVING_ASIDE and self._safe([self.motion], t).all():
            return
        moving = bool(np.abs(self.motion.sample(t).qd).max() > 1e-6)
        brake = brake_along(self.motion, t_r, self.limits) if moving and kind not in (
            "brake", *MOVING_ASIDE) else None
        if brake is not None and self._safe([brake], t_r).all():
            self.counters.safe_stops += 1
        elif self._dodge(t) or (self._search_again and brake is not None and
                                brake.t_end + 2 * self.config.control_dt_s < t_hit):
            return
        else:
            if brake is None and moving and kind in MOVING_ASIDE:
                brake = self._stop_if_safer(t)
            if self._escape(t, brake):
                return
            if brake is None:
                return      # nothing new: a plan asked for stays asked for
            self.counters.safe_stops += 1
        self._answer(brake, t_r)

    def _escape(self, t: float, brake: Motion | None) -> bool:
        """The last resort of :meth:`_evade`: the motion (braking from the next command when
        ``brake``) meets the predicted obstacles and no dodge is safe of them — the escape
        that meets them latest (:meth:`Escaper.latest
        <chekhov.execute.escape.Escaper.latest>`), from the tick this step's answer will be
        in by, installed when that is :data:`LATER_S` later than the motion's. Until that
        tick the arm goes on with what the loop commands while the step runs
        (:meth:`_meanwhile`), and the escape starts from there: one from the brake or the
        stop this step installed had the arm off it when the step overran, and the lag's stop
        then replaced it (tabletop_pole, seed 2, episode 1, at ``--compute-scale 2``)."""
        assert self.motion is not None
        t_r = self._t_react(t)
        current = self.motion if brake is None else self.motion.then(brake)
        t_e = max(t_r, self._in_by(t, ESCAPE_COST_S * self.wall_scale))
        arm = self._meanwhile()
        move, t_move, t_now = self.escaper.latest(current, t_r, t_e, self._deadline,
                                                  start=arm.sample(t_e))
        if move is None or t_move < t_now + LATER_S:
            return False
        self.counters.dodges += 1
        self._answer(arm.then(move), t_e)
        return True

    def _stop_if_safer(self, t: float) -> Motion | None:
        """A dodge no longer safe and none other found: a stop from the next command (each
        joint braking) when the dodge is not safe in time even with no margin and the stop
        is; else None (the dodge goes on)."""
        assert self.motion is not None
        t_r, ev = self._t_react(t), self.evader
        if ev.safe_in_time([self.motion], t, 0.0).all():
            return None
        stop = stop_from(self.motion.sample(t_r), t_r, self.limits, self.bounds)
        return stop if ev.safe_in_time([stop], t_r, 0.0).all() else None

    def _dodge(self, t: float) -> bool:
        """Out of the obstacles' way when braking along the path is not: the
        :class:`~chekhov.execute.evade.Evader`'s dodge from the next command — or, when the
        arm is in the static scene there already, its way out (:meth:`Evader.unstick
        <chekhov.execute.evade.Evader.unstick>`) — installed (the plan asked for cancelled, a
        new one asked for) when there is one."""
        assert self.motion is not None
        t_r = self._t_react(t)
        now = self.motion.sample(t_r)
        move = self._out_of_way(now, t_r)
        if move is None:
            self._search_again = self.evader.cut_short
            return False
        self.counters.dodges += 1
        self._answer(*self._on_time(move, t, t_r))
        return True

    def _on_time(self, move: Motion, t: float, t_r: float) -> tuple[Motion, float]:
        """A dodge ``move`` from the state at t_r (s), made again to the same target from
        the tick this step's answer will be in by, when the step has run past t_r: until
        then the arm goes on with what the loop commands meanwhile (:meth:`_meanwhile`: after
        a kick, its immediate motion, not the stop the step installed), and a dodge from t_r
        found it a tick behind (a lag, joined back) — from inside the obstacle's sweep, where
        no join back was safe: tabletop_pole 7 and kitchen 18 then braked for 15-20 ticks
        into the forearm. Kept only when safe in time (no margin), else ``move``; returned
        with the time (s) it starts to differ from what the arm has."""
        t_in = self._in_by(t, ON_TIME_MARGIN_S)
        if t_in <= t_r or move.pieces[0].kind != "dodge":
            return move, t_r
        arm = self._meanwhile()
        piece = ruckig_piece(arm.sample(t_in), move.end, t_in, self.limits, "dodge",
                             self.bounds)
        if piece is None:
            return move, t_r
        again = arm.then(Motion((piece,)))
        ok = self.evader.safe_in_time([again], t, 0.0)
        return (again, t_in) if ok.all() else (move, t_r)

    def _out_of_way(self, now: State, t0: float, *, search: bool = True) -> Motion | None:
        """From ``now`` at clock time t0 (s): the way out of the static scene when the arm is
        in it already (:meth:`Evader.unstick <chekhov.execute.evade.Evader.unstick>`; no
        dodge can be safe then, each starting in collision, so no search is spent on one),
        else, with ``search``, the dodge search's move (resumed when this step resumes one);
        None when there is none (the search may have been cut short: ``evader.cut_short``)."""
        ev = self.evader
        if ev.in_scene(now.q):
            ev.forget_cut()
            return ev.unstick(now, t0, self._deadline)
        if not search:
            return None
        return ev.dodge(now, t0, self._deadline, self._resuming)

    def _meanwhile(self) -> Motion:
        """What the arm follows from this step's tick until the step's answer is in (the
        loop's command while a step overruns its tick): a kick's immediate motion, else the
        motion the step began with (outside a step, the motion)."""
        arm = self.immediate_motion or self._step_motion or self.motion
        assert arm is not None
        return arm

    def _safe(self, motions: list[Motion], t0: float) -> NDArray[np.bool_]:
        """:meth:`Evader.safe_in_time <chekhov.execute.evade.Evader.safe_in_time>`."""
        return self.evader.safe_in_time(motions, t0)

    def _t_react(self, t: float) -> float:
        """s, where a reaction computed on the tick at ``t`` starts: ``reaction_lead_s``
        ahead (whole ticks, at least one), so that the motion commanded until then stands
        while the reaction is computed."""
        dt = self.config.control_dt_s
        return t + dt * max(1, round(self.config.reaction_lead_s / dt))

    def _in_by(self, t: float, more_s: float) -> float:
        """s, the tick this step (at tick t, s) will have its answer in by when it takes
        ``more_s`` (s, on the clock) beyond what it has spent (:meth:`_spent`)."""
        dt = self.config.control_dt_s
        return t + dt * math.ceil((self._spent() + more_s) / dt - 1e-9)

    def _spent(self) -> float:
        """s, this step's own compute so far (an inline worker's planning left out), times
        ``wall_scale``."""
        return self.wall_scale * (time.perf_counter() - self._wall0 - self._submit_wall)

    def _answer(self, motion: Motion, t_reacted: float | None = None) -> None:
        """Answer a conflict with ``motion`` (a brake, dodge or escape): the plan asked for
        cancelled and a new one asked for, the motion installed, the open reactions answered
        from ``t_reacted`` (s; the motion's start by default)."""
        self._cancel()
        self._need = "obstacle"
        self._install(motion)
        self._react(motion.t_start if t_reacted is None else t_reacted)

    def _install(self, motion: Motion) -> None:
        """Command ``motion`` from its start (the current motion up to there)."""
        self.motion = motion if self.motion is None else self.motion.then(motion)
        self._token += 1

    def _react(self, t: float, kinds: tuple[str, ...] = ("obstacle", "goal", "kick")) -> None:
        """The open reactions (of ``kinds``) got a first answer starting at t (s)."""
        for r in self.reactions:
            if r.t_reacted is None and r.t_observed <= t and r.kind in kinds:
                r.t_reacted = t

    def _cancel(self) -> None:
        if self._pending is not None:
            self.worker.cancel()
            self._pending = None
