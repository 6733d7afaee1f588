"""The outcome of one benchmark run, as measured by the runner."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

# Planner statuses that mean "the TrajOpt stage ran and its trajectory was rejected".
TRAJOPT_FAILED = frozenset({"collision", "infeasible"})
# Statuses of a run that could not be run (the worker caught an exception): its info names the
# stage ("goal", "plan", "check") and the error.
RUN_ERRORS = frozenset({"case_error", "crash"})


@dataclass(frozen=True, eq=False)
class RunRecord:
    """One planner on one case.

    Attributes:
        scene, planner, case_index, case_hash: which run (see :class:`RunTask`).
        solved: the planner returned a path (its own checks passed).
        status: the planner's status (a PlanStatus value: "solved", "timeout", "no_ik", ...;
            "crash" when ``plan`` raised).
        time_s: s, the planner's ``PlanResult.time_s`` (IK, seeding, optimisation, its own
            validation).
        timing_s: s, the planner's breakdown of ``time_s``.
        path: (T, K) rad, the returned path; None when not solved.
        path_length: rad, joint-space length of ``path`` (nan without one).
        exact_valid: the runner's exact check of ``path`` (``ExactChecker.path_valid`` at
            ``exact_substeps`` per segment, independent of the planner); None without a path.
        exact_check_s: s, time of that check (not part of ``time_s``).
        seed_path: (T', K) rad, the seed TrajOpt started from: for Roadmap+TrajOpt the roadmap's
            own path (``info["roadmap_seed"]``, before shortcutting), for X+TrajOpt X's path;
            None for planners without a seed stage or when the seed stage failed.
        seed_length: rad, joint-space length of ``seed_path`` (nan without one).
        seed_time_s: s, time of the seed stage (``timing_s["seed"]``); nan without one.
        seed_found: the seed stage produced a path; None for planners without one.
        trajopt_status: TrajOpt's own status ("converged", "iteration_limit", "exact_clear",
            "infeasible", "collision", "timeout", or "abandoned": stopped as longer than the
            answer so far, not a rejection); None when TrajOpt did not run.
        fallback_to_seed: the planner returned its (exactly checked) seed, TrajOpt's
            trajectory rejected (Roadmap+TrajOpt); None when no TrajOpt stage ran
            (:func:`chekhov.bench.worker.fell_back_to_seed`).
        seed_stage_of: for a seed planner X's run recorded from X+TrajOpt's seed stage, that
            planner's name (its planning time is counted once); None otherwise.
        info: scalar extras of ``PlanResult.info`` (iterations, counts, error text).
        worker: "host:pid" of the process that ran it.
        family: the case family ("random" or "tasks").
    """

    scene: str
    planner: str
    case_index: int
    case_hash: str
    solved: bool
    status: str
    time_s: float
    timing_s: dict[str, float] = field(default_factory=dict)
    path: Array | None = None
    path_length: float = float("nan")
    exact_valid: bool | None = None
    exact_check_s: float = 0.0
    seed_path: Array | None = None
    seed_length: float = float("nan")
    seed_time_s: float = float("nan")
    seed_found: bool | None = None
    trajopt_status: str | None = None
    fallback_to_seed: bool | None = None
    info: dict[str, object] = field(default_factory=dict)
    worker: str = ""
    seed_stage_of: str | None = None
    family: str = "random"

    @property
    def key(self) -> tuple[str, str, str, int]:
        return (self.scene, self.family, self.planner, self.case_index)

    @property
    def success(self) -> bool:
        """The paper's success: a path was returned and the exact check finds it free."""
        return self.solved and self.exact_valid is True

    @property
    def failure_kind(self) -> str:
        """"none" on success; "exact_collision" when the returned path fails the exact check;
        otherwise the planner's status."""
        if self.success:
            return "none"
        if self.solved:
            return "exact_collision"
        return self.status

    @property
    def trajopt_time_s(self) -> float:
        """s, time after the seed stage (shortcut, TrajOpt, its validation) for planners with a
        TrajOpt stage that ran; nan otherwise."""
        if self.trajopt_status is None or not np.isfinite(self.seed_time_s):
            return float("nan")
        return max(self.time_s - self.seed_time_s, 0.0)

    @property
    def trajopt_ok(self) -> bool | None:
        """TrajOpt's trajectory was accepted (None when TrajOpt did not run)."""
        if self.trajopt_status is None:
            return None
        return self.trajopt_status not in TRAJOPT_FAILED
