"""Time parameterisation of a geometric path (waypoints (T, K), rad) into a
:class:`~chekhov.trajectory.JointTrajectory`, under per-joint velocity, acceleration and (for
ruckig) jerk limits, with two field libraries:

* ``"toppra"`` (default): TOPP-RA (Pham & Pham 2018), the time-optimal parameterisation
  along a C² cubic spline through the waypoints, velocity and acceleration limits. Fast
  motion through the waypoints without stopping; the spline leaves the straight segments a
  little where the path turns (the result says by how much: ``max_deviation_rad``).
* ``"ruckig"``: jerk-limited (Ruckig, Berscheid & Kröger 2021, as MoveIt uses it), straight
  segment by straight segment, at rest at every waypoint: slower, but exactly on the
  waypoints' polyline — the path that was certified.

A planner's certified answer is a polyline; the planners layer
(:func:`chekhov.planners.timed.timed_trajectory`) keeps toppra's trajectory only when it is
collision-free by the exact check of its own knots, and otherwise times the certified
polyline with ruckig. Velocity and acceleration limits hold at the knots, which are
``knot_dt_s`` apart; between knots the quintic Hermite interpolation follows the profile.
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from chekhov.errors import TrajectoryError
from chekhov.trajectory import JointTrajectory, hermite_accelerations

Array = NDArray[np.float64]
METHODS = ("toppra", "ruckig")


@dataclass(frozen=True)
class TimingConfig:
    """How a path is timed.

    Attributes:
        method: "toppra" or "ruckig" (module docstring).
        velocity_scale: share of the robot's velocity limits (URDF) to use, in (0, 1].
        acceleration_limit: rad/s², every joint (the URDF has none).
        jerk_limit: rad/s³, every joint (ruckig only).
        knot_dt_s: s between the stored knots.
        gridpoints: toppra's discretisation of the path (at least this many points).
    """

    method: str = "toppra"
    velocity_scale: float = 1.0
    acceleration_limit: float = 3.0
    jerk_limit: float = 30.0
    knot_dt_s: float = 0.005
    gridpoints: int = 100

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise TrajectoryError(f"TimingConfig.method: {self.method!r}, expected one of "
                                  f"{list(METHODS)}")
        for name in ("acceleration_limit", "jerk_limit", "knot_dt_s"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and np.isfinite(v) and v > 0):
                raise TrajectoryError(f"TimingConfig.{name}: must be a positive number, "
                                      f"got {v!r}")
        if not (0 < self.velocity_scale <= 1):
            raise TrajectoryError(f"TimingConfig.velocity_scale: must be in (0, 1], got "
                                  f"{self.velocity_scale!r}")


class Limits(NamedTuple):
    """Per-joint limits (K,) each: rad/s, rad/s², rad/s³."""

    velocity: Array
    acceleration: Array
    jerk: Array


class Timed(NamedTuple):
    """A timed path: the trajectory, the method that made it, and the largest distance (rad)
    of its knots from the waypoints' polyline."""

    trajectory: JointTrajectory
    method: str
    max_deviation_rad: float


def joint_limits(velocity_limit: Array, config: TimingConfig) -> Limits:
    """The limits ``config`` sets for a robot with these velocity limits (K,) rad/s."""
    v = np.asarray(velocity_limit, dtype=float) * config.velocity_scale
    if v.ndim != 1 or not np.all(np.isfinite(v) & (v > 0)):
        raise TrajectoryError(f"velocity limits must be positive and finite, got {v}")
    return Limits(v, np.full_like(v, config.acceleration_limit),
                  np.full_like(v, config.jerk_limit))


def time_parameterize(path: Array, joint_names: tuple[str, ...], limits: Limits,
                      config: TimingConfig | None = None) -> Timed:
    """The path (T, K) rad timed by ``config.method`` (default config: toppra) under
    ``limits``."""
    config = config if config is not None else TimingConfig()
    P = _distinct(np.asarray(path, dtype=float))
    if P.ndim != 2 or P.shape[1] != len(joint_names) or not np.all(np.isfinite(P)):
        raise TrajectoryError(f"path: expected a finite (T, {len(joint_names)}) array, got "
                              f"shape {P.shape}")
    if len(P) == 1:
        z = np.zeros_like(P)
        return Timed(JointTrajectory(joint_names, np.zeros(1), P, z, z), config.method, 0.0)
    if config.method == "toppra":
        traj = _toppra(P, joint_names, limits, config)
    else:
        traj = _ruckig_segments(P, joint_names, limits, config)
    traj = within_limits(traj, limits)
    return Timed(traj, config.method, polyline_deviation(traj.positions, P))


def within_limits(traj: JointTrajectory, limits: Limits) -> JointTrajectory:
    """``traj``, slowed down uniformly (times × c, velocities / c, accelerations / c²) if its
    interpolant anywhere exceeds the velocity or acceleration limits: the parameterisations
    respect them on their own grids, the interpolation between knots may overshoot slightly
    (toppra: up to 25% in acceleration where its discretisation switches)."""
    ratio = limit_ratio(traj, limits)
    if ratio <= 1.0:
        return traj
    c = ratio * (1.0 + 1e-9)
    return JointTrajectory(traj.joint_names, traj.times * c, traj.positions,
                           traj.velocities / c, traj.accelerations / (c * c))


