"""Time parameterisation of a geometric path (waypoints (T, K), rad) into a
:class:`~chekhov.trajectory.JointTrajectory`, under per-joint velocity (rad/s, the URDF's),
acceleration (rad/s²) and, for ruckig, jerk (rad/s³) limits, with two field libraries:

* ``"toppra"`` (default): TOPP-RA (Pham & Pham 2018), the time-optimal parameterisation under
  velocity and acceleration limits (solved by :mod:`chekhov.topp_kernel`, or by the toppra
  package: ``TimingConfig.toppra_solver``) along the waypoints' polyline with each corner
  rounded by a circular arc (Kunz & Stilman 2012, the blends MoveIt's time-optimal
  parameterisation uses): :class:`BlendedPolyline`. Every configuration of the arc is within
  ``TimingConfig.blend_deviation_rad`` (joint-space L2, rad) of the corner waypoint it rounds,
  so **the trajectory stays within that distance of the certified polyline** (and on it along
  the straight parts); the motion does not stop at corners. A corner turned too sharply for an
  arc of radius :data:`MIN_BLEND_RADIUS_RAD` (a reversal, a very short segment) is not rounded:
  the motion comes to rest there. ``blend_deviation_rad=0`` rests at every corner, exactly on
  the polyline.
* ``"ruckig"``: jerk-limited (Ruckig, Berscheid & Kröger 2021, as MoveIt uses it), straight
  segment by straight segment, at rest at every waypoint: slower, but exactly on the
  waypoints' polyline. (Ruckig's intermediate waypoints need its cloud API or Pro version.)

Why not a spline through the waypoints: it leaves the straight segments that the collision
checker certified by up to ~1 rad on planners' paths (measured on tabletop_pole), so its
trajectory had to be re-checked and was often in collision. A blend leaves the polyline by at
most ``blend_deviation_rad``; the planners layer (:func:`chekhov.planners.timed.timed_trajectory`)
still re-checks any trajectory that leaves the polyline and falls back to ruckig.

Limits hold everywhere on the returned trajectory's interpolant, not only at its knots: knots
are at most ``knot_dt_s`` apart (and at every toppra grid point, so the straight parts are
reproduced exactly by the cubic Hermite interpolation), and :func:`within_limits` slows the
whole trajectory uniformly by the (small) factor the interpolant may exceed them by.
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from ruckig import InputParameter, Result, Ruckig, Trajectory

from chekhov.errors import TrajectoryError
from chekhov.polyline_kernel import nearest_segments
from chekhov.topp_kernel import path_speeds
from chekhov.trajectory import JointTrajectory, hermite_accelerations

Array = NDArray[np.float64]
METHODS = ("toppra", "ruckig")
TOPPRA_SOLVERS = ("compiled", "library")
MIN_BLEND_RADIUS_RAD = 1e-3
"""rad: a corner whose arc would be tighter than this is not rounded; the motion rests there."""
STRAIGHT_RAD = 1e-6
"""rad: a corner turning by less than this is left as it is (no arc, no stop)."""
GRID_STEP_RAD = 0.1
"""rad of path length: the largest step of toppra's grid."""
ARC_STEP_RAD = 0.1
"""rad of turn: the largest step of toppra's grid on an arc."""
GRID_MIN_STEP_RAD = 1e-4
"""rad of path length: grid points nearer than this (or than half the grid's step, on a short
path) to the previous one are dropped."""
GRADED_FROM_RAD = 0.002
"""rad of path length: the first graded grid step from a line's end."""


