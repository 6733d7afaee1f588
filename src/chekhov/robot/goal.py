"""A planning goal: an end-effector pose with tolerances, or a joint configuration."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chekhov.errors import RobotError

Array = NDArray[np.float64]
_EYE = np.eye(3)


@dataclass(frozen=True, eq=False)
class Goal:
    """Where the arm must end.

    Exactly one of ``T_world_ee`` (4, 4), the end-effector frame's pose in the world, or ``q``
    (K,), a joint configuration in radians, is set. Build with :meth:`pose` or
    :meth:`configuration`.

    Attributes:
        position_tolerance: m, allowed end-effector position error (pose goals).
        orientation_tolerance: rad, allowed end-effector rotation error (pose goals).
        joint_tolerance: rad, allowed error of any joint (configuration goals).

    Every planner's answer is certified against these tolerances
    (:func:`chekhov.planners.certify.certify`): a path whose last configuration misses the
    goal is never reported as a success.
    """

    T_world_ee: Array | None = None
    q: Array | None = None
    position_tolerance: float = 0.005
    orientation_tolerance: float = 0.05
    joint_tolerance: float = 1e-6

    def __post_init__(self) -> None:
        if (self.T_world_ee is None) == (self.q is None):
            raise RobotError("goal: give exactly one of an end-effector pose or a configuration")
        if self.T_world_ee is not None:
            T = np.asarray(self.T_world_ee, dtype=float)
            if T.shape != (4, 4) or not np.all(np.isfinite(T)):
                raise RobotError(f"goal pose must be a finite 4x4 matrix, got shape {T.shape}")
            R = T[:3, :3]
            # np.allclose(R Rᵀ, I, atol=1e-6) without its machinery (40 µs, a pose goal is
            # made in every query): |R Rᵀ - I| ≤ 1e-6 + 1e-5 |I| entry by entry
            if not np.all(np.abs(R @ R.T - _EYE) <= 1e-6 + 1e-5 * _EYE):
                raise RobotError("goal pose: the rotation block is not orthonormal")
            object.__setattr__(self, "T_world_ee", T)
        if self.q is not None:
            q = np.asarray(self.q, dtype=float)
            if q.ndim != 1 or not np.all(np.isfinite(q)):
                raise RobotError(f"goal configuration must be a finite vector, got {q}")
            object.__setattr__(self, "q", q)
        for name in ("position_tolerance", "orientation_tolerance", "joint_tolerance"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) \
                    or not np.isfinite(value) or value < 0:
                raise RobotError(f"goal {name}: expected a finite number >= 0, got {value!r}")

    @classmethod
    def pose(cls, T_world_ee: Array, position_tolerance: float = 0.005,
             orientation_tolerance: float = 0.05) -> Goal:
        """A goal end-effector pose T_world_ee (4, 4)."""
        return cls(T_world_ee=T_world_ee, position_tolerance=position_tolerance,
                   orientation_tolerance=orientation_tolerance)

    @classmethod
    def configuration(cls, q: Array, joint_tolerance: float = 1e-6) -> Goal:
        """A goal joint configuration q (K,), rad, met when every joint is within
        ``joint_tolerance`` rad."""
        return cls(q=q, joint_tolerance=joint_tolerance)

    @property
    def is_pose(self) -> bool:
        return self.T_world_ee is not None
