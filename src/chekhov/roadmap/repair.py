"""Repair when the roadmap cannot answer: a bidirectional tree that connects into the roadmap.

When dynamic obstacles cut every stored route, or the start or goal cannot be joined to the
roadmap, the query is not given up. Two trees grow in the current world — one from the start,
one from every goal configuration — by RRT-Connect (:mod:`chekhov.roadmap.trees`; Kuffner &
LaValle 2000: extend one tree towards a uniform sample, then pull the other straight towards
the new node, swap; steps of at most ``range_fraction`` of the joint space's diagonal, OMPL's
default range). Every new node of an extend step also tries a straight motion to its nearest
roadmap nodes that are still valid; once both trees touch the roadmap, the roadmap is searched
between the touched nodes (cached shortest path, stored k shortest, then lazy A* on what the
obstacles left). Whichever closes first — the trees meeting, or a route through the roadmap —
gives the path. The search stops only at its deadline (or after ``max_nodes`` tree nodes), so
wherever RRT-Connect finds a path in time, this does too, usually sooner: the roadmap carries
the long way round.

Motions are checked by the fast checker at the roadmap's resolution; the caller certifies the
final path exactly, as for every planner.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from chekhov.roadmap.config import RepairConfig
from chekhov.roadmap.graph import Roadmap
from chekhov.roadmap.nearest import NearestNodes
from chekhov.roadmap.trees import BiTrees, fast_motion
from chekhov.roadmap.validity import RoadmapValidity
from chekhov.world import World

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]
RouteFn = Callable[[int, int, float], "IntArray | None"]
"""(node s, node g, deadline) → roadmap nodes s … g free of the current obstacles, or None."""


@dataclass(frozen=True, eq=False)
class RepairResult:
    """What :meth:`TreeRepair.search` found.

    Attributes:
        path: (T, K) rad from the start to one of the goal configurations, fast-free at the
            roadmap's resolution; None when none was found.
        status: "solved", "timeout" (the deadline came first) or "exhausted" (``max_nodes``).
        q_goal: (K,) the goal configuration reached. time_s: s.
        info: "tree_nodes" (both trees), "via" ("trees" or "roadmap"), "route_tries".
    """

    path: Array | None
    status: str
    q_goal: Array | None
    time_s: float
    info: dict[str, object] = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.path is not None


class TreeRepair:
    """Bidirectional tree search into one roadmap, in the world's current obstacles (module
    docstring). ``route`` searches the roadmap between two nodes (the seeder's)."""

    def __init__(self, world: World, roadmap: Roadmap, validity: RoadmapValidity,
                 route: RouteFn, resolution: float, config: RepairConfig | None = None) -> None:
        self.world = world
        self.roadmap = roadmap
        self.validity = validity
        self.route = route
        self.resolution = resolution
        self.config = config if config is not None else RepairConfig()
        robot = world.robot
        self.step = self.config.range_fraction * float(np.linalg.norm(robot.upper - robot.lower))
        self.free = fast_motion(world.fast, resolution)
        self._nodes = NearestNodes(roadmap.nodes)

    def search(self, q_start: Array, Q_goal: Array, deadline: float) -> RepairResult:
        """A path q_start (K,) → one row of Q_goal (n, K) (both known free) before
        ``deadline`` (a ``time.perf_counter()`` value, s)."""
        t0 = time.perf_counter()
        run = _Search(self, q_start, Q_goal)
        path, status = run.go(deadline)
        q_goal = None if path is None else path[-1]
        return RepairResult(path, status, q_goal, time.perf_counter() - t0,
                            {"tree_nodes": run.trees[0].n + run.trees[1].n, "via": run.via,
                             "route_tries": len(run.tried)})

    # --- motions ------------------------------------------------------------------------
    def attachments(self, q: Array) -> list[int]:
        """Roadmap nodes, valid now, with a free straight motion from q (nearest first)."""
        k = min(self.config.attach_candidates, self.roadmap.n_nodes)
        if k == 0:
            return []
        _, idx = self._nodes.query(q, k)
        idx = np.atleast_1d(idx)
        idx = idx[self.validity.nodes_valid(idx)]
        if len(idx) == 0:
            return []
        ok = self.world.fast.motions_valid(np.repeat(q[None], len(idx), axis=0),
                                           self.roadmap.nodes[idx], self.resolution)
        return [int(i) for i in idx[ok]]


class _Search:
    """One search's state: the two trees (0: start, 1: goals), their roadmap attachments
    (roadmap node → tree node) and the roadmap pairs tried."""

    def __init__(self, repair: TreeRepair, q_start: Array, Q_goal: Array) -> None:
        self.r = repair
        self.bi = BiTrees(q_start, Q_goal, repair.free, repair.step)
        self.trees = self.bi.trees
        self.attached: tuple[dict[int, int], dict[int, int]] = ({}, {})
        self.tried: set[tuple[int, int]] = set()
        self.rng = np.random.default_rng(repair.config.seed)
        self.via = ""

    def go(self, deadline: float) -> tuple[Array | None, str]:
        robot, cfg = self.r.world.robot, self.r.config
        for side in (0, 1):
            for i in range(self.trees[side].n):
                path = self._attach(side, i, deadline)
                if path is not None:
                    return path, "solved"
        a = extended = 0
        while time.perf_counter() < deadline:
            if self.trees[0].n + self.trees[1].n >= cfg.max_nodes:
                return None, "exhausted"
            i_new = self.bi.extend(a, robot.sample_uniform(self.rng, 1)[0])
            if i_new is not None:
                extended += 1
                path = (self._attach(a, i_new, deadline)
                        if extended % cfg.attach_every == 0 else None)
                if path is None:
                    j = self.bi.connect(1 - a, self.trees[a].X[i_new], deadline)
                    if j is not None:
                        self.via = "trees"
                        path = self.bi.join(a, i_new, j)
                if path is not None:
                    return path, "solved"
            a = 1 - a
        return None, "timeout"

    def _attach(self, side: int, i: int, deadline: float) -> Array | None:
        """Record tree ``side``'s node i's roadmap attachments; a path when one of them
        routes through the roadmap to the other tree."""
        tree, other = self.trees[side], self.attached[1 - side]
        dist = self.r.roadmap.dist
        for m in self.r.attachments(tree.X[i]):
            if m in self.attached[side]:
                continue
            self.attached[side][m] = i
            if not other:
                continue
            cand = np.fromiter(other.keys(), dtype=np.int64)
            cost = dist[m, cand] if side == 0 else dist[cand, m]
            for g in cand[np.argsort(cost)[: self.r.config.route_pairs]]:
                s, e = (m, int(g)) if side == 0 else (int(g), m)
                if (s, e) in self.tried or not np.isfinite(dist[s, e]) \
                        or time.perf_counter() >= deadline:
                    continue
                self.tried.add((s, e))
                nodes = self.r.route(s, e, deadline)
                if nodes is not None:
                    self.via = "roadmap"
                    return np.vstack([self.trees[0].branch(self.attached[0][s]),
                                      self.r.roadmap.nodes[nodes],
                                      self.trees[1].branch(self.attached[1][e])[::-1]])
        return None
