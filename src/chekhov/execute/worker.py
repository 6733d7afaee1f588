"""Where the executive's replans run: :class:`InlineWorker` (on the simulated clock: the plan
is computed at once and becomes usable its measured wall time after the request — so a run
is not bit-reproducible: the tick a reply joins on, and what the anytime planner improves in
its time, follow the machine's speed) or :class:`ThreadWorker` (a real thread beside a
real-time control loop). Both run :func:`plan_motion`."""

from __future__ import annotations

import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from chekhov.errors import ChekhovError, TrajectoryError
from chekhov.execute.motion import State
from chekhov.execute.obstacles import Obstacles
from chekhov.planners.base import Planner
from chekhov.planners.timed import timed_trajectory
from chekhov.robot.goal import Goal
from chekhov.timing import TimingConfig
from chekhov.trajectory import JointTrajectory
from chekhov.world import World

Array = NDArray[np.float64]

PLAN_SHARE = 0.6
"""The share of a replan's budget given to the planner; the rest times the path and joins it
(Ruckig timing on the certified polyline: ~2 ms)."""

RUCKIG_MAX_WAYPOINTS = 12
"""A path of more waypoints than this is timed with toppra (corners rounded, the arcs checked
exactly; Ruckig when that is refused) even where the executive's timing says Ruckig, which
comes to rest at every waypoint. Such paths are TrajOpt's (30-59 waypoints close together
along a curve: straight-line TrajOpt as the executive's planner, or Roadmap + TrajOpt's
fallback when the roadmap and the tree repair found nothing in time); a shortcut route has
2-8. Found on a scene nobody here had developed on (a Panda between two bins, a board overhead;
session 35): a fallback answer of 2.79 rad executed in 12.2 s, stopping at each of its 30
waypoints, and its episode missed the deadline in both runs. Measured on straight-line
TrajOpt's answers to 39 task cases of that scene and 21 of the kitchen: median duration 12.3 /
12.6 s at rest at every waypoint, 2.3 / 2.4 s with toppra's blends; timing wall time 6.0 →
4.2 ms. Routes of 7-8 waypoints (kitchen) stay with Ruckig: toppra moved them 11-26% faster,
but with the threshold at 6, 12 episodes a scene, the median time to goal over the undisturbed
run went 1.19 → 1.09 (the bins), 1.17 → 1.29 and 1.16 → 1.19 (kitchen, two runs), 1.20 →
1.19 (panda_cage): no consistent gain within the run-to-run spread."""


def reply_timing(path: Array, timing: TimingConfig) -> TimingConfig:
    """How the executive times ``path`` (T, K) rad: ``timing``, or toppra's blends in place of
    Ruckig for a path of more than :data:`RUCKIG_MAX_WAYPOINTS` waypoints."""
    if timing.method == "ruckig" and len(path) > RUCKIG_MAX_WAYPOINTS:
        return replace(timing, method="toppra")
    return timing


@dataclass(frozen=True, eq=False)
class PlanRequest:
    """A replan: from ``start``, the commanded state at clock time ``t_handoff`` (s), to
    ``goal``, within ``budget_s`` (s) of planning. ``worlds``: the obstacle sets to plan
    against, tried in order while the start or goal is in collision with one or the goal
    pose has no free IK solution in it (the predicted
    sweep, then the obstacles as last seen). ``token``: which motion the start was taken
    from (a reply is used only while that motion is still commanded)."""

    t_request: float
    t_handoff: float
    start: State
    goal: Goal
    worlds: tuple[Obstacles, ...]
    budget_s: float
    token: int


@dataclass(frozen=True, eq=False)
class PlanReply:
    """A replan's answer: the timed trajectory (from ``request.start.q`` at rest, t = 0), or
    None with the planner's status; ``wall_s``: the planning and timing's wall time (s)."""

    request: PlanRequest
    trajectory: JointTrajectory | None
    status: str
    wall_s: float


