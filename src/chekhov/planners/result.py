"""What every planner returns."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.path_check import PathCertificate
from chekhov.paths import path_length

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class PlanResult:
    """What a planner returns.

    Attributes:
        success: a path was found that the planner's own checks accept.
        path: waypoints (T, K), rad, first row the start; None on failure.
        status: short machine-readable reason, e.g. "solved", "timeout", "no_ik",
            "no_connection", "collision".
        time_s: wall time of ``plan`` (s).
        timing_s: breakdown of ``time_s`` by phase (s), e.g. {"ik": .., "seed": .., "optimise": ..}.
        seed: the seed path (T', K) an optimising planner started from, when there was one.
        info: anything else worth reporting (iterations, flags such as "fallback_to_seed").
        certificate: the exact path check's proof for ``path``, when the planner ran it
            (:class:`~chekhov.collision.path_check.PathCertificate`); the certification
            (:func:`chekhov.planners.certify.certify`) runs the check itself otherwise.
    """

    success: bool
    path: Array | None
    status: str
    time_s: float
    timing_s: dict[str, float] = field(default_factory=dict)
    seed: Array | None = None
    info: dict[str, object] = field(default_factory=dict)
    certificate: PathCertificate | None = None

    @property
    def path_length(self) -> float:
        """Joint-space length of the path (rad): sum of segment L2 norms; nan without a path."""
        return path_length(self.path) if self.path is not None else float("nan")
