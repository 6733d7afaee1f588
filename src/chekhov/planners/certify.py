"""The one place where a planner's answer becomes a success: :func:`certify`.

Every planner's result passes through it (:class:`chekhov.planners.base.PlannerBase`). A path
is certified when

* it is a finite (T >= 1, K) array whose first row is the (checked) start,
* every waypoint lies within the joint limits (to 1e-9 rad),
* its last configuration meets the goal within the goal's tolerances — a pose goal by forward
  kinematics (position error ≤ ``position_tolerance`` m, rotation angle ≤
  ``orientation_tolerance`` rad), a configuration goal joint by joint (≤ ``joint_tolerance``),
* it is collision-free at its waypoints and :data:`SUBSTEPS` interpolated configurations per
  segment — segments longer than :data:`MAX_SEGMENT_RAD` split evenly first — by the exact
  checker's decision
  (:func:`chekhov.collision.path_check.exact_path_decision`: the conservative fast checker
  first, coal on its alarms) — unless the result carries that function's certificate for
  this very path, substeps and obstacle version (a planner that already ran it), and
* it arrived by the deadline: a path found after ``time_limit_s`` is a "timeout". The
  certification's own time (``timing_s["certify"]``) counts; it runs only on a found path.
  An anytime planner's answer arrived when it certified it (``result.solutions[-1]``).

An answer that fails keeps its path in ``info["rejected_path"]`` and gets the status of the
first failed check (:class:`PlanStatus` BAD_PATH, START_MISMATCH, JOINT_LIMITS, GOAL_UNMET,
COLLISION, TIMEOUT), with ``info["certificate"]`` saying why.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.path_check import (
    CERTIFY_MAX_SEGMENT_RAD,
    CERTIFY_SUBSTEPS,
    PathCertificate,
    exact_path_decision,
    path_digest,
)
from chekhov.paths import resample_path
from chekhov.planners.result import PlanResult
from chekhov.planners.status import PlanStatus
from chekhov.transforms import rotation_angle

if TYPE_CHECKING:
    from chekhov.planners.query import PlanQuery
    from chekhov.world import World

Array = NDArray[np.float64]

SUBSTEPS = CERTIFY_SUBSTEPS
"""Interpolated configurations per segment in the collision check (the paper's 100)."""

MAX_SEGMENT_RAD = CERTIFY_MAX_SEGMENT_RAD
"""rad: a longer segment is split evenly before the collision check, so its substeps are never
more than 0.0016 rad apart (TrajOpt's waypoint spacing, the paper's). Measured: a shortcut
Panda path with a 3.35 rad segment passed at 100 substeps per segment (0.034 rad apart) and
collided at 200."""

START_TOLERANCE_RAD = 1e-6
LIMIT_TOLERANCE_RAD = 1e-9
GOAL_SLACK = 1e-6
"""Added to a goal's tolerances (m, rad) for floating-point round-off in the check."""


def certify(world: World, query: PlanQuery, result: PlanResult) -> PlanResult:
    """``result`` if it is a failure or a certified success; otherwise the same result as a
    failure with the status of the first failed check (module docstring)."""
    if not result.success:
        return _finish(result, query, None, 0.0)
    t = time.perf_counter()
    why = path_problem(world, query, result.path, result.certificate)
    # an anytime planner's answer counts from when it certified it (its last solution)
    found = query.t0 + result.solutions[-1].time_s if result.solutions else time.perf_counter()
    if not why and found > query.deadline:
        why = (PlanStatus.TIMEOUT, "the path was found after the time limit")
    return _finish(result, query, why, time.perf_counter() - t)


def path_problem(world: World, query: PlanQuery, path: Array | None,
                 certificate: PathCertificate | None = None
                 ) -> tuple[PlanStatus, str] | None:
    """(status, reason) of the first check ``path`` fails for ``query``; None when it passes.
    A ``certificate`` that covers the path stands for the collision check."""
    return check_path(world, query, path, certificate)[0]


def check_path(world: World, query: PlanQuery, path: Array | None,
               certificate: PathCertificate | None = None
               ) -> tuple[tuple[PlanStatus, str] | None, PathCertificate | None]:
    """:func:`path_problem`, and the exact check's certificate for the path when it passes
    (``certificate`` itself when that covered it)."""
    robot = world.robot
    P = None if path is None else np.asarray(path, dtype=float)
    if P is None or P.ndim != 2 or P.shape[1] != robot.dof or len(P) == 0 \
            or not np.all(np.isfinite(P)):
        shape = None if P is None else P.shape
        return (PlanStatus.BAD_PATH,
                f"expected a finite (T >= 1, {robot.dof}) path, got {shape}"), None
    if np.abs(P[0] - query.q_start).max() > START_TOLERANCE_RAD:
        return (PlanStatus.START_MISMATCH,
                "the path does not begin at the start configuration"), None
    inside = robot.within_limits(P, LIMIT_TOLERANCE_RAD)
    if not inside.all():
        return (PlanStatus.JOINT_LIMITS,
                f"waypoint {int(np.argmin(inside))} is outside the joint limits"), None
    unmet = goal_error(world, query, P[-1])
    if unmet:
        return (PlanStatus.GOAL_UNMET, unmet), None
    if certificate is not None and certificate.covers_resampled(P, SUBSTEPS, world.fast):
        return None, certificate   # this check passed P before (an anytime planner's offer)
    D = resample_path(P, MAX_SEGMENT_RAD) if len(P) > 1 else P   # the same waypoints, and more
    if certificate is not None and certificate.covers(D, SUBSTEPS, world.fast):
        return None, replace(certificate, resampled_from=path_digest(P))
    valid, proof = exact_path_decision(world.fast, world.exact, D, SUBSTEPS, query.deadline)
    if valid is None:
        return (PlanStatus.TIMEOUT, "the time limit passed during the collision check"), None
    if not valid or proof is None:
        return (PlanStatus.COLLISION,
                f"in collision at {SUBSTEPS} substeps per segment (exact checker)"), None
    return None, replace(proof, resampled_from=path_digest(P))


def goal_error(world: World, query: PlanQuery, q: Array) -> str:
    """Why ``q`` (K,) misses the query's goal ("" when it meets it within tolerance)."""
    goal = query.goal
    if goal.q is not None:
        err = float(np.abs(q - goal.q).max())
        if err > goal.joint_tolerance + GOAL_SLACK:
            return f"last configuration {err:.3g} rad from the goal (tolerance " \
                   f"{goal.joint_tolerance:g})"
        return ""
    assert goal.T_world_ee is not None
    T = world.robot.compute_ee_pose(q)
    dp = float(np.linalg.norm(T[:3, 3] - goal.T_world_ee[:3, 3]))
    da = rotation_angle(T[:3, :3], goal.T_world_ee[:3, :3])
    if dp > goal.position_tolerance + GOAL_SLACK or da > goal.orientation_tolerance + GOAL_SLACK:
        return (f"end effector {dp * 1000:.2f} mm / {da:.4f} rad from the goal pose "
                f"(tolerance {goal.position_tolerance * 1000:g} mm / "
                f"{goal.orientation_tolerance:g} rad)")
    return ""


def _finish(result: PlanResult, query: PlanQuery, why: tuple[PlanStatus, str] | None,
            certify_s: float) -> PlanResult:
    """The result with ``time_s`` from the query's start, the certification's time and, when
    it failed, its reason."""
    timing = {**result.timing_s, "certify": certify_s}
    info = dict(result.info)
    if query.clamped:
        info["clamped"] = query.clamped
    if result.success:
        info["certificate"] = "certified" if why is None else why[1]
    now = time.perf_counter()
    if why is None:
        return replace(result, time_s=now - query.t0, timing_s=timing, info=info)
    info["rejected_path"] = result.path
    return replace(result, success=False, path=None, status=why[0], time_s=now - query.t0,
                   timing_s=timing, info=info)