def limit_ratio(traj: JointTrajectory, limits: Limits) -> float:
    """The largest of |q̇| / velocity limit and sqrt(|q̈| / acceleration limit) anywhere on the
    trajectory's interpolant, exactly (its velocity is quadratic and its acceleration linear
    within each interval)."""
    if len(traj.times) < 2:
        return 0.0
    P, V, h = traj.positions, traj.velocities, np.diff(traj.times)[:, None]
    a0, a1 = hermite_accelerations(traj.times, P, V)
    acc = np.maximum(np.abs(a0), np.abs(a1))
    # velocity within an interval: v(u) = V0 + a0 h u + (a1 - a0) h u² / 2, u in [0, 1]
    vel = np.maximum(np.abs(V[:-1]), np.abs(V[1:]))
    da = a1 - a0
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(np.abs(da) > 0, -a0 / da, -1.0)
    inside = (u > 0) & (u < 1)
    v_peak = np.abs(V[:-1] + a0 * h * u + da * h * u * u / 2)
    vel = np.where(inside, np.maximum(vel, v_peak), vel)
    return max(float((vel / limits.velocity).max()),
               float(np.sqrt((acc / limits.acceleration).max())))


def polyline_deviation(Q: Array, P: Array) -> float:
    """Largest distance (rad) from a configuration of Q (N, K) to the polyline P (T, K)."""
    a, d = P[:-1], np.diff(P, axis=0)                              # (S, K)
    dd = np.maximum(np.einsum("sk,sk->s", d, d), 1e-300)
    t = np.clip(np.einsum("nsk,sk->ns", Q[:, None, :] - a[None], d) / dd, 0.0, 1.0)
    gap = Q[:, None, :] - (a[None] + t[..., None] * d[None])       # (N, S, K)
    return float(np.sqrt(np.einsum("nsk,nsk->ns", gap, gap).min(axis=1)).max())


def _distinct(P: Array) -> Array:
    """P without waypoints equal to the one before (a zero-length segment has no direction)."""
    if P.ndim != 2 or len(P) < 2:
        return P
    keep = np.concatenate([[True], np.linalg.norm(np.diff(P, axis=0), axis=1) > 1e-12])
    return P[keep]


def _toppra(P: Array, names: tuple[str, ...], limits: Limits, config: TimingConfig
            ) -> JointTrajectory:
    import toppra
    import toppra.algorithm
    import toppra.constraint

    logging.getLogger("toppra").setLevel(logging.ERROR)   # its INFO lines on every call
    ss = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    spline = toppra.SplineInterpolator(ss, P)
    constraints = [
        toppra.constraint.JointVelocityConstraint(
            np.column_stack([-limits.velocity, limits.velocity])),
        toppra.constraint.JointAccelerationConstraint(
            np.column_stack([-limits.acceleration, limits.acceleration]))]
    algo = toppra.algorithm.TOPPRA(constraints, spline, parametrizer="ParametrizeConstAccel",
                                   gridpt_min_nb_points=max(config.gridpoints, 2 * len(P)))
    try:
        timed = algo.compute_trajectory()
    except Exception as e:   # toppra's numerics (a failed LP, a degenerate spline)
        raise TrajectoryError(f"toppra failed: {type(e).__name__}: {e}") from e
    if timed is None:
        raise TrajectoryError("toppra found no parameterisation within the limits")
    ts = _knot_times(float(timed.duration), config.knot_dt_s)
    return JointTrajectory.from_velocities(names, ts, timed(ts), timed(ts, 1))


def _ruckig_segments(P: Array, names: tuple[str, ...], limits: Limits,
                     config: TimingConfig) -> JointTrajectory:
    """Rest-to-rest, jerk-limited motion along each straight segment in turn."""
    from ruckig import InputParameter, Result, Ruckig, Trajectory

    t0, pieces = 0.0, []
    for a, b in itertools.pairwise(P):
        L = float(np.linalg.norm(b - a))
        u = (b - a) / L
        inp = InputParameter(1)
        inp.current_position, inp.target_position = [0.0], [L]
        inp.current_velocity = inp.current_acceleration = [0.0]
        inp.target_velocity = inp.target_acceleration = [0.0]
        inp.max_velocity = [_along(limits.velocity, u)]
        inp.max_acceleration = [_along(limits.acceleration, u)]
        inp.max_jerk = [_along(limits.jerk, u)]
        traj = Trajectory(1)
        if Ruckig(1).calculate(inp, traj) not in (Result.Working, Result.Finished):
            raise TrajectoryError("ruckig found no motion along a segment")
        ts = _knot_times(float(traj.duration), config.knot_dt_s)
        s = np.array([traj.at_time(float(t)) for t in ts])[:, :, 0]   # (n, 3): s, ṡ, s̈
        pieces.append((t0 + ts, a + s[:, :1] * u, s[:, 1:2] * u, s[:, 2:3] * u))
        t0 += float(traj.duration)
    # consecutive segments share their end knot (at rest): keep it once
    cat = [np.concatenate([p[k] if i == 0 else p[k][1:] for i, p in enumerate(pieces)])
           for k in range(4)]
    return JointTrajectory.from_velocities(names, cat[0], cat[1], cat[2])


def _along(limit: Array, u: Array) -> float:
    """The largest rate along the unit direction u that keeps every joint within ``limit``."""
    return float(np.min(limit / np.maximum(np.abs(u), 1e-12)))


def _knot_times(duration: float, dt: float) -> Array:
    n = max(int(np.ceil(duration / dt)), 1)
    return np.linspace(0.0, duration, n + 1)
