"""Compatibility: the case sets moved to :mod:`chekhov.cases` (below the benchmark and the
viewer, which both read them); these names are re-exported from there."""

from chekhov.cases import (
    CASE_FORMAT,
    CASE_FORMAT_VERSION,
    CaseSet,
    cache_stem,
    cached_cases,
    case_rng,
    default_cache_dir,
    find_cached,
    generate_cases,
    sample_case,
    sample_free,
)

__all__ = ["CASE_FORMAT", "CASE_FORMAT_VERSION", "CaseSet", "cache_stem", "cached_cases",
           "case_rng", "default_cache_dir", "find_cached", "generate_cases", "sample_case",
           "sample_free"]
