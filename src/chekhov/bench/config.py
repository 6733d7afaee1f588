"""Settings of a benchmark run (``chekhov bench``)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from chekhov.errors import ChekhovError
from chekhov.roadmap.config import RoadmapConfig

DEFAULT_TIME_LIMIT_S = 2.0
EXECUTORS = ("local", "ray")


@dataclass(frozen=True)
class BenchConfig:
    """What to run and how.

    Attributes:
        scenes: built-in scene names (or scene YAML files).
        planners: registry names (:data:`chekhov.bench.registry.PLANNER_NAMES`).
        n_cases: cases per scene: the first ``n_cases`` of
            ``cached_solvable_cases(world, n, case_seed)`` or of the case file given for the scene.
        time_limit_s: s, limit of every ``plan`` call (the paper: 300 s; RRT* and PRM* run to
            it). Stated in every report.
        case_seed: seed of the generated cases.
        case_files: (scene name, case file) pairs (``chekhov cases generate``, e.g. after the
            solvability pass), at most one per scene and case family (the file's own);
            scenes and families without one use generated cases.
        families: case families to run, each scene on each ("random": the paper's uniform
            cases, the default; "tasks": pre-grasp to pre-grasp or place; see
            :mod:`chekhov.cases`). Each (scene, family) is its own experiment.
        resolution: rad, joint-space step of every motion check (OMPL planners, LazyPRM).
        roadmap_config: roadmap of Roadmap+TrajOpt (default ``RoadmapConfig()``), loaded from or
            built into ``roadmap_dir`` (default: the roadmap cache).
        exact_substeps: configurations interpolated per segment in the runner's exact check
            (the paper: 100).
        workers: processes (local) or actors (Ray); None: ``os.cpu_count()`` (local) or the
            cluster's CPUs (Ray). 1 runs in this process.
        executor: "local" (multiprocessing) or "ray".
        address: Ray cluster address (``ray.init(address=...)``); None starts a local Ray.
        planner_seed: base of the per-run seeds (one per case, the same wherever it runs).
        warm_up: each worker plans once, untimed, before its first timed run of a planner.
        share_seed_runs: when both X and X+TrajOpt run on a case, X's run is the seed stage of
            X+TrajOpt's run (same planner, same seed, same limit), recorded under both names:
            halves the cost of RRT* and PRM*, which run to the limit.
        db_lock_timeout_s: s, how long a database locked by another program is waited for
            (retried with backoff) before the benchmark stops with a ``BenchError``; runs
            written before are kept.
    """

    scenes: tuple[str, ...]
    planners: tuple[str, ...]
    n_cases: int = 20
    time_limit_s: float = DEFAULT_TIME_LIMIT_S
    case_seed: int = 0
    case_files: tuple[tuple[str, str], ...] = ()
    resolution: float = 0.02
    roadmap_config: RoadmapConfig = field(default_factory=RoadmapConfig)
    roadmap_dir: str | None = None
    exact_substeps: int = 100
    workers: int | None = None
    executor: str = "local"
    address: str | None = None
    planner_seed: int = 0
    warm_up: bool = True
    share_seed_runs: bool = True
    db_lock_timeout_s: float = 120.0
    families: tuple[str, ...] = ("random",)

    def __post_init__(self) -> None:
        from chekhov.bench.registry import PLANNER_NAMES, canonical_planner_name
        from chekhov.cases import FAMILIES

        if not self.families or len(set(self.families)) != len(self.families) \
                or not set(self.families) <= set(FAMILIES):
            raise ChekhovError(f"bench: families must be distinct names of {list(FAMILIES)}, "
                               f"got {list(self.families)}")

        if not self.scenes:
            raise ChekhovError("bench: no scenes given")
        if not self.planners:
            raise ChekhovError("bench: no planners given")
        names = tuple(canonical_planner_name(p) for p in self.planners)
        if len(set(names)) != len(names):
            raise ChekhovError(f"bench: a planner is listed twice in {list(self.planners)}")
        object.__setattr__(self, "planners", names)
        assert set(names) <= set(PLANNER_NAMES)
        if len(set(self.scenes)) != len(self.scenes):
            raise ChekhovError(f"bench: a scene is listed twice in {list(self.scenes)}")
        if self.n_cases < 1:
            raise ChekhovError(f"bench: --cases must be at least 1, got {self.n_cases}")
        if not self.time_limit_s > 0:
            raise ChekhovError(f"bench: --time-limit must be positive (s), got "
                               f"{self.time_limit_s}")
        if not self.resolution > 0:
            raise ChekhovError(f"bench: resolution must be positive (rad), got "
                               f"{self.resolution}")
        if self.exact_substeps < 1:
            raise ChekhovError(f"bench: exact_substeps must be at least 1, got "
                               f"{self.exact_substeps}")
        if self.workers is not None and self.workers < 1:
            raise ChekhovError(f"bench: --workers must be at least 1, got {self.workers}")
        if self.executor not in EXECUTORS:
            raise ChekhovError(f"bench: unknown executor '{self.executor}'; choose one of "
                               f"{list(EXECUTORS)}")
        if not (isinstance(self.db_lock_timeout_s, int | float) and self.db_lock_timeout_s > 0):
            raise ChekhovError(f"bench: db_lock_timeout_s must be positive (s), got "
                               f"{self.db_lock_timeout_s!r}")
        if self.address is not None and self.executor != "ray":
            raise ChekhovError("bench: --address needs --executor ray")
        for scene, path in self.case_files:
            if not Path(path).is_file():
                raise ChekhovError(f"bench: case file for scene '{scene}' not found: {path}")

    @property
    def local_workers(self) -> int:
        """Worker processes of the local executor (default: the CPU count)."""
        return self.workers if self.workers is not None else max(1, os.cpu_count() or 1)

    def case_files_of(self, scene: str) -> list[str]:
        """The case files given for ``scene`` (one per family at most)."""
        return [path for s, path in self.case_files if s == scene]