def plan_motion(world: World, planner: Planner, request: PlanRequest,
                timing: TimingConfig) -> PlanReply:
    """Plan ``request`` with ``planner`` in ``world`` (its dynamic obstacles set to each of
    the request's obstacle sets in turn) within :data:`PLAN_SHARE` of the budget, and time the
    path (:func:`~chekhov.planners.timed.timed_trajectory` with :func:`reply_timing`: a
    trajectory off the certified polyline is checked exactly, one on it is not)."""
    t0 = time.perf_counter()
    status = "no_world"
    for obstacles in request.worlds:
        left = request.budget_s * PLAN_SHARE - (time.perf_counter() - t0)
        if left <= 0:
            break
        world.set_obstacles(obstacles)
        try:
            result = planner.plan(request.start.q, request.goal, left)
        except ChekhovError as e:     # e.g. a start outside the limits: no plan from there
            return PlanReply(request, None, f"input: {e}", time.perf_counter() - t0)
        status = str(result.status)
        if result.success and result.path is not None:
            try:
                traj = timed_trajectory(world, result.path,
                                        reply_timing(result.path, timing)).trajectory
            except TrajectoryError as e:
                status = f"timing: {e}"
                break
            return PlanReply(request, traj, status, time.perf_counter() - t0)
        if status not in ("invalid_start", "invalid_goal", "no_ik"):
            break
    return PlanReply(request, None, status, time.perf_counter() - t0)


def _same_world(world: World, planner: Planner) -> None:
    """A worker sets the obstacles of ``world``: the planner must plan in that world."""
    if getattr(planner, "world", world) is not world:
        raise ChekhovError(f"worker: planner {getattr(planner, 'name', planner)!r} plans in "
                           "another World than the worker's (build it for the worker's world)")


class Worker(Protocol):
    """Runs one replan at a time."""

    def submit(self, request: PlanRequest) -> None: ...

    def poll(self, now: float) -> PlanReply | None:
        """The reply, once it has come by clock time ``now`` (s); then the worker is free."""
        ...

    def cancel(self) -> None: ...


class InlineWorker:
    """Plans at submit time; the reply comes at ``t_request`` + its measured wall time, or
    + ``reply_after_s`` (s) when that is given (a clock on which every run is the same)."""

    def __init__(self, world: World, planner: Planner, timing: TimingConfig, *,
                 reply_after_s: float | None = None) -> None:
        _same_world(world, planner)
        self.world, self.planner, self.timing = world, planner, timing
        self.reply_after_s = reply_after_s
        self._reply: PlanReply | None = None

    def submit(self, request: PlanRequest) -> None:
        self._reply = plan_motion(self.world, self.planner, request, self.timing)

    def poll(self, now: float) -> PlanReply | None:
        r = self._reply
        if r is None:
            return None
        after = r.wall_s if self.reply_after_s is None else self.reply_after_s
        if now < r.request.t_request + after:
            return None
        self._reply = None
        return r

    def cancel(self) -> None:
        self._reply = None


class ThreadWorker:
    """Plans on a thread with its own world (the control loop's checks use another)."""

    def __init__(self, world: World, planner: Planner, timing: TimingConfig) -> None:
        _same_world(world, planner)
        self.world, self.planner, self.timing = world, planner, timing
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="chekhov-plan")
        self._future: Future[PlanReply] | None = None

    def submit(self, request: PlanRequest) -> None:
        self._future = self._pool.submit(plan_motion, self.world, self.planner, request,
                                         self.timing)

    def poll(self, now: float) -> PlanReply | None:
        f = self._future
        if f is None or not f.done():
            return None
        self._future = None
        return f.result()

    def cancel(self) -> None:
        self._future = None     # a running plan finishes on its own; its reply is dropped

    def close(self, wait: bool = False) -> None:
        """Stop the thread. ``wait=False``: return at once (a plan being computed finishes on
        its own and its reply is dropped); ``wait=True``: a clean shutdown, returning once
        the thread has ended (after the plan being computed, at most its budget). Either way
        no plan not yet started runs, and no reply comes after."""
        self._future = None
        self._pool.shutdown(wait=wait, cancel_futures=True)