@dataclass(frozen=True)
class TimingConfig:
    """How a path is timed.

    Attributes:
        method: "toppra" or "ruckig" (module docstring).
        velocity_scale: share of the robot's velocity limits (URDF) to use, in (0, 1].
        acceleration_limit: rad/s², one for every joint or a tuple of one per joint (the URDF
            has none).
        jerk_limit: rad/s³, one for every joint or one per joint (ruckig only).
        knot_dt_s: s, the largest time between the stored knots.
        gridpoints: toppra's discretisation of the path (at least this many points).
        blend_deviation_rad: toppra: the largest joint-space distance (L2, rad) of a rounded
            corner from its waypoint; 0 rests at every corner.
        toppra_solver: "compiled" (:mod:`chekhov.topp_kernel`: TOPP-RA for these limits,
            exact per stage, ~20 times faster) or "library" (the toppra package's solver).
            The same grid and scheme; durations agree to ~1e-6 (``tests/test_trajectory.py``).
    """

    method: str = "toppra"
    velocity_scale: float = 1.0
    acceleration_limit: float | tuple[float, ...] = 3.0
    jerk_limit: float | tuple[float, ...] = 30.0
    knot_dt_s: float = 0.005
    gridpoints: int = 100
    blend_deviation_rad: float = 0.02
    toppra_solver: str = "compiled"

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise TrajectoryError(f"TimingConfig.method: {self.method!r}, expected one of "
                                  f"{list(METHODS)}")
        if self.toppra_solver not in TOPPRA_SOLVERS:
            raise TrajectoryError(f"TimingConfig.toppra_solver: {self.toppra_solver!r}, "
                                  f"expected one of {list(TOPPRA_SOLVERS)}")
        for name in ("acceleration_limit", "jerk_limit", "knot_dt_s"):
            v = getattr(self, name)
            if isinstance(v, list | np.ndarray):
                v = tuple(float(x) for x in v)
                object.__setattr__(self, name, v)
            ok = isinstance(v, int | float) or (isinstance(v, tuple) and len(v) > 0 and name
                                                 != "knot_dt_s")
            if not (ok and np.all(np.isfinite(v)) and np.all(np.asarray(v) > 0)):
                raise TrajectoryError(f"TimingConfig.{name}: must be a positive number"
                                      f"{'' if name == 'knot_dt_s' else ' or one per joint'}, "
                                      f"got {v!r}")
        if not (0 < self.velocity_scale <= 1):
            raise TrajectoryError(f"TimingConfig.velocity_scale: must be in (0, 1], got "
                                  f"{self.velocity_scale!r}")
        if not (isinstance(self.gridpoints, int) and self.gridpoints >= 2):
            raise TrajectoryError(f"TimingConfig.gridpoints: must be an integer >= 2, got "
                                  f"{self.gridpoints!r}")
        d = self.blend_deviation_rad
        if not (isinstance(d, int | float) and np.isfinite(d) and d >= 0):
            raise TrajectoryError(f"TimingConfig.blend_deviation_rad: must be a number >= 0 "
                                  f"(rad), got {d!r}")


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
    out = [v]
    for name in ("acceleration_limit", "jerk_limit"):
        x = np.asarray(getattr(config, name), dtype=float)
        if x.ndim == 1 and x.shape != v.shape:
            raise TrajectoryError(f"TimingConfig.{name}: {len(x)} values for {len(v)} joints")
        out.append(np.broadcast_to(x, v.shape).copy())
    return Limits(*out)


