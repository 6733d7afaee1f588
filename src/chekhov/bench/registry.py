"""How each registry planner (:mod:`chekhov.planners.registry`) is configured, for the
benchmark database's plannerConfigs and the report; the registry's names re-exported."""

from __future__ import annotations

import json
from dataclasses import asdict
from typing import Any

from chekhov.planners.base import Planner
from chekhov.planners.registry import (
    BASE_PLANNERS,
    GROUPS,
    PLANNER_NAMES,
    SEEDS,
    PlannerSpec,
    canonical_planner_name,
    expand_planner_names,
    is_optimal,
    make_planner,
    seed_planner_name,
)
from chekhov.roadmap.graph import Roadmap

__all__ = ["BASE_PLANNERS", "GROUPS", "PLANNER_NAMES", "SEEDS", "PlannerSpec",
           "canonical_planner_name", "expand_planner_names", "is_optimal", "make_planner",
           "planner_settings", "seed_planner_name", "settings_text", "uses_roadmap"]

ROADMAP_PLANNERS = ("Roadmap+TrajOpt", "Roadmap+TrajOpt(paper)")


def uses_roadmap(name: str) -> bool:
    """Whether the registry planner ``name`` (or alias) plans on the scene's roadmap (the
    only planners whose ``make_planner`` calls its ``roadmap`` argument)."""
    return canonical_planner_name(name) in ROADMAP_PLANNERS


def planner_settings(spec: PlannerSpec, planner: Planner, roadmap: Roadmap | None = None
                     ) -> dict[str, Any]:
    """How ``planner`` (built by ``spec.build``) is configured, for plannerConfigs.settings
    and the report. Deterministic for the same code and options."""
    from chekhov.planners.lazy_prm import LazyPRM
    from chekhov.planners.ompl_planner import OmplPlanner
    from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
    from chekhov.planners.rrt_connect import DeterministicRRTConnect
    from chekhov.planners.trajopt_planner import SeededTrajOpt, TrajOptPlanner

    d: dict[str, Any] = {"name": spec.name, "optimal_runs_to_limit": is_optimal(spec.name)}
    p: Any = planner
    if isinstance(p, SeededTrajOpt):
        d["seed_planner"] = _sampling_settings(p.seed_planner)
        d["trajopt"] = _trajopt_settings(p.config)
        d["seed_resampled_to_rad"] = p.config.max_step_rad
    elif isinstance(p, TrajOptPlanner):
        d["seed"] = f"straight line, T = {p.config.n_waypoints}"
        d["trajopt"] = _trajopt_settings(p.config)
    elif isinstance(p, RoadmapTrajOpt):
        d["roadmap"] = p.roadmap.meta.config.to_dict()
        d["roadmap_nodes"] = len(p.roadmap.nodes)
        d["roadmap_edges"] = len(p.roadmap.edges)
        c = p.config    # the same keys as before the config object, so resumed runs match
        d["shortcut"] = c.shortcut
        d["straight_line_first"] = c.straight_line_first
        d["straight_line_time_s"] = c.straight_line_time_s
        d["straight_line_fallback"] = c.straight_line_fallback
        d["goal_routes"] = c.goal_routes
        d.update({k: getattr(c, k) for k in (
            "repair", "repair_reserve", "straight_line_ratio", "straight_line_max_blocked",
            "improve_time_s", "simplify_rounds")})
        d["seeder"] = asdict(p.seeder.config) if hasattr(p.seeder, "config") else {}
        d["trajopt"] = _trajopt_settings(c.trajopt)
    elif isinstance(p, OmplPlanner | LazyPRM | DeterministicRRTConnect):
        d.update(_sampling_settings(p))
    return json.loads(json.dumps(d, default=str))


def _sampling_settings(p: Any) -> dict[str, Any]:
    from chekhov.planners.lazy_prm import LazyPRM
    from chekhov.planners.ompl_planner import OmplPlanner
    from chekhov.planners.rrt_connect import DeterministicRRTConnect

    if isinstance(p, OmplPlanner):
        return {"library": "OMPL", **p.describe()}
    if isinstance(p, LazyPRM):
        return {"library": "chekhov", "planner": "LazyPRM", "max_edge": p.max_edge,
                **asdict(p.config)}
    if isinstance(p, DeterministicRRTConnect):
        return {"library": "chekhov", "planner": "RRTConnect(deterministic)", "step_rad": p.step,
                **asdict(p.config)}
    return {"planner": getattr(p, "name", type(p).__name__)}


def _trajopt_settings(config: Any) -> dict[str, Any]:
    keys = ("n_waypoints", "max_step_rad", "safety_margin_m", "check_distance_m", "continuous",
            "max_iterations", "validate", "substeps", "time_limit_s")
    return {k: getattr(config, k) for k in keys if hasattr(config, k)}


def settings_text(settings: dict[str, Any]) -> str:
    """plannerConfigs.settings: the settings as sorted one-line JSON."""
    return json.dumps(settings, sort_keys=True, separators=(",", ":"))
