"""Evaluation: saved test cases (start configuration + goal pose) and, later, the benchmark runner.

    from chekhov.bench import generate_cases, CaseSet, solvability_pass
"""

from chekhov.bench.cases import (
    CASE_FORMAT,
    CASE_FORMAT_VERSION,
    CaseSet,
    cached_cases,
    default_cache_dir,
    generate_cases,
    sample_free,
)
from chekhov.bench.solvability import SolvabilityReport, solvability_pass

__all__ = [
    "CASE_FORMAT",
    "CASE_FORMAT_VERSION",
    "CaseSet",
    "SolvabilityReport",
    "cached_cases",
    "default_cache_dir",
    "generate_cases",
    "sample_free",
    "solvability_pass",
]
