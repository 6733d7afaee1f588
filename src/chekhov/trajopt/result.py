"""What the trajectory optimiser returns."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.path_check import PathCertificate
from chekhov.paths import path_length

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class TrajOptResult:
    """Outcome of :func:`chekhov.trajopt.solve_trajopt`.

    Attributes:
        trajectory: optimised waypoints (T, K), rad; the first row is the start.
        status: "converged", "iteration_limit", "exact_clear" (successes; the last: only the
            sphere model's clearance was short and the validation passed, see
            ``TrajOptConfig.accept_exact_clear``), "infeasible" (constraints still violated
            after the last penalty increase), "collision" (the validation found a collision:
            never returned as a success), "timeout" (the time limit passed before the
            validation decided) or "abandoned" (longer than the caller's answer so far, see
            ``solve_trajopt``'s ``abandon_above_rad``).
        success: status is one of the successes above (the validation, where on, passed).
        valid: result of the validation (None when validation is "none" or ran out of time).
        certificate: the validation's proof that this trajectory is exactly collision-free
            (:class:`~chekhov.collision.path_check.PathCertificate`), when it passed.
        costs: final values: "smoothness" (rad²), "merit".
        violations: final constraint violations: "collision_m" (largest hinge below
            min_clearance_m), "goal_position_m", "goal_orientation_rad", "velocity_rad",
            "acceleration_rad", "torque_nm" (0 when satisfied or absent).
        iterations: QP solves. penalty_increases: times μ was raised.
        timing_s: seconds in "collision" (distance terms), "linearise" (goal, torque, QP
            values), "qp" (OSQP), "validate", "other", and "total".
        seed: the seed trajectory (T, K).
        info: "cpu_s" (process CPU seconds of the optimisation, without the validation: the
            one-core cost, robust to other load on the machine), "penalty", "trust_rad",
            "qp_rebuilds", "admm_iterations" (OSQP's, over every QP of the run, rebuilt
            ones included).
    """

    trajectory: Array
    status: str
    success: bool
    valid: bool | None
    certificate: PathCertificate | None
    costs: dict[str, float]
    violations: dict[str, float]
    iterations: int
    penalty_increases: int
    timing_s: dict[str, float]
    seed: Array
    info: dict[str, object] = field(default_factory=dict)

    def unmet(self, tol: float = 1e-4) -> set[str]:
        """Names of the constraints the trajectory violates by more than tol (``violations``'
        keys)."""
        return {k for k, v in self.violations.items() if v > tol}

    @property
    def path_length(self) -> float:
        """Joint-space length of the trajectory (rad)."""
        return path_length(self.trajectory)

    @property
    def optimise_s(self) -> float:
        """Time spent optimising, without the validation (s)."""
        return self.timing_s["total"] - self.timing_s.get("validate", 0.0)
