"""A timed joint trajectory: :class:`JointTrajectory`.

Knots: positions (T, K) rad at times (T,) s, with velocities (T, K) rad/s and accelerations
(T, K) rad/s². Between knots the trajectory is the **cubic Hermite** polynomial of each joint
that matches position and velocity at both ends, so :meth:`~JointTrajectory.sample` returns a
velocity that is the derivative of the position it returns and an acceleration that is the
derivative of that velocity (C¹; the acceleration is linear within an interval, so its extremes
are at the knots and velocity and acceleration limits can be checked exactly:
:func:`hermite_accelerations`). The stored accelerations are the interpolant's at each knot
(from the right; the last knot's from the left): :meth:`JointTrajectory.from_velocities` and
:meth:`JointTrajectory.from_waypoints` compute them, and then ``sample`` at a stored time returns
the stored values. (A trajectory built directly with other accelerations keeps them as given;
``sample`` still returns the interpolant's.) Time parameterisation
(:func:`chekhov.timing.time_parameterize`) writes knots a few ms apart.

File format (``save`` / ``load``): an ``.npz`` (NumPy zip, no pickles) with ``format`` =
"chekhov-trajectory", ``version`` = 1, ``joint_names`` (K,) str, ``times`` (T,),
``positions``, ``velocities``, ``accelerations`` (T, K) float64; units rad, s. Written
atomically (a temporary file in the same folder, then renamed over the target).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

from chekhov.atomic import write_atomic
from chekhov.errors import TrajectoryError
from chekhov.npzfile import read_npz
from chekhov.paths import path_length

Array = NDArray[np.float64]
FORMAT = "chekhov-trajectory"
VERSION = 1


@dataclass(frozen=True, eq=False)
class JointTrajectory:
    """Joint positions, velocities and accelerations at increasing times from 0.

    Attributes:
        joint_names: (K,) the joints, in column order.
        times: (T,) s, strictly increasing, times[0] = 0.
        positions: (T, K) rad. velocities: (T, K) rad/s. accelerations: (T, K) rad/s².
    """

    joint_names: tuple[str, ...]
    times: Array
    positions: Array
    velocities: Array
    accelerations: Array

    def __post_init__(self) -> None:
        names = tuple(str(n) for n in self.joint_names)
        object.__setattr__(self, "joint_names", names)
        t = _array("times", self.times, 1)
        if len(t) < 1:
            raise TrajectoryError("field 'times': needs at least one knot")
        if t[0] != 0.0:
            raise TrajectoryError(f"field 'times': must start at 0 s, starts at {t[0]!r}")
        steps = np.diff(t)
        if np.any(steps <= 0):
            i = int(np.argmax(steps <= 0)) + 1
            raise TrajectoryError(f"field 'times': not strictly increasing at index {i} "
                                  f"({t[i - 1]!r} then {t[i]!r})")
        object.__setattr__(self, "times", t)
        for field in ("positions", "velocities", "accelerations"):
            a = _array(field, getattr(self, field), 2)
            if a.shape != (len(t), len(names)):
                raise TrajectoryError(f"field '{field}': shape {a.shape}, expected "
                                      f"({len(t)}, {len(names)}) (times x joints)")
            object.__setattr__(self, field, a)

    @classmethod
    def from_velocities(cls, joint_names: tuple[str, ...], times: Array, positions: Array,
                        velocities: Array) -> JointTrajectory:
        """The trajectory through these knots (times (T,) s, positions (T, K) rad, velocities
        (T, K) rad/s), its accelerations those of the interpolant."""
        t = np.asarray(times, dtype=float)
        P, V = np.asarray(positions, dtype=float), np.asarray(velocities, dtype=float)
        if len(t) < 2 or P.shape != V.shape or P.shape[:1] != t.shape:
            return cls(joint_names, t, P, V, np.zeros_like(P))   # validation says why
        a_start, a_end = hermite_accelerations(t, P, V)
        return cls(joint_names, t, P, V, np.vstack([a_start, a_end[-1:]]))

    @classmethod
    def from_waypoints(cls, positions: Array, times: Array, joint_names: tuple[str, ...]
                       ) -> JointTrajectory:
        """The C² cubic spline through positions (T, K) rad at times (T,) s, at rest at both
        ends (scipy's clamped ``CubicSpline``): its velocities (rad/s) and accelerations
        (rad/s²) at the knots, which the cubic Hermite interpolation reproduces exactly. It
        may overshoot the waypoints between them; no limits are applied (for that, use
        :func:`chekhov.timing.time_parameterize`)."""
        P = np.asarray(positions, dtype=float)
        z = np.zeros_like(P) if P.ndim == 2 else P
        first = cls(joint_names, times, P, z, z)            # validates, locating the field
        if len(first.times) < 2:
            return first
        spline = CubicSpline(first.times, first.positions, bc_type="clamped", axis=0)
        return cls.from_velocities(first.joint_names, first.times, first.positions,
                                   spline(first.times, 1))

    # --- properties -------------------------------------------------------------------
    @property
    def dof(self) -> int:
        return len(self.joint_names)

    @property
    def duration(self) -> float:
        """s, the time of the last knot."""
        return float(self.times[-1])

    @property
    def length(self) -> float:
        """Joint-space length of the knots' polyline (rad)."""
        return path_length(self.positions)

    # --- sampling ---------------------------------------------------------------------
    def sample(self, t: float | Array) -> tuple[Array, Array, Array]:
        """(q, q̇, q̈) at time(s) t (s; clamped to [0, duration]): (K,) each for a scalar t,
        (N, K) for an array of N times."""
        ts = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), 0.0, self.duration)
        if not np.all(np.isfinite(ts)):
            raise TrajectoryError("sample: times must be finite")
        if len(self.times) == 1:
            n = len(ts)
            out = tuple(np.repeat(a[:1], n, axis=0)
                        for a in (self.positions, self.velocities, self.accelerations))
        else:
            out = _hermite3(self.times, self.positions, self.velocities, ts)
        if np.ndim(t) == 0:
            return out[0][0], out[1][0], out[2][0]
        return out[0], out[1], out[2]

    def resample(self, dt: float) -> JointTrajectory:
        """Knots every ``dt`` s (and at the end), sampled from this trajectory: the same
        motion where it is (piecewise) cubic, a close approximation elsewhere."""
        if not (np.isfinite(dt) and dt > 0):
            raise TrajectoryError(f"resample: dt must be a positive number of s, got {dt!r}")
        if len(self.times) == 1:
            return self
        ts = np.arange(0.0, self.duration, dt)
        ts = np.append(ts, self.duration) if self.duration > ts[-1] else ts
        return self._at(ts)

    def densify(self, n: int) -> JointTrajectory:
        """``n`` knots evenly spaced in time within every interval (n ≥ 1; n = 1 keeps it)."""
        if int(n) != n or n < 1:
            raise TrajectoryError(f"densify: n must be an integer >= 1, got {n!r}")
        if len(self.times) == 1:
            return self
        f = np.arange(int(n)) / n
        ts = (self.times[:-1, None] + np.diff(self.times)[:, None] * f).ravel()
        return self._at(np.append(ts, self.duration))

    def _at(self, ts: Array) -> JointTrajectory:
        q, qd, _ = self.sample(ts)
        return JointTrajectory.from_velocities(self.joint_names, ts, q, qd)

    # --- files ------------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """Write the trajectory to ``path`` (.npz, the module's format), atomically."""
        path = Path(path)
        arrays: dict[str, Any] = {"format": np.array(FORMAT), "version": np.array(VERSION),
                  "joint_names": np.array(self.joint_names, dtype=str), "times": self.times,
                  "positions": self.positions, "velocities": self.velocities,
                  "accelerations": self.accelerations}
        write_atomic(path, lambda f: np.savez(f, **arrays), "wb")
        return path

    @classmethod
    def load(cls, path: str | Path) -> JointTrajectory:
        """Read a trajectory file; a :class:`TrajectoryError` names the file and the field."""
        path = Path(path)
        fields = ("format", "version", "joint_names", "times", "positions", "velocities",
                  "accelerations")
        data = read_npz(path, fields, TrajectoryError, "trajectory")
        for name in fields:
            if name not in data:
                raise TrajectoryError(f"{path}: field '{name}' is missing")
        if data["format"].shape != () or str(data["format"]) != FORMAT:
            raise TrajectoryError(f"{path}: field 'format' is {str(data['format'])[:40]!r}, "
                                  f"expected {FORMAT!r}")
        if data["version"].shape != () or str(data["version"]) != str(VERSION):
            raise TrajectoryError(f"{path}: field 'version' is {str(data['version'])[:40]}, "
                                  f"expected {VERSION} (a newer chekhov wrote it?)")
        try:
            return cls(tuple(str(n) for n in np.atleast_1d(data["joint_names"])),
                       data["times"], data["positions"], data["velocities"],
                       data["accelerations"])
        except TrajectoryError as e:
            raise TrajectoryError(f"{path}: {e}") from e