def time_parameterize(path: Array, joint_names: tuple[str, ...], limits: Limits,
                      config: TimingConfig | None = None) -> Timed:
    """The path (T, K) rad timed by ``config.method`` (default config: toppra) under
    ``limits``; starts and ends at rest. Raises :class:`TrajectoryError` for a malformed path
    or when the library finds no motion."""
    config = config if config is not None else TimingConfig()
    P = _distinct(np.asarray(path, dtype=float))
    if P.ndim != 2 or P.shape[1] != len(joint_names) or not np.all(np.isfinite(P)):
        raise TrajectoryError(f"path: expected a finite (T, {len(joint_names)}) array, got "
                              f"shape {P.shape}")
    if any(a.shape != (P.shape[1],) for a in limits):
        raise TrajectoryError(f"limits: expected ({P.shape[1]},) each, got "
                              f"{[a.shape for a in limits]}")
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
    (on toppra's arcs, whose direction turns between grid points)."""
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
    return float(polyline_offsets(Q, P)[1].max(initial=0.0))


def polyline_offsets(Q: Array, P: Array) -> tuple[NDArray[np.int64], Array]:
    """(segment (N,), distance (N,) rad): for each configuration of Q (N, K), the segment of
    the polyline P (T, K) nearest it (P[s] → P[s + 1]; the first of equals; 0 for one
    waypoint) and its distance from it."""
    Q, P = np.atleast_2d(Q), np.atleast_2d(P)
    if len(P) == 1:
        return np.zeros(len(Q), dtype=np.int64), np.linalg.norm(Q - P[0], axis=1)
    return nearest_segments(np.ascontiguousarray(Q, dtype=float),
                            np.ascontiguousarray(P, dtype=float))


def _distinct(P: Array) -> Array:
    """P without waypoints equal to the one before (a zero-length segment has no direction)."""
    if P.ndim != 2 or len(P) < 2:
        return P
    keep = np.concatenate([[True], np.linalg.norm(np.diff(P, axis=0), axis=1) > 1e-12])
    return P[keep]


# --- toppra along the blended polyline ------------------------------------------------------
class Corners(NamedTuple):
    """The interior waypoints of a polyline (T-2 of them): turn angle (rad), the length (rad)
    the arc takes from each neighbouring segment, and its radius (rad); 0, 0 unrounded."""

    angle: Array
    cut: Array
    radius: Array

    @property
    def stops(self) -> NDArray[np.bool_]:
        """Corners turned but not rounded: the motion rests there."""
        return (self.angle >= STRAIGHT_RAD) & (self.radius < MIN_BLEND_RADIUS_RAD)


def corners(P: Array, deviation: float) -> Corners:
    """The arcs rounding the corners of the polyline P (T, K) rad (Kunz & Stilman 2012): each
    tangent to both segments, taking at most half of either, its points within ``deviation``
    rad of the corner waypoint (cut = deviation / tan(angle / 4), radius = cut / tan(angle /
    2))."""
    d = np.diff(P, axis=0)
    L = np.linalg.norm(d, axis=1)
    y = d / L[:, None]
    angle = np.arccos(np.clip(np.einsum("sk,sk->s", y[:-1], y[1:]), -1.0, 1.0))
    turned = angle >= STRAIGHT_RAD
    safe = np.where(turned, angle, 1.0)
    cut = np.minimum(np.minimum(L[:-1], L[1:]) / 2, deviation / np.tan(safe / 4))
    radius = cut / np.tan(safe / 2)
    keep = turned & (radius >= MIN_BLEND_RADIUS_RAD)
    return Corners(angle, np.where(keep, cut, 0.0), np.where(keep, radius, 0.0))


class BlendedPolyline:
    """The polyline P (T, K) rad with its corners rounded (:func:`corners`; none may be a
    stop), as a toppra geometric path parameterised by arc length s in [0, length] rad.
    An arc includes its end points: there the second derivative is the arc's."""

    def __init__(self, P: Array, deviation: float) -> None:
        c = corners(P, deviation)
        if c.stops.any():
            raise TrajectoryError("BlendedPolyline: a corner cannot be rounded (split there)")
        d = np.diff(P, axis=0)
        L = np.linalg.norm(d, axis=1)
        y = d / L[:, None]
        cut = np.concatenate([[0.0], c.cut, [0.0]])                 # (T,) at each waypoint
        self.line_start = P[:-1] + cut[:-1, None] * y               # (S, K)
        self.line_dir = y
        line_len = L - cut[:-1] - cut[1:]
        arc = c.radius > 0                                          # (T-2,)
        arc_len = np.where(arc, c.radius * c.angle, 0.0)
        piece = np.ravel(np.column_stack([line_len, np.append(arc_len, 0.0)]))[:-1]
        s0 = np.concatenate([[0.0], np.cumsum(piece)])
        self.line_s0, self.length = s0[0::2], float(s0[-1])
        self.arc_s0, self.arc_len = s0[1:-1:2][arc], arc_len[arc]
        self.arc_r, self.arc_angle = c.radius[arc], c.angle[arc]
        y_in, y_out, q = y[:-1][arc], y[1:][arc], P[1:-1][arc]
        bis = y_out - y_in
        bis /= np.linalg.norm(bis, axis=1, keepdims=True)
        centre = q + bis * (self.arc_r / np.cos(self.arc_angle / 2))[:, None]
        start = q - c.cut[arc][:, None] * y_in
        self.arc_centre, self.arc_y = centre, y_in
        self.arc_x = (start - centre) / self.arc_r[:, None]
        # the arc: centre + r (x cos θ + y sin θ), θ = (s - s0) / r in [0, angle]; x is the
        # unit vector from the centre to the arc's start, y the incoming direction

    @property
    def dof(self) -> int:
        return int(self.line_dir.shape[1])

    @property
    def path_interval(self) -> Array:
        return np.array([0.0, self.length])

    @property
    def waypoints(self) -> None:
        return None

    def __call__(self, s: float | Array, order: int = 0) -> Array:
        """Position (rad), or its first or second derivative along s, at s: (K,) or (N, K)."""
        ss = np.clip(np.atleast_1d(np.asarray(s, dtype=float)), 0.0, self.length)
        k = np.clip(np.searchsorted(self.line_s0, ss, side="right") - 1, 0, len(self.line_s0) - 1)
        if order == 0:
            out = self.line_start[k] + self.line_dir[k] * (ss - self.line_s0[k])[:, None]
        else:
            out = self.line_dir[k] if order == 1 else np.zeros((len(ss), self.dof))
        if len(self.arc_s0):
            j = np.clip(np.searchsorted(self.arc_s0, ss, side="right") - 1, 0, None)
            on = (ss >= self.arc_s0[j]) & (ss <= self.arc_s0[j] + self.arc_len[j])
            j, r = j[on], self.arc_r[j[on]][:, None]
            th = (ss[on] - self.arc_s0[j])[:, None] / r
            x, y = self.arc_x[j], self.arc_y[j]
            if order == 0:
                out[on] = self.arc_centre[j] + r * (x * np.cos(th) + y * np.sin(th))
            elif order == 1:
                out[on] = -x * np.sin(th) + y * np.cos(th)
            else:
                out[on] = -(x * np.cos(th) + y * np.sin(th)) / r
        return out[0] if np.ndim(s) == 0 else out

    def gridpoints(self, at_least: int) -> Array:
        """toppra's grid (rad of path length): every line and arc end; steps of at most
        :data:`GRID_STEP_RAD` (and :data:`ARC_STEP_RAD` of turn on an arc); on a line, points
        also at :data:`GRADED_FROM_RAD` × 1, 2, 4 … from either end, where the motion is slow
        and a coarse grid would cost the most time; at least ``at_least`` points."""
        step = min(GRID_STEP_RAD, self.length / at_least)
        arc_end = self.arc_s0 + self.arc_len
        ends = np.unique(np.concatenate([self.line_s0, self.arc_s0, arc_end, [self.length]]))
        a, b = ends[:-1], ends[1:]                               # the pieces, in order
        starts_arc = np.abs(self.arc_s0[None, :] - a[:, None]) <= 1e-12
        on_arc = starts_arc.any(axis=1)
        turns = np.where(on_arc, np.ceil(self.arc_angle[np.argmax(starts_arc, axis=1)]
                                         / ARC_STEP_RAD) if len(self.arc_s0) else 1, 1)
        # each piece's np.linspace(a, b, n), n = its steps + 1, all at once (the same values)
        n = np.maximum(np.ceil((b - a) / step), turns).astype(np.int64) + 1
        piece = np.repeat(np.arange(len(a)), n)
        i = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
        even = i * ((b - a) / (n - 1))[piece] + a[piece]
        even[np.cumsum(n) - 1] = b
        # graded points from either end of each line longer than 2 GRADED_FROM_RAD
        line = ~on_arc & (b - a > 2 * GRADED_FROM_RAD)
        m = np.zeros(len(a), dtype=np.int64)
        m[line] = np.log2((b - a)[line] / 2 / GRADED_FROM_RAD).astype(np.int64) + 1
        owner = np.repeat(np.arange(len(a)), m)
        g = GRADED_FROM_RAD * 2.0 ** (np.arange(m.sum()) - np.repeat(np.cumsum(m) - m, m))
        grid = np.unique(np.concatenate([even, a[owner] + g, b[owner] - g]))  # g <= (b - a) / 2
        # corners that turn by 1e-6..1e-2 rad between even segments leave lines of 1e-7..1e-5
        # rad between their arcs: grid points that close made stages of ~1e-7 s whose
        # rounding the interpolant read as huge accelerations, and within_limits slowed whole
        # trajectories 13-467 times
        tiny = min(GRID_MIN_STEP_RAD, step / 2)   # a short path keeps its fine grid
        keep = np.concatenate([[True], np.diff(grid) > tiny])
        keep[-1] = True                      # both ends, however short the path
        grid = grid[keep]
        if len(grid) > 2 and grid[-1] - grid[-2] <= tiny:
            grid = np.delete(grid, -2)       # an inner point just short of the end
        grid[-1] = self.length               # toppra wants the path's ends exactly
        return grid


def _toppra(P: Array, names: tuple[str, ...], limits: Limits, config: TimingConfig
            ) -> JointTrajectory:
    """Time-optimal along the blended polyline, at rest where a corner cannot be rounded."""
    stops = np.flatnonzero(corners(P, config.blend_deviation_rad).stops) + 1
    bounds = [0, *stops.tolist(), len(P) - 1]
    pieces = [_toppra_piece(BlendedPolyline(P[a:b + 1], config.blend_deviation_rad), limits,
                            config) for a, b in itertools.pairwise(bounds)]
    return _concatenate(names, pieces)


def _toppra_piece(path: BlendedPolyline, limits: Limits, config: TimingConfig
                  ) -> tuple[Array, Array, Array]:
    """(times (N,) s, positions (N, K) rad, velocities (N, K) rad/s) of the time-optimal
    rest-to-rest motion along ``path``."""
    grid = path.gridpoints(config.gridpoints)
    if config.toppra_solver == "compiled":
        sd = path_speeds(grid, path(grid, 1), path(grid, 2), limits.velocity,
                         limits.acceleration)
    else:
        sd = _library_speeds(path, grid, limits)
    if sd is None:
        raise TrajectoryError("toppra found no parameterisation within the limits")
    return _stage_knots(path, grid, np.maximum(np.asarray(sd, dtype=float), 0.0),
                        config.knot_dt_s)


def _library_speeds(path: BlendedPolyline, grid: Array, limits: Limits) -> Array | None:
    """The toppra package's path speeds (N,) rad/s at the grid, None when it finds none."""
    import toppra.algorithm  # 0.26 s: only for this solver
    import toppra.constraint

    constraints = [
        toppra.constraint.JointVelocityConstraint(
            np.column_stack([-limits.velocity, limits.velocity])),
        toppra.constraint.JointAccelerationConstraint(
            np.column_stack([-limits.acceleration, limits.acceleration]))]
    logging.getLogger("toppra").setLevel(logging.ERROR)   # its INFO lines on every call
    try:
        algo = toppra.algorithm.TOPPRA(constraints, path, gridpoints=grid)
        _, sd, _ = algo.compute_parameterization(0.0, 0.0)
    except Exception as e:   # toppra's numerics (a failed LP)
        raise TrajectoryError(f"toppra failed: {type(e).__name__}: {e}") from e
    return None if sd is None else np.asarray(sd, dtype=float)


def _stage_knots(path: BlendedPolyline, grid: Array, sd: Array, dt: float
                 ) -> tuple[Array, Array, Array]:
    """Knots of toppra's answer (path speeds sd (N,) rad/s at the grid (N,) rad, constant
    path acceleration between them): every grid point, and at most ``dt`` s apart."""
    ds, v_sum = np.diff(grid), sd[:-1] + sd[1:]
    if np.any(v_sum <= 0):
        i = int(np.argmax(v_sum <= 0))
        raise TrajectoryError(f"toppra stops inside the path (s = {grid[i]:.4g} rad)")
    h = 2 * ds / v_sum                                   # s per stage
    u = (sd[1:] ** 2 - sd[:-1] ** 2) / (2 * ds)          # rad/s², constant within a stage
    m = np.maximum(np.ceil(h / dt).astype(int), 1)
    stage = np.repeat(np.arange(len(h)), m)
    tau = (np.arange(m.sum()) - np.repeat(np.cumsum(m) - m, m)) / m[stage] * h[stage]
    t0 = np.concatenate([[0.0], np.cumsum(h)])
    t = np.append(t0[stage] + tau, t0[-1])
    s = np.append(grid[stage] + sd[stage] * tau + u[stage] * tau ** 2 / 2, grid[-1])
    s_dot = np.append(sd[stage] + u[stage] * tau, sd[-1])
    return t, path(s), path(s, 1) * s_dot[:, None]


def _concatenate(names: tuple[str, ...], pieces: list[tuple[Array, Array, Array]]
                 ) -> JointTrajectory:
    """One trajectory of rest-to-rest pieces (times from 0 each), one after the other: each
    piece's first knot (at rest where the last one ended) is dropped."""
    t0, ts, qs, vs = 0.0, [], [], []
    for i, (t, q, v) in enumerate(pieces):
        k = 0 if i == 0 else 1
        ts.append(t0 + t[k:])
        qs.append(q[k:])
        vs.append(v[k:])
        t0 += float(t[-1])
    return JointTrajectory.from_velocities(names, np.concatenate(ts), np.concatenate(qs),
                                           np.concatenate(vs))


# --- ruckig, segment by segment ---------------------------------------------------------------
def _ruckig_segments(P: Array, names: tuple[str, ...], limits: Limits,
                     config: TimingConfig) -> JointTrajectory:
    """Rest-to-rest, jerk-limited motion along each straight segment in turn."""

    pieces = []
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
        pieces.append((ts, a + s[:, :1] * u, s[:, 1:2] * u))
    return _concatenate(names, pieces)


def _along(limit: Array, u: Array) -> float:
    """The largest rate along the unit direction u that keeps every joint within ``limit``."""
    return float(np.min(limit / np.maximum(np.abs(u), 1e-12)))


def _knot_times(duration: float, dt: float) -> Array:
    n = max(int(np.ceil(duration / dt)), 1)
    return np.linspace(0.0, duration, n + 1)
