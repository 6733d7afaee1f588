"""Planners by name, built per world: the one place the benchmark, the viewer, the CLI and
``benchmarks/`` allocate planners (as OMPL's planner allocators do).

========================  ==================================================================
name                      planner
========================  ==================================================================
``Roadmap+TrajOpt``       :class:`~chekhov.planners.roadmap_trajopt.RoadmapTrajOpt` on the
                          scene's roadmap (``load_or_build_roadmap``): ours, with a 40 ms
                          straight-line TrajOpt try before the roadmap seed
``Roadmap+TrajOpt(paper)`` the same with ``straight_line_first=False`` and the paper's
                          0.16 rad seed spacing: the paper's planner, every query seeded
                          from the roadmap
``TrajOpt``               :class:`~chekhov.planners.trajopt_planner.TrajOptPlanner`, straight-
                          line seed, T = 30
``RRTConnect``            OMPL RRTConnect (the bidirectional RRT that OpenRAVE's BasicRRT is,
                          the paper's "RRT")
``RRT``, ``RRT*``,        OMPL RRT, RRT*, PRM* (RRT* and PRM* optimise path length and run to
``PRM*``                  the time limit)
``LazyPRM``               :class:`~chekhov.planners.lazy_prm.LazyPRM` (Bohlin & Kavraki)
``X+TrajOpt``             :class:`~chekhov.planners.trajopt_planner.SeededTrajOpt`: X's path,
                          resampled to ≤ 0.16 rad, as TrajOpt's seed (the paper's Table II)
========================  ==================================================================

And ``RRTConnect(deterministic)``:
:class:`~chekhov.planners.rrt_connect.DeterministicRRTConnect`, RRT-Connect with seeded samples
and a node budget (the same answer on every machine), what the solvability pass decides with.

All use the world's fast checker at the same motion resolution (default 0.02 rad); OMPL's
own defaults otherwise.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from chekhov.errors import ChekhovError
from chekhov.planners.base import Planner
from chekhov.roadmap.graph import Roadmap
from chekhov.world import World

BASE_PLANNERS = ("Roadmap+TrajOpt", "Roadmap+TrajOpt(paper)", "TrajOpt", "RRTConnect", "RRT",
                 "RRT*", "PRM*", "LazyPRM")
SEEDS = ("RRTConnect", "RRT", "RRT*", "PRM*", "LazyPRM")
PLANNER_NAMES: tuple[str, ...] = ("Roadmap+TrajOpt", "Roadmap+TrajOpt(paper)", "TrajOpt",
                                  "RRTConnect",
                                  "RRTConnect+TrajOpt", "RRT", "RRT+TrajOpt", "RRT*",
                                  "RRT*+TrajOpt", "PRM*", "PRM*+TrajOpt", "LazyPRM",
                                  "LazyPRM+TrajOpt", "RRTConnect(deterministic)")
_OMPL_KIND = {"RRTConnect": "RRTConnect", "RRT": "RRT", "RRT*": "RRTstar", "PRM*": "PRMstar"}
_ALIASES = {n.lower(): n for n in PLANNER_NAMES}
_ALIASES.update({"rrtstar": "RRT*", "prmstar": "PRM*", "rrtstar+trajopt": "RRT*+TrajOpt",
                 "prmstar+trajopt": "PRM*+TrajOpt", "roadmap": "Roadmap+TrajOpt",
                 "roadmap-paper": "Roadmap+TrajOpt(paper)",
                 "trajopt-straight": "TrajOpt"})
# Named groups accepted by --planners.
GROUPS = {"all": PLANNER_NAMES,
          "paper": ("Roadmap+TrajOpt", "Roadmap+TrajOpt(paper)", "TrajOpt", "RRTConnect",
                    "RRTConnect+TrajOpt",
                    "LazyPRM", "LazyPRM+TrajOpt", "RRT*", "RRT*+TrajOpt", "PRM*",
                    "PRM*+TrajOpt"),
          "fast": ("Roadmap+TrajOpt", "TrajOpt", "RRTConnect", "RRTConnect+TrajOpt")}


def canonical_planner_name(name: str) -> str:
    """The registry name of ``name`` (case-insensitive; "RRTstar" for "RRT*" accepted)."""
    n = _ALIASES.get(name.strip().lower())
    if n is None:
        raise ChekhovError(f"unknown planner '{name}'; available: {', '.join(PLANNER_NAMES)} "
                           f"(groups: {', '.join(GROUPS)})")
    return n


def expand_planner_names(names: list[str] | tuple[str, ...]) -> tuple[str, ...]:
    """Registry names of ``names`` with groups ("all", "paper", "fast") expanded, in order,
    without repeats."""
    out: list[str] = []
    for name in names:
        group = GROUPS.get(name.strip().lower())
        for n in group if group is not None else (canonical_planner_name(name),):
            if n not in out:
                out.append(n)
    return tuple(out)


def seed_planner_name(name: str) -> str | None:
    """For "X+TrajOpt" (X a sampling-based planner) X; otherwise None."""
    base, plus, rest = name.partition("+")
    return base if plus and rest == "TrajOpt" and base in SEEDS else None


def is_optimal(name: str) -> bool:
    """RRT* and PRM* (and their +TrajOpt) optimise path length and run to the time limit."""
    return name.split("+")[0] in ("RRT*", "PRM*")


@dataclass(frozen=True)
class PlannerSpec:
    """A registry entry.

    Attributes:
        name: registry name.
        resolution: rad, motion-check step of OMPL planners and LazyPRM.
        seed: seeds the planner's own random streams (reseeded per run by the worker).
    """

    name: str
    resolution: float = 0.02
    seed: int = 0

    def build(self, world: World, roadmap: Callable[[], Roadmap]) -> Planner:
        """The planner for ``world``; ``roadmap()`` is called only for Roadmap+TrajOpt."""
        from chekhov.planners.trajopt_planner import SeededTrajOpt, TrajOptPlanner

        name = canonical_planner_name(self.name)
        if name in ("Roadmap+TrajOpt", "Roadmap+TrajOpt(paper)"):
            from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
            from chekhov.planners.roadmap_trajopt_config import RoadmapTrajOptConfig
            from chekhov.trajopt.config import TrajOptConfig
            config = RoadmapTrajOptConfig(straight_line_first=True) if \
                name == "Roadmap+TrajOpt" else \
                RoadmapTrajOptConfig(straight_line_first=False, trajopt=TrajOptConfig())
            return RoadmapTrajOpt(world, roadmap(), config, name=name)
        if name == "TrajOpt":
            return TrajOptPlanner(world, name=name)
        base = seed_planner_name(name)
        if base is not None:
            p = SeededTrajOpt(world, self._sampling(world, base))
            p.name = name
            return p
        return self._sampling(world, name)

    def _sampling(self, world: World, name: str) -> Planner:
        if name == "RRTConnect(deterministic)":
            from chekhov.planners.rrt_connect import (
                DeterministicRRTConnect,
                DeterministicRRTConnectConfig,
            )
            config = DeterministicRRTConnectConfig(resolution=self.resolution, seed=self.seed)
            return DeterministicRRTConnect(world, config)
        if name == "LazyPRM":
            from chekhov.planners.lazy_prm import LazyPRM, LazyPRMConfig
            return LazyPRM(world, LazyPRMConfig(resolution=self.resolution), seed=self.seed)
        from chekhov.planners.ompl_planner import OmplPlanner
        p = OmplPlanner(world, _OMPL_KIND[name], resolution=self.resolution, seed=self.seed)
        p.name = name
        return p


def make_planner(name: str, world: World, roadmap: Callable[[], Roadmap] | Roadmap | None = None,
                 *, resolution: float = 0.02, seed: int = 0) -> Planner:
    """The planner ``name`` (a registry name or alias) for ``world``; ``roadmap`` (a roadmap,
    or a function that loads one) is needed only by Roadmap+TrajOpt."""
    def get_roadmap() -> Roadmap:
        if roadmap is None:
            raise ChekhovError(f"{canonical_planner_name(name)} needs a roadmap")
        return roadmap() if callable(roadmap) else roadmap
    return PlannerSpec(name, resolution, seed).build(world, get_roadmap)
