"""What every planner returns."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.path_check import PathCertificate
from chekhov.paths import path_length
from chekhov.planners.status import PlanStatus, Stage, StageReport
from chekhov.trajectory import JointTrajectory

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Solution:
    """One certified answer as a planner found it (anytime planners find several, each
    shorter than the one before).

    Attributes:
        path: (T, K) rad, certified (start, limits, goal, exact check at 100 substeps).
        time_s: s from the start of ``plan()`` to the moment it was certified.
        stage: the stage that produced it. length_rad: its joint-space length.
    """

    path: Array
    time_s: float
    stage: Stage
    length_rad: float


@dataclass(frozen=True, eq=False)
class PlanResult:
    """What a planner returns.

    Attributes:
        success: a path was found and certified (after ``PlannerBase.plan``).
        path: waypoints (T, K), rad, first row the start; None on failure.
        status: why the call ended (:class:`PlanStatus`; a string given is converted, an
            unknown one is a ValueError).
        time_s: wall time of ``plan`` up to its certified answer (s); the timing of the
            answer that follows (``trajectory``) is ``info["time_parameterize_s"]``.
        timing_s: breakdown of ``time_s`` by phase (s), e.g. {"ik": .., "seed": .., "optimise": ..}.
        seed: the seed path (T', K) an optimising planner started from, when there was one.
        info: anything else worth reporting (iterations, flags such as "fallback_to_seed").
        certificate: the exact path check's proof for ``path``, when the planner ran it
            (:class:`~chekhov.collision.path_check.PathCertificate`); the certification
            (:func:`chekhov.planners.certify.certify`) runs the check itself otherwise.
        stages: what each stage did, in order (:class:`StageReport`).
        seed_from: the stage whose path the final optimisation started from (its report in
            ``stages`` says whether it found one); None for planners without a seed.
        trajectory: ``path`` timed (:class:`~chekhov.trajectory.JointTrajectory`, certified
            like the path) when the planner's ``timing`` is set; None otherwise.
        solutions: every certified answer in the order found, the last being ``path`` (one
            for planners that answer once; :attr:`first_solution_s` is the first's time).
    """

    success: bool
    path: Array | None
    status: PlanStatus
    time_s: float
    timing_s: dict[str, float] = field(default_factory=dict)
    seed: Array | None = None
    info: dict[str, object] = field(default_factory=dict)
    certificate: PathCertificate | None = None
    stages: tuple[StageReport, ...] = ()
    seed_from: Stage | None = None
    trajectory: JointTrajectory | None = None
    solutions: tuple[Solution, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.status, PlanStatus):
            object.__setattr__(self, "status", PlanStatus.of(self.status))

    def stage(self, stage: Stage) -> StageReport | None:
        """The last report of ``stage``, or None when it did not run."""
        return next((r for r in reversed(self.stages) if r.stage == stage), None)

    @property
    def first_solution_s(self) -> float:
        """s from the start of ``plan()`` to the first certified answer; nan on failure."""
        if not self.success:
            return float("nan")
        return self.solutions[0].time_s if self.solutions else self.time_s

    @property
    def fell_back_to_seed(self) -> bool | None:
        """Whether the answer is the (shortcut) seed itself although TrajOpt ran from it —
        its trajectory rejected or no shorter; None when no TrajOpt stage ran."""
        if not any(r.stage in _TRAJOPT_STAGES for r in self.stages):
            return None
        return bool(self.success and self.solutions
                    and self.solutions[-1].stage in (Stage.ROADMAP_SEED, Stage.SHORTCUT,
                                                       Stage.ROUTES,
                                                       Stage.SIMPLIFY))

    @property
    def seed_report(self) -> StageReport | None:
        """The report of the stage the final optimisation's seed came from (``seed_from``)."""
        return self.stage(self.seed_from) if self.seed_from is not None else None

    @property
    def path_length(self) -> float:
        """Joint-space length of the path (rad): sum of segment L2 norms; nan without a path."""
        return path_length(self.path) if self.path is not None else float("nan")


_TRAJOPT_STAGES = frozenset({Stage.STRAIGHT_LINE, Stage.OPTIMISE, Stage.RETRY, Stage.FALLBACK})