def _array(field: str, value: object, ndim: int) -> Array:
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise TrajectoryError(f"field '{field}': not an array of numbers ({e})") from e
    if a.ndim != ndim:
        raise TrajectoryError(f"field '{field}': {a.ndim}-D, expected {ndim}-D")
    bad = ~np.isfinite(a)
    if bad.any():
        raise TrajectoryError(f"field '{field}': not finite at index "
                              f"{tuple(int(i) for i in np.argwhere(bad)[0])}")
    a.setflags(write=False)
    return a


def hermite_accelerations(times: Array, P: Array, V: Array) -> tuple[Array, Array]:
    """The cubic Hermite interpolant's accelerations (rad/s²) at the start (from the right)
    and at the end (from the left) of each interval: (T-1, K) each. Within an interval the
    acceleration is linear between the two, so these bound it."""
    h = np.diff(times)[:, None]
    dp = P[1:] - P[:-1]
    a_start = (6 * dp - 4 * V[:-1] * h - 2 * V[1:] * h) / (h * h)
    a_end = (-6 * dp + 2 * V[:-1] * h + 4 * V[1:] * h) / (h * h)
    return a_start, a_end


def _hermite3(times: Array, P: Array, V: Array, ts: Array) -> tuple[Array, Array, Array]:
    """Cubic Hermite interpolation (position and velocity match at both knots) of each joint at
    times ts (N,): (q, q̇, q̈), (N, K) each; q̈ from the right at a knot."""
    i = np.clip(np.searchsorted(times, ts, side="right") - 1, 0, len(times) - 2)
    h = (times[i + 1] - times[i])[:, None]
    s = ((ts - times[i])[:, None]) / h
    p0, p1, m0, m1 = P[i], P[i + 1], V[i] * h, V[i + 1] * h
    # q(s) = c0 + c1 s + c2 s² + c3 s³ with s in [0, 1]
    c2 = 3 * (p1 - p0) - 2 * m0 - m1
    c3 = -2 * (p1 - p0) + m0 + m1
    q = p0 + s * (m0 + s * (c2 + s * c3))
    dq = m0 + s * (2 * c2 + s * 3 * c3)
    ddq = 2 * c2 + 6 * c3 * s
    return q, dq / h, ddq / (h * h)
