"""Evaluation: saved test cases (start configuration + goal pose), the benchmark runner, its
results database and the report.

    from chekhov.bench import generate_cases, CaseSet, solvability_pass
    from chekhov.bench import BenchConfig, run_benchmark, BenchDatabase, write_report

The runner, database and report are imported on first use (they pull in every planner).
"""

from typing import Any

from chekhov.bench.solvability import SolvabilityReport, solvability_pass
from chekhov.cases import (
    CASE_FORMAT,
    CASE_FORMAT_VERSION,
    CaseSet,
    cached_cases,
    default_cache_dir,
    generate_cases,
    sample_free,
)

_LAZY = {"BenchConfig": "chekhov.bench.config", "run_benchmark": "chekhov.bench.runner",
         "BenchOutcome": "chekhov.bench.runner", "BenchDatabase": "chekhov.bench.database",
         "write_report": "chekhov.bench.report", "PLANNER_NAMES": "chekhov.bench.registry",
         "RunRecord": "chekhov.bench.record", "RunTask": "chekhov.bench.task"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'chekhov.bench' has no attribute '{name}'")


__all__ = [
    "CASE_FORMAT",
    "CASE_FORMAT_VERSION",
    "PLANNER_NAMES",
    "BenchConfig",
    "BenchDatabase",
    "BenchOutcome",
    "CaseSet",
    "RunRecord",
    "RunTask",
    "SolvabilityReport",
    "cached_cases",
    "default_cache_dir",
    "generate_cases",
    "run_benchmark",
    "sample_free",
    "solvability_pass",
    "write_report",
]
