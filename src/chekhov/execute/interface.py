"""What the executive takes and gives, tick by tick: its configuration
(:class:`ExecutorConfig`), each tick's :class:`Observation` and :class:`Command`, the
:class:`Reaction` records of disturbances and the :class:`Counters` of what it did (see
:class:`~chekhov.execute.executor.Executor`). Units: s, rad, m."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from chekhov.execute.obstacles import Obstacles
from chekhov.robot.goal import Goal
from chekhov.timing import TimingConfig

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ExecutorConfig:
    """How the executive reacts.

    Attributes:
        control_dt_s: s, the control period (100 Hz).
        planning_budget_s: s, a replan's time limit; it plans from the state expected this
            long (rounded up to ticks) after the request, and its answer is joined on at the
            first tick after it comes.
        max_budget_s: s, the budget after failed replans (doubling each time).
        horizon_s: s, how far ahead the obstacles' motion is predicted.
        margin_m: m, how much the obstacles are inflated when planning and monitoring.
        obstacle_speed_m_s: m/s, the obstacles' speed bound: one seen in a single sensor
            frame so far (its velocity unknown; the next frame gives it) is predicted to be
            anywhere that speed takes it (0: taken as standing still until then). A person's
            arm first seen at rest was planned around as a standing obstacle; the next
            frame, 33 ms on, showed it at 1 m/s with the arm already in its sweep
            (tabletop_container 19, collided in 3 of 4 react runs).
        reaction_lead_s: s, how far ahead of its tick a reaction (a hold, brake or dodge, or
            a plan joined on) starts (whole ticks, at least one): the motion commanded until
            then stands, so the control loop goes on commanding it while the reaction is
            computed. A reaction computed in longer than that is late: the arm is off the
            new motion when it comes, and joins back onto it (a "lag", as after a kick).
            Measured on the charged clock (tabletop_pole and panda_cage, 6 episodes each,
            one run): reaction p95 40 ms at 10 ms of lead, 48-50 ms at 20, 60-108 ms at 30.
        search_budget_s: s of wall-clock time a step may spend searching for a dodge or an
            escape (checked between chunks of candidates, 1-4 ms each). Past it the search
            stops, the arm brakes or stops, and the search goes on at the next tick: a step
            that ran past its tick would leave the arm behind the motion it found, and its
            next step searching again from there. None: no limit (the free clock, where
            compute takes no time; then the search is deterministic). Measured on the same
            scripts (``benchmarks/react_replay.py``, 31 episodes of 6 scenes chosen for their
            conflicts, charged clock), collision episodes (avoidable) per run: 30 (12) of 62
            at 6 ms, 11 (6) of 31 at 10 ms, 33 (6) of 93 at 15 ms, 7 (1) of 31 at 25 ms,
            32 (4) of 93 with none; three later passes of 15 against 25 ms: 34 (6) and
            35 (10) of 93; an episode's longest step at most 95 ms at 15 ms, 145
            with none. A search cut short brakes the arm, and from a braking arm fewer dodges
            are safe.
        kick_tolerance_rad, kick_tolerance_rad_s: rad and rad/s, a measured position or
            velocity this far from the motion's is a kick (after a step that ran past its
            tick, any offset beyond 1e-9 is: a lag, the arm behind the new motion —
            :data:`~chekhov.execute.executor.LAG_TOLERANCE`).
        check_dt_s: s, the time step of the checks along a motion.
        check_budget_s: s of wall-clock time one exact check of a motion (the monitor's
            conflict check, a join's or an escape's freedom) may take; past it, the safe
            answer: a conflict where the fast checker flagged one, not free (looked at before
            each coal query). Near contact on a Kinova Jaco's 45,000-triangle meshes a check
            took up to 600 ms; on the built-in robots p50 1 ms, p99 7-9 ms, at most 9-30 ms
            (6 episodes each of tabletop_pole, panda_cage, shelf_boxes, kitchen: one check of
            766 cut). None: no limit.
        rejoin_s: s, how far ahead on its motion a kicked arm rejoins it.
        join_offsets_s: s, where on a new plan's trajectory the join aims, tried in order.
        timing: how plans are timed: Ruckig, at rest at each waypoint and exactly on the
            certified polyline; a path of more than ``worker.RUCKIG_MAX_WAYPOINTS`` waypoints
            (TrajOpt's, along a curve: 5 times slower at rest at each) with toppra
            (``worker.reply_timing``). On the executive's replies to 60 task cases each of
            kitchen and panda_cage (2-9 waypoints), toppra's rounded corners gave durations
            10% shorter at the median in the same wall time, its arcs' exact check included
            (1.6-2.6 ms against 1.6-2.6; this docstring said 10-15 ms before the compiled
            TOPP-RA); whole episodes, 45 paired, took 5% less time at the median with it
            (``docs/history.md``, session 35). Not the default: the full ``chekhov react
            --episodes 20`` with it (session 36) had 5 collision episodes, 4 of them avoidable,
            against 2 and 0 in the README's table (``docs/results/
            react_toppra_every_reply.jsonl``).
    """

    control_dt_s: float = 0.01
    planning_budget_s: float = 0.05
    max_budget_s: float = 0.64
    horizon_s: float = 0.6
    margin_m: float = 0.04
    obstacle_speed_m_s: float = 1.0
    reaction_lead_s: float = 0.01
    search_budget_s: float | None = 0.015
    kick_tolerance_rad: float = 1e-3
    kick_tolerance_rad_s: float = 1e-3
    check_dt_s: float = 0.01
    check_budget_s: float | None = 0.03
    rejoin_s: float = 0.25
    join_offsets_s: tuple[float, ...] = (0.15, 0.3, 0.0)
    timing: TimingConfig = field(default_factory=lambda: TimingConfig(method="ruckig"))


@dataclass(frozen=True, eq=False)
class Observation:
    """What the executive gets each tick.

    Attributes:
        t: s, the clock. q: (K,) rad and qd: (K,) rad/s, the measured state.
        obstacles: a sensor frame, on the ticks one arrives (name → (shape, T_world_obj)).
        stamp: s, when that frame was taken (earlier than t by the sensor's latency).
        goal: a new goal, on the tick it is given.
    """

    t: float
    q: Array
    qd: Array
    obstacles: Obstacles | None = None
    stamp: float | None = None
    goal: Goal | None = None


@dataclass(frozen=True, eq=False)
class Command:
    """The state to be in at time ``t`` (s): q (K,) rad, qd rad/s, qdd rad/s²; ``mode``: what
    the motion is doing ("plan", "join", "brake", "rest")."""

    t: float
    q: Array
    qd: Array
    qdd: Array
    mode: str


@dataclass
class Reaction:
    """A disturbance and the answer to it: ``kind`` ("obstacle", "goal", "kick"), when it was
    observed, when the first motion answering it began (``t_reacted``: a brake, a dodge, a
    rejoin or a new plan) and when a motion to the goal that answers it began
    (``t_resolved``: a rejoin or a new plan), s; None while none has."""

    kind: str
    t_observed: float
    t_reacted: float | None = None
    t_resolved: float | None = None


@dataclass
class Counters:
    replans: int = 0
    failed_plans: int = 0
    late_plans: int = 0
    rejoins: int = 0
    safe_stops: int = 0
    dodges: int = 0
    holds: int = 0
    undecided_checks: int = 0
    """exact checks cut by ``check_budget_s`` (answered safe)."""
    planning_wall_s: list[float] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)
    step_wall_s: list[float] = field(default_factory=list)
    """s, each step's own compute time (an inline worker's planning left out)."""
    swerves: int = 0
    """kicked arms given a swerve as the immediate motion (every smooth move ran into
    something within a tick or two)."""
    immediate_wall_s: list[float] = field(default_factory=list)
    """s, the compute time of each immediate motion after a kick (times ``wall_scale``):
    the loop commands it from the next tick, so it must be under one."""
