"""Inverse kinematics: end-effector pose → joint configurations within limits.

Damped least squares (Levenberg-Marquardt) on the pose error log6(T_ee⁻¹ T_target), from random
restarts; joint limits are enforced by clamping after every step.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from chekhov.errors import IKError
from chekhov.robot.robot import Robot

Array = NDArray[np.float64]


@dataclass(frozen=True)
class IKConfig:
    """Settings of :func:`solve_ik`.

    Attributes:
        position_tolerance: m. rotation_tolerance: rad.
        max_iterations: per restart. max_restarts: random starts tried in all.
        damping: Levenberg-Marquardt damping (m², rad²).
        min_separation: rad; solutions closer than this (joint-space norm) are duplicates.
    """

    position_tolerance: float = 1e-4
    rotation_tolerance: float = 1e-3
    max_iterations: int = 100
    max_restarts: int = 40
    damping: float = 1e-6
    min_separation: float = 0.1


def solve_ik(robot: Robot, T_world_ee: Array, n_solutions: int = 1, *,
             q_seed: Array | None = None, rng: np.random.Generator | None = None,
             accept: Callable[[Array], bool] | None = None,
             config: IKConfig = IKConfig(), deadline: float = math.inf) -> Array:
    """Joint configurations reaching T_world_ee (4, 4): shape (n, K) with 1 ≤ n ≤ n_solutions.

    Distinct solutions come from random restarts (``q_seed`` first, if given). ``accept`` can
    reject solutions (e.g. ``fast.is_valid`` for collision-free ones only). No restart begins
    after ``deadline`` (a ``time.perf_counter()`` value, s). Raises :class:`IKError` with the
    best residual when none is found.
    """
    T_target = np.asarray(T_world_ee, dtype=float)
    if T_target.shape != (4, 4) or not np.all(np.isfinite(T_target)):
        raise IKError(f"target pose must be a finite 4x4 matrix, got shape {T_target.shape}")
    rng = rng if rng is not None else np.random.default_rng()
    shoulder, reach = robot.reach
    dist = float(np.linalg.norm(T_target[:3, 3] - shoulder))
    if dist > reach:
        raise IKError(f"end-effector position {np.round(T_target[:3, 3], 3).tolist()} is "
                      f"{dist:.3f} m from the first joint, beyond the arm's reach of {reach:.3f} m")
    target = pin.SE3(T_target)
    model, data, fid = robot.model, robot.model.createData(), robot.ee_frame_id
    solutions: list[Array] = []
    best_err = (np.inf, np.inf)
    rejected = 0
    attempts = 0
    for attempt in range(config.max_restarts):
        if attempt and time.perf_counter() > deadline:
            break
        attempts += 1
        q0 = (robot.check_configuration(q_seed, "q_seed") if attempt == 0 and q_seed is not None
              else rng.uniform(robot.lower, robot.upper))
        q, pos_err, rot_err = _descend(model, data, fid, target, q0, robot.lower, robot.upper,
                                       config, deadline)
        if pos_err + rot_err < sum(best_err):
            best_err = (pos_err, rot_err)
        if pos_err > config.position_tolerance or rot_err > config.rotation_tolerance:
            continue
        if any(np.linalg.norm(q - s) < config.min_separation for s in solutions):
            continue
        if accept is not None and not accept(q):
            rejected += 1
            continue
        solutions.append(q)
        if len(solutions) >= n_solutions:
            break
    if not solutions:
        p = T_target[:3, 3]
        why = (f"{rejected} solution(s) rejected (e.g. in collision)" if rejected else
               f"best residual {best_err[0]:.4f} m, {best_err[1]:.4f} rad")
        raise IKError(f"no IK solution for end-effector position {np.round(p, 3).tolist()} "
                      f"after {attempts} restarts: {why}"
                      + (" (time limit reached)" if attempts < config.max_restarts else ""))
    return np.array(solutions)


def _descend(model: pin.Model, data: pin.Data, fid: int, target: pin.SE3, q: Array,
             lower: Array, upper: Array, cfg: IKConfig, deadline: float = math.inf
             ) -> tuple[Array, float, float]:
    """Damped least squares from q for at most ``cfg.max_iterations`` steps, stopping at the
    tolerance or at ``deadline`` (perf_counter, s); (q, position error m, rotation error rad)."""
    q = q.copy()
    eye = np.eye(6)
    err = np.full(6, np.inf)
    for it in range(cfg.max_iterations):
        if it % 8 == 7 and time.perf_counter() > deadline:
            break
        pin.framesForwardKinematics(model, data, q)
        iMd = data.oMf[fid].actInv(target)
        err = pin.log6(iMd).vector
        if (np.linalg.norm(err[:3]) < cfg.position_tolerance * 0.5
                and np.linalg.norm(err[3:]) < cfg.rotation_tolerance * 0.5):
            break
        J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)
        J = pin.Jlog6(iMd.inverse()) @ J
        dq = J.T @ np.linalg.solve(J @ J.T + cfg.damping * eye + 1e-3 * np.linalg.norm(err)
                                   * eye, err)
        q = np.clip(q + dq, lower, upper)
    pin.framesForwardKinematics(model, data, q)
    T = data.oMf[fid]
    pos = float(np.linalg.norm(T.translation - target.translation))
    rot = float(np.linalg.norm(pin.log3(T.rotation.T @ target.rotation)))
    return q, pos, rot
