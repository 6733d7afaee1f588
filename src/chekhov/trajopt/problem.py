"""The trajectory optimisation problem: variables, costs, constraints and their linearisation.

Variables are the waypoints Q (T, K) in radians; the first is fixed to the start (and the last
to the goal configuration when the goal is one). ``build_trajopt`` returns a
:class:`TrajOptProblem` that can be inspected and evaluated before it is solved.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from chekhov.collision.trajectory_distances import TrajectoryDistances
from chekhov.errors import ChekhovError, IKError, RobotError
from chekhov.paths import resample_path
from chekhov.robot.goal import Goal
from chekhov.robot.robot import Robot
from chekhov.trajopt.config import TrajOptConfig
from chekhov.trajopt.kernels import excess_sum, hinge_sum, weighted_squared_steps
from chekhov.world import World

Array = NDArray[np.float64]


def _read_only(a: Array) -> Array:
    """a, made read-only (kept by a problem and handed out to every caller)."""
    a.setflags(write=False)
    return a


# share of the goal tolerances the optimisation aims at (see Problem.goal_tolerance)
GOAL_AIM = 0.9


class TrajOptError(ChekhovError):
    """A trajectory optimisation problem that cannot be set up (bad seed, unreachable goal)."""


@dataclass(frozen=True, eq=False)
class Evaluation:
    """Every cost and constraint term at one trajectory, with first derivatives.

    Attributes:
        Q: the trajectory (T, K), rad.
        dist_waypoint: (T, Cd) m, discrete signed distances; grad_waypoint (T, Cd, K) m/rad.
        dist_segment: (T-1, Cc) m, swept distances; grad_segment (T-1, Cc, 2K) m/rad with
            respect to (Q[t], Q[t+1]).
        goal_error: (6,) end-effector error at Q[-1]: position (m, world) then rotation
            log3(R R_goalᵀ) (rad, world); goal_jacobian (6, K). Empty for configuration goals.
        velocity: (T-1, K) rad per step; acceleration (T-2, K) rad per step².
        torque: (T-2, K) N·m at interior waypoints; torque_jacobian (T-2, K, 3K) N·m/rad with
            respect to (Q[t-1], Q[t], Q[t+1]). Empty without a duration or torque limits.
    """

    Q: Array
    dist_waypoint: Array
    grad_waypoint: Array
    dist_segment: Array
    grad_segment: Array
    goal_error: Array
    goal_jacobian: Array
    velocity: Array
    acceleration: Array
    torque: Array
    torque_jacobian: Array


@dataclass(frozen=True, eq=False)
class TrajOptProblem:
    """A TrajOpt problem for one world, start, goal and seed.

    Attributes:
        world: robot, scene and checkers. distances: the signed-distance term evaluator.
        q_start: (K,) rad. goal: end-effector pose or configuration.
        seed: initial trajectory (T, K), rad, first row q_start.
        config: solver settings.
        weights: (K,) smoothness weights. lower, upper: (K,) joint limits, rad.
        dt: seconds between waypoints (nan without a duration).
        velocity_limit: (K,) rad per step; acceleration_limit (K,) rad per step²;
            torque_limit (K,) N·m (inf where absent).
        end_clearance_m: (2,) m, the sphere model's clearance at the seed's first and last
            waypoints: the most the collision constraint asks at either end
            (:meth:`required_clearance`: a swept segment is no farther from anything than its
            ends, so a start 1 mm into the margin made every run "infeasible": four penalty
            increases, 25-50 ms, for nothing), and at a pose goal's end the most the hinge
            asks (:meth:`safety_margins`).
    """

    world: World
    distances: TrajectoryDistances
    q_start: Array
    goal: Goal
    seed: Array
    config: TrajOptConfig
    weights: Array
    lower: Array
    upper: Array
    dt: float
    velocity_limit: Array
    acceleration_limit: Array
    torque_limit: Array
    end_clearance_m: Array

    @property
    def n_waypoints(self) -> int:
        return int(self.seed.shape[0])

    @property
    def dof(self) -> int:
        return int(self.seed.shape[1])

    @property
    def fixed_goal(self) -> bool:
        """Whether the last waypoint is fixed (configuration goal)."""
        return not self.goal.is_pose

    @property
    def has_dynamics(self) -> bool:
        return bool(np.isfinite(self.dt))

    @property
    def has_torque(self) -> bool:
        return self.has_dynamics and bool(np.isfinite(self.torque_limit).any())

    @cached_property
    def goal_tolerance(self) -> Array:
        """Per-component tolerances (6,) of the goal error that the optimisation aims at: a box
        inside ``GOAL_AIM`` times the tolerance balls, so that an answer the solver accepts
        (constraints met to its tolerance) meets the goal's own tolerance, as the planners'
        certification checks it (a path ending on the ball's surface would fail it by 1e-5)."""
        g = self.goal
        return _read_only(GOAL_AIM * np.repeat([g.position_tolerance, g.orientation_tolerance],
                                               3) / np.sqrt(3.0))

    # --- evaluation ---------------------------------------------------------------------
    def evaluate(self, Q: Array, timing: dict[str, float] | None = None,
                 deadline: float = math.inf) -> Evaluation:
        """All terms and their derivatives at Q (T, K); seconds spent are added to
        ``timing["collision"]`` (distance terms) and ``timing["linearise"]`` (the rest).
        Raises :class:`~chekhov.errors.DeadlineError` when ``deadline`` (perf_counter, s)
        passes during the collision terms."""
        cfg = self.config
        K = self.dof
        margin = cfg.check_distance_m
        t0 = time.perf_counter()
        dw, gw = self.distances.waypoints(Q, margin, cfg.terms_per_waypoint,
                                          with_obstacles=not cfg.continuous,
                                          tabled_clear_m=cfg.min_clearance_m)
        if cfg.continuous and len(Q) > 1:
            ds, g0, g1 = self.distances.segments(Q, margin, cfg.terms_per_segment, deadline)
            gs = np.concatenate([g0, g1], axis=2)
        else:
            ds, gs = np.empty((len(Q) - 1, 0)), np.empty((len(Q) - 1, 0, 2 * K))
        t1 = time.perf_counter()
        e, J = self.compute_goal_error(Q[-1])
        vel = np.diff(Q, axis=0)
        acc = Q[2:] - 2 * Q[1:-1] + Q[:-2]
        tau, dtau = self.compute_torques(Q)
        if timing is not None:
            timing["collision"] = timing.get("collision", 0.0) + t1 - t0
            timing["linearise"] = timing.get("linearise", 0.0) + time.perf_counter() - t1
        return Evaluation(Q, dw, gw, ds, gs, e, J, vel, acc, tau, dtau)

    def compute_goal_error(self, q: Array) -> tuple[Array, Array]:
        """Goal error (6,) at q — position p - p_goal (m, world) and rotation log3(R R_goalᵀ)
        (rad, world) — and its Jacobian (6, K). Empty arrays for configuration goals."""
        if not self.goal.is_pose:
            return np.empty(0), np.empty((0, self.dof))
        robot = self.world.robot
        T_goal = self.goal.T_world_ee
        assert T_goal is not None
        J = robot.compute_frame_jacobian(q)  # also runs the forward kinematics
        pin.updateFramePlacement(robot.model, robot.data, robot.ee_frame_id)
        T = robot.data.oMf[robot.ee_frame_id]
        M = T.rotation @ T_goal[:3, :3].T
        e = np.concatenate([T.translation - T_goal[:3, 3], pin.log3(M)])
        Jr = pin.Jlog3(M) @ M.T @ J[3:]
        return e, np.vstack([J[:3], Jr])

    def compute_torques(self, Q: Array) -> tuple[Array, Array]:
        """Joint torques (T-2, K) N·m at interior waypoints from RNEA with central-difference
        velocities and accelerations, and their Jacobians (T-2, K, 3K) with respect to
        (Q[t-1], Q[t], Q[t+1]). Empty without a duration or torque limits."""
        K = self.dof
        if not self.has_torque or len(Q) < 3:
            return np.empty((0, K)), np.empty((0, K, 3 * K))
        model, data = self.world.robot.model, self.world.robot.data
        dt = self.dt
        n = len(Q) - 2
        tau = np.empty((n, K))
        jac = np.empty((n, K, 3 * K))
        for i in range(n):
            qm, q, qp = Q[i], Q[i + 1], Q[i + 2]
            v = (qp - qm) / (2 * dt)
            a = (qp - 2 * q + qm) / dt**2
            pin.computeRNEADerivatives(model, data, q, v, a)
            tau[i] = pin.rnea(model, data, q, v, a)
            dq, dv = data.dtau_dq, data.dtau_dv
            Mu = np.triu(data.M)
            Ma = Mu + Mu.T - np.diag(np.diag(Mu))
            jac[i, :, :K] = -dv / (2 * dt) + Ma / dt**2
            jac[i, :, K:2 * K] = dq - 2 * Ma / dt**2
            jac[i, :, 2 * K:] = dv / (2 * dt) + Ma / dt**2
        return tau, jac

    # --- merit --------------------------------------------------------------------------
    def smoothness(self, Q: Array) -> float:
        """Σ_t ||W (q_{t+1} - q_t)||², rad²."""
        return float(weighted_squared_steps(np.asarray(Q, dtype=np.float64), self.weights))

    def violations(self, ev: Evaluation) -> dict[str, Array]:
        """Per-term violations (≥ 0) of the penalised constraints at an evaluation."""
        safe_w, safe_s = self.safety_margins()
        out = {
            "collision": np.concatenate([
                np.maximum(safe_w[:, None] - ev.dist_waypoint, 0).ravel(),
                np.maximum(safe_s[:, None] - ev.dist_segment, 0).ravel()]),
            "goal": np.maximum(np.abs(ev.goal_error) - self.goal_tolerance, 0)
            if self.goal.is_pose else np.zeros(0),
        }
        if self.has_dynamics:
            out["velocity"] = np.maximum(np.abs(ev.velocity) - self.velocity_limit, 0).ravel()
            out["acceleration"] = np.maximum(np.abs(ev.acceleration) - self.acceleration_limit,
                                             0).ravel()
        if self.has_torque:
            out["torque"] = np.maximum(np.abs(ev.torque) - self.torque_limit, 0).ravel()
        return out

    def merit(self, ev: Evaluation, mu: float) -> float:
        """The l1 merit: smoothness + μ Σ_blocks coeff · Σ violations (:meth:`violations`'
        sums, compiled: the SQP asks for it twice a step)."""
        cfg = self.config
        safe_w, safe_s = self.safety_margins()
        total = cfg.collision_coeff * (hinge_sum(safe_w, ev.dist_waypoint)
                                       + hinge_sum(safe_s, ev.dist_segment))
        if self.goal.is_pose:
            total += cfg.goal_coeff * excess_sum(ev.goal_error[None], self.goal_tolerance)
        if self.has_dynamics:
            total += cfg.limit_coeff * (excess_sum(ev.velocity, self.velocity_limit)
                                        + excess_sum(ev.acceleration, self.acceleration_limit))
        if self.has_torque:
            total += cfg.torque_coeff * excess_sum(ev.torque, self.torque_limit)
        return self.smoothness(ev.Q) + mu * float(total)

    def required_clearance(self) -> tuple[Array, Array]:
        """The clearance (m) the collision constraint asks of each waypoint (T,) and segment
        (T-1,): ``min_clearance_m``, or an end's own clearance (``end_clearance_m``) at that
        end and on the segment from it, where that is lower: the start and a configuration
        goal are fixed, and a pose goal's end can move only within the goal's tolerances
        from the seed's (an IK solution of the pose; on the Panda's task cases one in the
        spheres' margin, 1-5 cm in, made every straight-line run raise the penalty to its
        limit and end "exact_clear")."""
        return self._lowered_at_ends(self.config.min_clearance_m, (0, 1))

    def safety_margins(self) -> tuple[Array, Array]:
        """The hinge's margin (m) at each waypoint (T,) and segment (T-1,): ``safety_margin_m``,
        but at a pose goal's last waypoint and on the segment to it no more than the seed's
        end has (``end_clearance_m[1]``, an IK solution of the goal). A pre-grasp pose 1-2 cm
        from a cabinet wall otherwise set the hinge against the goal: the end stopped 1-2
        mm short of the pose at every penalty ("infeasible", 40-80 ms, on 8 of 100 kitchen
        task cases), then a retry towards the seed's end configuration."""
        return self._safety_margins

    @cached_property
    def _safety_margins(self) -> tuple[Array, Array]:
        """:meth:`safety_margins`, computed once (the SQP asks for them three times a step)."""
        ends = () if self.fixed_goal else (1,)
        waypoints, segments = self._lowered_at_ends(self.config.safety_margin_m, ends)
        return _read_only(waypoints), _read_only(segments)

    def _lowered_at_ends(self, value: float, ends: tuple[int, ...]) -> tuple[Array, Array]:
        """(T,) and (T-1,) arrays of ``value`` m, lowered to ``end_clearance_m`` at each end
        in ``ends`` (0: the first waypoint and segment, 1: the last) where that is less."""
        T = self.n_waypoints
        waypoints, segments = np.full(T, value), np.full(max(T - 1, 0), value)
        for end in ends:
            c, w, s = self.end_clearance_m[end], (0, T - 1)[end], (0, T - 2)[end]
            waypoints[w] = min(waypoints[w], c)
            if T > 1:
                segments[s] = min(segments[s], c)
        return waypoints, segments

    def constraint_report(self, ev: Evaluation) -> dict[str, float]:
        """Largest violation of each constraint, in its unit; collision measured against
        :meth:`required_clearance` (``min_clearance_m`` but at an end already closer)."""
        need_w, need_s = self.required_clearance()
        short = max(float(np.max(need_w[:, None] - ev.dist_waypoint, initial=0.0)),
                    float(np.max(need_s[:, None] - ev.dist_segment, initial=0.0)))
        out = {"collision_m": short}
        if self.goal.is_pose:
            out["goal_position_m"] = max(0.0, float(np.linalg.norm(ev.goal_error[:3]))
                                         - self.goal.position_tolerance)
            out["goal_orientation_rad"] = max(0.0, float(np.linalg.norm(ev.goal_error[3:]))
                                              - self.goal.orientation_tolerance)
        if self.has_dynamics:
            out["velocity_rad"] = float(np.max(np.abs(ev.velocity) - self.velocity_limit,
                                               initial=0.0))
            out["acceleration_rad"] = float(np.max(np.abs(ev.acceleration)
                                                   - self.acceleration_limit, initial=0.0))
        if self.has_torque:
            out["torque_nm"] = float(np.max(np.abs(ev.torque) - self.torque_limit, initial=0.0))
        return out

    def unmet(self, ev: Evaluation, tol: float = 1e-4) -> set[str]:
        """Names (``constraint_report``'s keys) of the constraints violated by more than tol
        (collision: clearance below min_clearance_m; the goal: by any amount)."""
        return {k for k, v in self.constraint_report(ev).items()
                if v > (0.0 if k.startswith("goal") else tol)}

    def satisfied(self, ev: Evaluation, tol: float = 1e-4) -> bool:
        """Whether every constraint holds (collision to min_clearance_m, the goal exactly
        within its tolerance, the rest to tol)."""
        return not self.unmet(ev, tol)


def straight_line_seed(q_start: Array, q_goal: Array, n_waypoints: int) -> Array:
    """T = n_waypoints configurations evenly spaced from q_start to q_goal, shape (T, K)."""
    t = np.linspace(0.0, 1.0, n_waypoints)[:, None]
    return (1 - t) * np.asarray(q_start, dtype=float) + t * np.asarray(q_goal, dtype=float)


def goal_configuration(world: World, q_start: Array, goal: Goal, deadline: float = math.inf
                       ) -> Array:
    """A configuration for the goal: the configuration itself, or the collision-free IK
    solution of the goal pose nearest q_start (``world.goal_ik``; no IK restart after
    ``deadline``, a ``time.perf_counter()`` value). Raises TrajOptError when there is none."""
    if goal.q is not None:
        return goal.q
    try:
        return world.goal_ik.nearest(goal, q_start, deadline=deadline)
    except IKError as e:
        raise TrajOptError(f"goal pose: {e}") from e


def build_trajopt(world: World, q_start: Array, goal: Goal, seed: Array | None = None,
                  config: TrajOptConfig | None = None,
                  distances: TrajectoryDistances | None = None) -> TrajOptProblem:
    """Set up a TrajOpt problem.

    Args:
        world: the planning world (the fast checker's current obstacles are used).
        q_start: (K,) rad.
        goal: end-effector pose with tolerances, or a configuration.
        seed: (T, K) rad, starting at q_start; resampled to at most ``config.max_step_rad``
            between waypoints. None: a straight line of ``config.n_waypoints`` to the goal
            configuration (IK nearest to q_start for pose goals).
        distances: a reusable term evaluator for ``world.fast`` (built when None).
    """
    config = config if config is not None else TrajOptConfig()
    robot = world.robot
    K = robot.dof
    try:
        q_start = robot.check_configuration(q_start, "start configuration")
        if goal.q is not None:
            robot.check_configuration(goal.q, "goal configuration")
    except RobotError as e:
        raise TrajOptError(str(e)) from e
    if goal.is_pose:
        assert goal.T_world_ee is not None
        shoulder, reach = robot.reach
        dist = float(np.linalg.norm(goal.T_world_ee[:3, 3] - shoulder))
        if dist > reach:
            raise TrajOptError(
                f"goal pose: position {np.round(goal.T_world_ee[:3, 3], 3).tolist()} is "
                f"{dist:.3f} m from the arm's first joint, beyond its reach of {reach:.3f} m")
    S = _checked_seed(world, q_start, goal, seed, config)
    weights = (np.ones(K) if config.joint_weights is None
               else np.asarray(config.joint_weights, dtype=float))
    if weights.shape != (K,):
        raise TrajOptError(f"joint_weights: expected {K} values, got {weights.shape}")
    dt, vlim, alim, tlim = _dynamics_limits(robot, config, len(S))
    distances = distances if distances is not None else TrajectoryDistances(world.fast)
    return TrajOptProblem(
        world=world, distances=distances, q_start=q_start, goal=goal, seed=S, config=config,
        weights=weights, lower=robot.lower.copy(), upper=robot.upper.copy(), dt=dt,
        velocity_limit=vlim, acceleration_limit=alim, torque_limit=tlim,
        end_clearance_m=_end_clearance(distances, S, config))


def _end_clearance(distances: TrajectoryDistances, S: Array, config: TrajOptConfig
                   ) -> Array:
    """(2,) m: the sphere model's clearance at S's first and last waypoints (beyond
    ``check_distance_m``, the terms' far value)."""
    d_ends, _ = distances.waypoints(S[[0, -1]], config.check_distance_m,
                                    config.terms_per_waypoint,
                                    tabled_clear_m=config.min_clearance_m)
    return d_ends.min(axis=1)


def _checked_seed(world: World, q_start: Array, goal: Goal, seed: Array | None,
                  config: TrajOptConfig) -> Array:
    """The seed (T, K) rad TrajOpt starts from: ``seed`` checked and resampled to at most
    ``config.max_step_rad`` (ending at a configuration goal), or a straight line to the goal
    configuration; clipped to the limits, starting exactly at q_start."""
    robot, K = world.robot, world.robot.dof
    if seed is None:
        q_goal = goal_configuration(world, q_start, goal)
        S = straight_line_seed(q_start, q_goal, config.n_waypoints)
    else:
        S = np.asarray(seed, dtype=float)
        if S.ndim != 2 or S.shape[1] != K or len(S) < 2:
            raise TrajOptError(f"seed: expected shape (T >= 2, {K}), got {S.shape}")
        if not np.all(np.isfinite(S)):
            raise TrajOptError("seed: contains NaN or inf")
        if not np.allclose(S[0], q_start, atol=1e-6):
            raise TrajOptError("seed: its first waypoint is not the start configuration")
        if goal.q is not None and not np.allclose(S[-1], goal.q, atol=1e-6):
            S = np.vstack([S, goal.q])
        S = resample_path(S, config.max_step_rad)
        if len(S) < 2:
            S = np.vstack([S, S])
    S = np.clip(S, robot.lower, robot.upper)
    S[0] = q_start
    return S


def _dynamics_limits(robot: Robot, config: TrajOptConfig, T: int
                     ) -> tuple[float, Array, Array, Array]:
    """(dt s, per-step velocity limit (K,) rad, per-step² acceleration limit (K,) rad, torque
    limit (K,) N·m) for T waypoints; nan and inf without ``config.duration_s``."""
    K = robot.dof
    inf = np.full(K, np.inf)
    if config.duration_s is None:
        return np.nan, inf, inf, inf
    if config.duration_s <= 0:
        raise TrajOptError(f"duration_s must be positive, got {config.duration_s}")
    dt = config.duration_s / (T - 1)
    vlim = config.velocity_scale * robot.velocity_limit * dt
    alim = inf if config.acceleration_limit is None else np.full(
        K, config.acceleration_limit * dt**2)
    tlim = robot.effort_limit.copy() if config.torque_limits else inf
    return dt, vlim, alim, tlim
