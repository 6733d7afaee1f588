"""A reproducible RRT-Connect: seeded samples, a node budget instead of a clock.

:class:`DeterministicRRTConnect` answers a query the same way on every machine and every run: its
samples come from ``numpy.random.default_rng(config.seed)`` afresh for each query, its goal
configurations from the world's goal resolver (seeded), and its search
(:func:`chekhov.roadmap.trees.rrt_connect`) stops after ``config.max_nodes`` tree nodes — a
time limit, when finite, only cuts it short. It is what the solvability pass decides with
(:func:`chekhov.bench.solvability_pass`): whether a benchmark case is kept must not depend on
how fast the machine was that day. OMPL's RRTConnect stays the baseline to race against.

Like OMPL's planners here: the fast checker's state and motion tests (every ``resolution``
rad), OMPL's default step (0.2 × the joint space's diagonal), up to ``n_ik`` goal IK solutions
as goal roots, ends the fast checker rejects planned to through their exits; the answer is
certified by :meth:`PlannerBase.plan` like every planner's — with the proof its edges' checks
and its inner waypoints' cells make, so the final check decides nothing twice. A path found is
checked edge by edge first (:func:`~chekhov.collision.path_check.motion_certified`, what the
certification asks of each segment) and an edge refused there is cut from its tree and the
search goes on: a fast-free motion at 0.02 rad steps can still touch between them (measured:
3 of 100 shelf_boxes task cases' first paths did, and OMPL's RRTConnect answers "collision"
on such a path).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chekhov._config_checks import in_unit_interval, int_at_least, positive
from chekhov.collision.path_check import PathCertificate, motion_certified
from chekhov.collision.route_check import route_decision
from chekhov.planners.base import PlannerBase, PlanResult, search_deadline, solve_goal_ik
from chekhov.planners.query import PlanQuery
from chekhov.planners.status import PlanStatus
from chekhov.roadmap.trees import fast_motion, rrt_connect
from chekhov.world import World

Array = NDArray[np.float64]


@dataclass(frozen=True)
class DeterministicRRTConnectConfig:
    """Settings of :class:`DeterministicRRTConnect`.

    Attributes:
        max_nodes: tree nodes (both trees) after which the query fails ("no_path").
            Measured on 100 task cases each, the most a solved one needed: shelf_boxes 2118,
            kitchen 3693; exhausting 20 000 took 15 s in the kitchen (the nearest-node
            search is brute force).
        range_fraction: longest step, fraction of the joint space's diagonal (OMPL's 0.2).
        resolution: rad, joint-space step of motion checks.
        n_ik: goal IK solutions the goal tree grows from (a pose goal's).
        seed: seed of the samples (a fresh generator per query: same query, same answer).
    """

    max_nodes: int = 10_000
    range_fraction: float = 0.2
    resolution: float = 0.02
    n_ik: int = 4
    seed: int = 0

    def __post_init__(self) -> None:
        owner = type(self).__name__
        int_at_least(owner, "max_nodes", self.max_nodes, 1)
        int_at_least(owner, "n_ik", self.n_ik, 1)
        in_unit_interval(owner, "range_fraction", self.range_fraction)
        positive(owner, "resolution", self.resolution)


class DeterministicRRTConnect(PlannerBase):
    """RRT-Connect whose answer is a function of the query and the config (module docstring)."""

    fast_free_ends = True

    def __init__(self, world: World, config: DeterministicRRTConnectConfig | None = None) -> None:
        self.world = world
        self.config = config if config is not None else DeterministicRRTConnectConfig()
        self.name = "RRTConnect(deterministic)"
        robot = world.robot
        self.step = self.config.range_fraction * float(np.linalg.norm(robot.upper - robot.lower))
        self._free = fast_motion(world.fast, self.config.resolution)
        world.goal_ik.warmup()

    def _plan(self, query: PlanQuery) -> PlanResult:
        cfg, robot = self.config, self.world.robot
        timing: dict[str, float] = {}
        info: dict[str, object] = {"max_nodes": cfg.max_nodes}

        def done(status: PlanStatus, path: Array | None = None,
                 certificate: PathCertificate | None = None) -> PlanResult:
            return PlanResult(path is not None, path, status, time.perf_counter() - query.t0,
                              timing, info=info, certificate=certificate)

        goals = solve_goal_ik(self.world, query, cfg.n_ik, timing, info)
        if goals is None:
            return done(PlanStatus.TIMEOUT if query.expired() else PlanStatus.NO_IK)
        rng = np.random.default_rng(cfg.seed)
        t = time.perf_counter()
        deadline = search_deadline(query, t)    # as OMPL's planners here
        w = self.world

        def certified(q0: Array, q1: Array) -> bool:
            return motion_certified(w.fast, w.exact, q0, q1, deadline)

        found = rrt_connect(query.q_start, goals, self._free,
                            lambda: robot.sample_uniform(rng, 1)[0], step=self.step,
                            max_nodes=cfg.max_nodes, deadline=deadline, certify=certified)
        timing["search"] = time.perf_counter() - t
        info["tree_nodes"] = found.n_nodes
        if found.status == "timeout":
            return done(PlanStatus.TIMEOUT)
        if found.path is None:
            info["error"] = f"no path within {cfg.max_nodes} tree nodes"
            return done(PlanStatus.NO_PATH)
        return done(PlanStatus.SOLVED, found.path, self._certificate(found.path, deadline))

    def _certificate(self, path: Array, deadline: float) -> PathCertificate | None:
        """The certification's proof for ``path`` (T, K), whose every edge passed
        ``motion_certified``: only the cells at its inner waypoints are left to decide
        (:func:`~chekhov.collision.route_check.route_decision`); None when one is not (the
        certification then decides the whole path, and refuses it)."""
        if len(path) < 2:
            return None
        w = self.world
        known = np.ones(len(path) - 1, dtype=bool)
        return route_decision(w.fast, w.exact, path, known, deadline).certificate
