"""The reactive executive: :class:`Executor`. Call :meth:`Executor.step` once per control tick
with what the robot and its sensor report (:class:`Observation`); it returns the state to
command for the next tick (:class:`Command`).

On every tick it compares the measured position with the last command (a *kick*: the arm was
displaced), takes a new goal, and on every sensor frame checks the rest of the commanded
motion against the obstacles' predicted sweep (:mod:`chekhov.execute.obstacles`). A kick is
answered at once by a Ruckig join back onto the motion when that join is free; a conflict, a
new goal, or a kick it cannot rejoin asks its :mod:`worker <chekhov.execute.worker>` for a plan
from the state the motion will be in one planning budget later, and the reply is joined onto
the motion there (no velocity or acceleration jump). When the conflict is nearer than that
budget plus the time to stop, the arm brakes along its path at once and the plan starts where
it stops. The searches for a dodge or an escape stop at a wall-clock budget per step
(``search_budget_s``) and go on at the next tick, so that a step ends within a few ticks.
Units: s, rad, m.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import NDArray

from chekhov._heap import settle_heap
from chekhov.execute.checks import MotionChecks
from chekhov.execute.escape import Escaper
from chekhov.execute.evade import Evader, EvadeSettings, past
from chekhov.execute.interface import Command, Counters, ExecutorConfig, Observation, Reaction
from chekhov.execute.motion import (
    Bounds,
    Motion,
    State,
    brake_along,
    hold,
    join,
    stop_from,
    stop_time,
    trajectory_motion,
)
from chekhov.execute.near import MOVING_ASIDE, NearConflicts
from chekhov.execute.obstacles import Obstacles, ObstacleTracks, predicted_obstacles
from chekhov.execute.swerve import Swerver
from chekhov.execute.worker import PlanReply, PlanRequest, Worker
from chekhov.planners.certify import goal_error
from chekhov.planners.query import make_query
from chekhov.robot.goal import Goal
from chekhov.timing import Limits, joint_limits
from chekhov.world import World

Array = NDArray[np.float64]


EVADE_LEAD_S = 0.5
"""s, how early an arm at rest, braking or dodging gets out of the way of a predicted
conflict (a replan may find no start outside the obstacles' sweep)."""


LAG_TOLERANCE = 1e-9
"""rad and rad/s: after a step that ran past its tick, the arm (which followed the motion it
had meanwhile) is joined back onto the new motion when it is off it by more than this — not
by the kick tolerances: a brake just begun differs by ~1e-4 rad/s after a tick, and commanding
it from there was a velocity step (3% of an acceleration limit in a react run)."""


IMMEDIATE_SHARE = 0.7
"""The share of the control tick (``control_dt_s / wall_scale`` of wall time from the step's
start) by which a kicked arm's immediate motion is chosen (:meth:`Swerver.immediate
<chekhov.execute.swerve.Swerver.immediate>`: its swerve search does not begin a unit of work
that would end after it), so that the loop has it for the next tick."""


class Executor(NearConflicts):
    """Tracks a goal with the motion it commands, reacting to what each tick reports."""

    def __init__(self, world: World, worker: Worker, goal: Goal,
                 config: ExecutorConfig | None = None, *, wall_scale: float = 1.0) -> None:
        """``wall_scale``: a step's compute is counted this many times its wall time, as on
        a machine that many times slower (a simulation's stress setting; the wall-clock
        budgets are not scaled)."""
        self.world, self.worker, self.goal = world, worker, goal
        self.wall_scale = wall_scale
        self.config = config if config is not None else ExecutorConfig()
        self.limits: Limits = joint_limits(world.robot.velocity_limit, self.config.timing)
        self.bounds = Bounds(world.robot.lower, world.robot.upper)
        self.tracks = ObstacleTracks()
        self.motion: Motion | None = None
        self._step_motion: Motion | None = None
        self.immediate_motion: Motion | None = None
        """What a control loop beside the executive commands from the tick a kick is seen
        until the step ends (its checks can take longer than a tick): the unchecked Ruckig
        join back onto the motion, else the stop; None when this step saw no kick."""
        self.reactions: list[Reaction] = []
        self.counters = Counters()
        self.checks = MotionChecks(world, self.config, self.bounds, self.counters)
        self._last: Command | None = None
        self._need: str | None = "start"
        self._pending: PlanRequest | None = None
        self._budget = self.config.planning_budget_s
        self._token = 0
        self._seen: Obstacles = {}
        self._submit_wall = 0.0
        self._held = -1
        self._deadline: float | None = None
        self._search_again = False
        self._resuming = False
        self._wall0 = time.perf_counter()
        c = self.config
        settings = EvadeSettings(c.horizon_s, c.margin_m, c.check_dt_s, c.obstacle_speed_m_s)
        self.evader = Evader(world, self.tracks, settings, self.limits, self.bounds)
        self.swerver = Swerver(self.evader)
        self.escaper = Escaper(self.evader)

    # --- the tick ---------------------------------------------------------------------
    def step(self, obs: Observation) -> Command:
        """Take one tick's observation; the command for the next tick (t + control_dt_s)."""
        wall0 = self._wall0 = time.perf_counter()
        budget = self.config.search_budget_s
        self._deadline = None if budget is None else wall0 + budget
        self._submit_wall = 0.0
        self.immediate_motion = None
        t, dt = obs.t, self.config.control_dt_s
        if self.motion is None:
            self._install(hold(np.asarray(obs.q, dtype=float), t))
        self._step_motion = self.motion
        if obs.goal is not None:
            self.goal = obs.goal
            self._budget = self.config.planning_budget_s   # failures to the old goal: moot
            self._disturbed("goal", t)
        self._resuming = self._search_again   # this step's searches go on with the cut one
        self._check_kick(obs)
        if obs.obstacles is not None and obs.stamp is not None:
            self.tracks.update(obs.obstacles, obs.stamp)
            self._monitor(t)
        elif self._search_again:     # a search cut short by its budget goes on
            self._monitor(t)
        self._poll(t)
        if self._need is not None and self._pending is None:
            self._request(t)
        assert self.motion is not None
        s = self.motion.sample(t + dt)
        cmd = Command(t + dt, s.q, s.qd, s.qdd, self.motion.kind_at(t + dt))
        self._last = cmd
        wall = self._spent()
        self.counters.step_wall_s.append(wall)
        return cmd

    def warmup(self) -> float:
        """Load (on a fresh install: compile, ~1 s) the compiled kernels a reaction uses —
        a stop's sampling, a brake's steps and a motion's check against a packed snapshot of
        the obstacles —
        so that the first kick or conflict does not stall a tick — and freeze the objects
        alive out of the garbage collector's way (:func:`chekhov._heap.settle_heap`: a full
        collection over them took 33-53 ms). Changes nothing else (the world's obstacles
        included); returns the time (s)."""
        t0 = time.perf_counter()
        q = (self.bounds.lower + self.bounds.upper) / 2
        stop = stop_from(State(q, 0.5 * self.limits.velocity, np.zeros_like(q)), 0.0,
                         self.limits, self.bounds)
        _, Q = stop.positions(0.0, stop.t_end, self.config.check_dt_s)
        brake_along(stop, 0.0, self.limits)
        fast = self.world.fast
        fast.valid_in(fast.packed, Q)
        settle_heap()
        return time.perf_counter() - t0

    @property
    def done(self) -> bool:
        """At rest at the end of a motion that meets the goal, nothing pending."""
        if self.motion is None or self._last is None or self._need or self._pending:
            return False
        return self._last.t >= self.motion.t_end and self.meets_goal(self._last.q)

    def meets_goal(self, q: Array) -> bool:
        query = make_query(self.world.robot, q, self.goal, 1.0)
        return goal_error(self.world, query, np.asarray(q, dtype=float)) == ""

    # --- what happened ----------------------------------------------------------------
    def _disturbed(self, kind: str, t: float) -> None:
        """A new goal or a conflict: whatever was being planned is out of date."""
        self.reactions.append(Reaction(kind, t))
        self._cancel()
        self._need = kind

    def _check_kick(self, obs: Observation) -> None:
        """The arm off the motion's state for this tick (kicked, or lagging behind a step
        that ran past its tick): joined back onto the motion, else stopped or moved aside."""
        last = self._last
        if last is None or self.motion is None:
            return
        t = obs.t
        expected = self.motion.sample(t)
        c = self.config
        walls = self.counters.step_wall_s
        late = bool(walls) and walls[-1] > c.control_dt_s
        tol_q, tol_qd = (LAG_TOLERANCE, LAG_TOLERANCE) if late else \
            (c.kick_tolerance_rad, c.kick_tolerance_rad_s)
        if float(np.abs(obs.q - expected.q).max()) <= tol_q and \
                float(np.abs(obs.qd - expected.qd).max()) <= tol_qd:
            return
        self.reactions.append(Reaction("kick", t))
        start = State(np.asarray(obs.q, dtype=float), np.asarray(obs.qd, dtype=float), last.qdd)
        backs = self._joins_back(start, t)
        w = time.perf_counter()
        tick_end = self._wall0 + IMMEDIATE_SHARE * self.config.control_dt_s / self.wall_scale
        immediate = self.swerver.immediate(backs, start, t, tick_end)
        swerve = immediate.pieces[0].kind == "swerve"
        self.counters.swerves += swerve
        self.immediate_motion = self.motion.then(immediate)
        self.counters.immediate_wall_s.append(self.wall_scale * (time.perf_counter() - w))
        back = self._rejoin(backs, t)
        if back is not None:
            self.counters.rejoins += 1
            self._install(back)
            self._resolve(t + self.config.control_dt_s, t)
            self._react(t + self.config.control_dt_s)
            if self._pending is not None:        # planned from the motion before the kick
                self._cancel()
                self._need = self._need or "retry"
            return
        self._cancel()     # a swerve: every smooth move runs into something at once
        self._install(immediate if swerve else self._after_kick(start, t))
        self._react(t + self.config.control_dt_s)
        self._need = "kick"

    def _after_kick(self, start: State, t: float) -> Motion:
        """A kicked arm that cannot rejoin: out of the static scene when it is in it, else a
        dodge (a stop could leave it in an obstacle's way), else its stop when that is safe in
        time, else the first exactly free escape (:meth:`Evader.escapes
        <chekhov.execute.evade.Evader.escapes>`), else the stop — the stop too when the
        search budget runs out first (the search goes on next tick)."""
        ev = self.evader
        move = self._out_of_way(start, t, search=bool(self.tracks.tracks))
        if move is not None:
            self.counters.dodges += 1
            return move
        stop = stop_from(start, t, self.limits, self.bounds)
        if not past(self._deadline) and \
                not ev.safe_in_time([stop], t, 0.0).all():
            for move in ev.escapes(start, t, self._deadline):
                if past(self._deadline):
                    break
                if self.checks.free(move, t, self._seen):
                    self.counters.dodges += 1
                    return move
        self._search_again = bool(self.tracks.tracks) and (ev.cut_short or past(self._deadline))
        self.counters.safe_stops += 1
        return stop

    def _joins_back(self, start: State, t: float) -> list[Motion]:
        """Ruckig joins from the kicked ``start`` back onto the motion, ``rejoin_s`` ahead and
        at its end (those within the limits; unchecked)."""
        assert self.motion is not None
        ends = dict.fromkeys((min(t + self.config.rejoin_s, self.motion.t_end),
                              self.motion.t_end))
        return [b for b in (join(start, t, self.motion, e, self.limits, self.bounds)
                            for e in ends) if b is not None]

    def _rejoin(self, backs: list[Motion], t: float) -> Motion | None:
        """The first of the joins back (:meth:`_joins_back`) that is free (exact, to 0.1 s
        past the join) or safe in time of the predicted motion — with the margin, else
        (obstacles tracked) without: a kicked arm beside the forearm had stopped where it
        stood, in the forearm's way."""
        for b in backs:
            if self.checks.free(b, t, self._seen, b.pieces[0].t_end + 0.1) or \
                    self._safe([b], t).all():
                return b
        return next((b for b in backs if self.tracks.tracks and
                     self.evader.safe_in_time([b], t, 0.0).all()), None)

    def _monitor(self, t: float) -> None:
        """Check the rest of the motion against the predicted obstacles (a sensor frame, or
        the tick after a search cut short)."""
        assert self.motion is not None
        c = self.config
        self._search_again = False
        self._seen = predicted_obstacles(self.tracks, t, c.horizon_s, c.margin_m,
                                         speed_bound_m_s=c.obstacle_speed_m_s)
        self.world.fast.set_obstacles(self._seen)
        t_hit = self.checks.first_conflict(self.motion, t, self._seen)
        if t_hit is None:
            return
        if not any(r.kind == "obstacle" and r.t_resolved is None for r in self.reactions):
            self.reactions.append(Reaction("obstacle", t))
        if self._pending is None:
            self._need = "obstacle"
        state = self.motion.sample(t)
        lead = self._handoff_time(t) - t + stop_time(state, self.limits) + \
            self._t_react(t) - t
        if self.motion.kind_at(t) in ("rest", "brake", *MOVING_ASIDE):
            lead = max(lead, EVADE_LEAD_S)       # a standing arm needs time to get away
        if t_hit - t <= lead + 2 * c.control_dt_s:
            self._evade(t, t_hit)
        else:
            self._hold_short(t, t_hit)

    # --- plans ------------------------------------------------------------------------
    def _handoff_time(self, t: float) -> float:
        dt = self.config.control_dt_s
        return t + dt * (1 + math.ceil(self._budget / dt - 1e-9))

    def _request(self, t: float) -> None:
        assert self.motion is not None
        t_h = self._handoff_time(t)
        start = self.motion.sample(t_h)
        lo, hi = self.bounds
        start = State(np.clip(start.q, lo, hi), start.qd, start.qdd)   # plan from inside
        seen = {n: (tr.shape, self.tracks.pose(n, t_h)) for n, tr in self.tracks.tracks.items()}
        worlds = (self._seen, seen) if self.tracks.tracks else ({},)
        request = PlanRequest(t, t_h, start, self.goal, worlds, self._budget, self._token)
        self._pending = request
        self._need = None
        w0 = time.perf_counter()
        self.worker.submit(request)
        self._submit_wall += time.perf_counter() - w0
        self.world.fast.set_obstacles(self._seen)   # an inline worker planned in this world
        self.checks.forget_exact()

    def _poll(self, t: float) -> None:
        req = self._pending
        if req is None:
            return
        reply = self.worker.poll(t)
        if reply is None:
            return
        self._pending = None
        self.counters.planning_wall_s.append(reply.wall_s)
        if req.token != self._token:       # planned from a motion no longer commanded
            self._need = self._need or "retry"
            return
        self.counters.late_plans += int(t + self.config.control_dt_s > req.t_handoff + 1e-9)
        if reply.trajectory is None:
            self._failed(reply.status)
            if reply.status == "invalid_start" and self.motion is not None and \
                    self.motion.kind_at(t) not in MOVING_ASIDE:
                self._dodge(t)
            else:
                self._stop_for_goal(t)
            return
        t_join = self._t_react(t)
        new = self._joined(reply, t_join)
        if new is None:
            self._failed("join_in_collision")
            self._stop_for_goal(t)
            return
        self._budget = self.config.planning_budget_s
        self.counters.replans += 1
        self._install(new)
        self._resolve(t_join, req.t_request)
        self._react(t_join)

    def _stop_for_goal(self, t: float) -> None:
        """A plan to a new goal failed: while none exists the arm brakes to a stop along its
        motion (on the way to a goal no longer wanted), when that brake is safe of the
        predicted obstacles, and goes on when a plan comes; an arm at rest, braking or moving
        aside (each ending at rest) already is so answered, from the next command. Before
        2026-12-02 it went on to the old goal: a new goal beside a forearm found no free IK
        solution for 150-370 ms (panda_table_shelf, seed 0, episodes 0 and 2)."""
        assert self.motion is not None
        if not any(r.kind == "goal" and r.t_reacted is None for r in self.reactions):
            return
        t_r = self._t_react(t)
        if self.motion.kind_at(t) in ("rest", "brake", *MOVING_ASIDE):
            self._react(t_r, ("goal",))
            return
        brake = brake_along(self.motion, t_r, self.limits)
        if brake is None or not self._safe([brake], t_r).all():
            return
        self.counters.safe_stops += 1
        self._install(brake)
        self._react(t_r, ("goal",))

    def _failed(self, why: str) -> None:
        self.counters.failed_plans += 1
        self.counters.failures.append(why)
        self._budget = min(self._budget * 2, self.config.max_budget_s)
        self._need = self._need or "retry"

    def _joined(self, reply: PlanReply, t_join: float) -> Motion | None:
        """The reply's trajectory joined onto the motion at clock time ``t_join`` (the next
        command, as soon as the reply is in: the plan starts from the state expected at the
        handoff, and the Ruckig join takes the arm from wherever it is onto it), the first
        join that is free of the latest predicted obstacles with its rest — or, for an arm
        inside their margin (planned against the obstacles as last seen), safe in time with
        no margin."""
        assert reply.trajectory is not None and self.motion is not None
        start = self.motion.sample(t_join)
        target = trajectory_motion(reply.trajectory, 0.0)
        self.world.fast.set_obstacles(self._seen)
        inside = bool(self.world.robot.within_limits(start.q[None])[0])
        for offset in self.config.join_offsets_s:    # (from outside the limits: back in)
            new = join(start, t_join, target, min(offset, target.t_end), self.limits,
                       self.bounds if inside else None)
            if new is not None and self.checks.free(new, t_join, self._seen,
                                                    new.pieces[0].t_end + 0.1):
                return new
            if new is not None and not self.world.fast.valid(start.q[None])[0] and \
                    self.evader.safe_in_time([new], t_join, 0.0).all():
                return new
        return None

    # --- bookkeeping ------------------------------------------------------------------
    def _resolve(self, t_resolved: float, observed_by: float) -> None:
        """The reactions observed by ``observed_by`` (s) are resolved by a motion starting at
        ``t_resolved`` (s)."""
        for r in self.reactions:
            if r.t_resolved is None and r.t_observed <= observed_by:
                r.t_resolved = t_resolved
