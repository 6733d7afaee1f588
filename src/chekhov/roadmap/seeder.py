"""Roadmap queries: start configuration + goal → a collision-free seed path through the roadmap,
against the world's current obstacles (dynamic ones included)."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from itertools import pairwise
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.exits import exact_exit
from chekhov.roadmap.build import distal_values
from chekhov.roadmap.config import SeederConfig
from chekhov.roadmap.connect import Connection, Connector
from chekhov.roadmap.errors import RoadmapMismatchError
from chekhov.roadmap.goals import RoadmapGoals
from chekhov.roadmap.graph import Roadmap, edges_certified
from chekhov.roadmap.kpaths import KShortestPaths
from chekhov.roadmap.memo import ObstacleMemo
from chekhov.roadmap.repair import RepairResult, TreeRepair
from chekhov.roadmap.search import astar, path_edges, warm_up
from chekhov.roadmap.validity import INVALID, RoadmapValidity
from chekhov.robot.goal import Goal
from chekhov.robot.goal_ik import GoalIKConfig
from chekhov.world import World

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

EXITS_KEPT = 16
"""Ends whose exits (:meth:`RoadmapSeeder._way_out`) are remembered, at most."""


@dataclass(frozen=True, eq=False)
class SeedResult:
    """A roadmap query's answer.

    Attributes:
        success: a seed path was found.
        status: "solved", "no_ik" (pose goal without a collision-free IK solution),
            "no_connection" (start or goal cannot be joined to the roadmap: the paper's
            roadmap failure), "no_path" (dynamic obstacles cut every roadmap route),
            "invalid_start" / "invalid_goal" (in collision or outside the limits).
        path: (T, K) rad: start, connection intermediates, roadmap nodes, goal; None on failure.
        node_path: roadmap node indices along the path.
        q_goal: (K,) the goal configuration used.
        timing_s: s, by phase: "ik", "connect", "search", "validate", "total".
        info: connection kinds ("direct", "wrist", "proximal", "random", "tree", "wide"),
            which stored path
            was used ("path_rank"; -1: lazy search), checks made.
    """

    success: bool
    status: str
    path: Array | None
    node_path: IntArray
    q_goal: Array | None
    timing_s: dict[str, float]
    info: dict[str, object] = field(default_factory=dict)

    @property
    def length_rad(self) -> float:
        """Joint-space length of the seed path (rad); nan without one."""
        if self.path is None:
            return float("nan")
        return float(np.linalg.norm(np.diff(self.path, axis=0), axis=1).sum())


class RoadmapSeeder:
    """Seed paths from a roadmap for one world. The roadmap must have been built for the world's
    scene (same content hash) and robot."""

    def __init__(self, world: World, roadmap: Roadmap, config: SeederConfig | None = None
                 ) -> None:
        meta = roadmap.meta
        if meta.robot != world.robot.name or meta.scene_hash != world.scene.content_hash():
            raise RoadmapMismatchError(
                f"roadmap for robot '{meta.robot}', scene '{meta.scene}' "
                f"({meta.scene_hash[:12]}) does not match the world: robot "
                f"'{world.robot.name}', scene '{world.scene.name}' "
                f"({world.scene.content_hash()[:12]})")
        self.world = world
        self.roadmap = roadmap
        self.config = config or SeederConfig()
        self.resolution = (self.config.resolution if self.config.resolution is not None
                           else roadmap.config.resolution)
        cfg = self.config
        self.validity = RoadmapValidity(roadmap, world.fast, self.resolution)
        # the nodes' stored end-effector poses are this robot's, and the edges passed this
        # code's certification of a segment for it
        same_robot = meta.robot_hash == world.robot.content_hash()
        self._edges_certified = edges_certified(roadmap.config, meta.notes) and same_robot
        self.goals = RoadmapGoals(world, roadmap, self.validity, GoalIKConfig(
            random_seeds=cfg.ik_random_seeds, random_rounds=cfg.ik_random_rounds),
            cfg.ik_seeds, same_robot=same_robot)
        self.goal_ik = self.goals.goal_ik
        self.kpaths = KShortestPaths(roadmap)
        P, distal = distal_values(world, roadmap.config)
        self.connector = Connector(world, roadmap, self.validity, self.config, self.resolution,
                                   P, distal)
        warm_up()
        self._exits: ObstacleMemo[Array] = ObstacleMemo(world.fast, EXITS_KEPT)
        self.tree_repair = TreeRepair(world, roadmap, self.validity, self._route_nodes,
                                      self.resolution, cfg.repair)
        self.goal_ik.warmup()
        # compile (cold cache) or load every kernel of a query now, not in the first timed
        # one: a pose query between two nodes (whose ends normally connect directly)
        if roadmap.n_nodes >= 2:
            self.seeds(roadmap.nodes[0], Goal.pose(world.robot.compute_ee_pose(
                roadmap.nodes[-1])), 2)

    # --- goal ---------------------------------------------------------------------------
    def goal_configurations(self, T_world_ee: Array, n: int | None = None,
                            deadline: float = math.inf, near: Array | None = None,
                            *, from_near: bool = True) -> tuple[Array, str]:
        """:meth:`RoadmapGoals.configurations <chekhov.roadmap.goals.RoadmapGoals.configurations>`
        (n default ``n_goal_ik``)."""
        n = self.config.n_goal_ik if n is None else n
        return self.goals.configurations(T_world_ee, n, deadline, near, from_near=from_near)

    def goal_nodes(self, goal: Goal, near: Array | None = None) -> IntArray:
        """:meth:`RoadmapGoals.nodes <chekhov.roadmap.goals.RoadmapGoals.nodes>`."""
        return self.goals.nodes(goal, near)

    def certified_segments(self, path: Array, node_path: IntArray) -> NDArray[np.bool_]:
        """(T - 1,) which segments of a route ``path`` (T, K) rad are roadmap edges between
        consecutive nodes of its ``node_path`` (the nodes' configurations bit for bit) that
        passed the certification's own check of a segment when the roadmap was built, in the
        world it was built for: this robot, and no dynamic obstacle now
        (``collision.route_check``). All False otherwise."""
        P = np.asarray(path, dtype=float)
        known = np.zeros(max(len(P) - 1, 0), dtype=bool)
        self.validity.refresh()
        if not (self._edges_certified and self.validity.all_valid) or len(node_path) < 2:
            return known
        rm = self.roadmap
        Q = rm.nodes[node_path]
        found = [o for o in np.flatnonzero((Q[0] == P).all(axis=1))
                 if np.array_equal(P[o:o + len(Q)], Q)]
        if not found:
            return known
        o = int(found[0])
        for i, (a, b) in enumerate(pairwise(node_path.tolist())):
            row = rm.indices[rm.indptr[a]:rm.indptr[a + 1]]    # a's neighbours, sorted
            j = int(np.searchsorted(row, b))
            known[o + i] = j < len(row) and row[j] == b
        return known

    # --- query --------------------------------------------------------------------------
    def seed(self, q_start: Array, goal: Goal) -> SeedResult:
        """A seed path from q_start (K,) to the goal, avoiding the world's current obstacles:
        through the first goal IK solution that connects to the roadmap."""
        return self.seeds(q_start, goal, 1)[0]

    def seeds(self, q_start: Array, goal: Goal, n_routes: int, deadline: float = math.inf,
              *, goal_nodes_first: bool = False, shorter_than_rad: float = math.inf,
              last_resorts: bool = True) -> list[SeedResult]:
        """Up to ``n_routes`` seed paths from q_start (K,) to the goal, each ending at another
        of the pose goal's IK solutions (those that connect to the roadmap, in the order
        :meth:`goal_configurations` gives them, nearest the start first; with
        ``goal_nodes_first`` the goal's roadmap nodes (:meth:`goal_nodes`) before them, and
        no IK solutions found from q_start itself: the cheapest route to certify and to find,
        not the shortest — a first answer to improve on). With ``shorter_than_rad``, only
        goal configurations nearer the start than that (joint-space straight line, rad) are
        connected and routed: no path to the others is shorter (an anytime query's more
        routes, which must beat its answer so far). Without ``last_resorts``, goal
        configurations are connected only directly or by the cheap bridges, never by the
        tree or the wide search (``RoadmapConnector.connect``). On failure, one unsuccessful
        result;
        status "timeout" when ``deadline`` (a ``time.perf_counter()`` value, s) passed before
        an answer, "no_path" with ``info["pruned"]`` when no goal configuration is nearer than
        ``shorter_than_rad``. ``timing_s`` is the whole query's, shared by all."""
        t0 = time.perf_counter()
        timing = {"ik": 0.0, "connect": 0.0, "search": 0.0, "validate": 0.0}
        robot = self.world.robot
        q_start = robot.check_configuration(q_start, "start configuration")
        self.validity.refresh()
        checks0 = dict(self.validity.checks)
        ask = _Ask(q_start, goal, n_routes, deadline, shorter_than_rad, last_resorts, t0,
                   timing, checks0)
        q_from, status, why = self._way_out(q_start, "start", deadline)
        if q_from is None:
            return ask.fail(status, reason=why)
        nodes = self.goal_nodes(goal, q_from) if goal_nodes_first and goal.is_pose else \
            np.empty(0, dtype=np.int64)
        if len(nodes) and n_routes == 1:
            # the goal's roadmap nodes alone, by cheap connections, before any IK: a route
            # found so is the one the whole goal set gives (its nodes come first), and a
            # first answer at a pre-grasp pose needs no IK (0.3-0.5 ms of it)
            found = self._routes(ask._replace(last_resorts=False), q_from,
                                 self.roadmap.nodes[nodes])
            if found[0].success or found[0].status == "timeout":
                return found
        t = time.perf_counter()
        Q_goal, status, why = self._goal_set(q_from, goal, n_routes, deadline, nodes,
                                             goal_nodes_first)
        timing["ik"] = time.perf_counter() - t
        if status:
            return ask.fail(status, reason=why)
        return self._routes(ask, q_from, Q_goal)

    def _routes(self, ask: _Ask, q_from: Array, Q_goal: Array) -> list[SeedResult]:
        """:meth:`seeds`' routes from q_from (the start or its exit) to the goal
        configurations Q_goal (n, K), in their order."""
        timing, deadline, n_routes = ask.timing, ask.deadline, ask.n_routes
        if math.isfinite(ask.shorter_than_rad):
            Q_goal = Q_goal[np.linalg.norm(Q_goal - ask.q_start, axis=1) < ask.shorter_than_rad]
            if len(Q_goal) == 0:
                return ask.fail("no_path", pruned=True, reason=(
                    f"no goal configuration is nearer the start than "
                    f"{ask.shorter_than_rad:.3g} rad"))
        t = time.perf_counter()
        starts, goals = self._connect_ends(q_from, Q_goal, n_routes, deadline,
                                           ask.last_resorts)
        timing["connect"] += time.perf_counter() - t
        if time.perf_counter() >= deadline:
            return ask.fail("timeout", reason="the time limit passed while connecting")
        if not starts or not goals:
            return ask.fail("no_connection", side="start" if not starts else "goal")
        found = [_with_ends(r, ask.q_start, ask.goal.q) for r in
                 (self._route(q_from, Q_goal, starts, g, timing, deadline) for g in goals)
                 if r is not None]
        timing["total"] = time.perf_counter() - ask.t0
        if time.perf_counter() >= deadline:
            return ask.fail("timeout", reason="the time limit passed while routing")
        if not found:
            return ask.fail("no_path", reason="dynamic obstacles cut every roadmap route tried")
        checks = {k: self.validity.checks[k] - ask.checks0[k] for k in ask.checks0}
        return [SeedResult(True, "solved", path, nodes, q_goal, timing,
                           {**info, "checks": checks}) for path, nodes, q_goal, info in found]

    def _goal_set(self, q_start: Array, goal: Goal, n_routes: int, deadline: float,
                  goal_nodes: IntArray, nodes_first: bool = False) -> tuple[Array, str, str]:
        """(goal configurations (n, K) nearest the start first — with ``nodes_first``, the
        goal's roadmap nodes (``goal_nodes``) before the others, and none found from the
        start (``from_near`` of :meth:`goal_configurations`); a configuration goal's exit
        when the fast checker rejects it (:meth:`_way_out`) —, failure status, reason)."""
        if goal.is_pose:
            assert goal.T_world_ee is not None
            n = max(self.config.n_goal_ik, n_routes)
            nodes = self.roadmap.nodes[goal_nodes]
            # a first answer to improve on (nodes_first) takes no IK near the start (+0.5-0.8
            # ms a query at the median); the improvements' routes, which shorten it, do. 40
            # random cases a scene, alternating: first answer median 1.7-1.9 -> 1.1-1.2 ms in
            # four scenes, the same final paths
            Q_goal, why = self.goal_configurations(goal.T_world_ee, n, deadline, near=q_start,
                                                   from_near=not nodes_first)
            if len(nodes):      # the goal's roadmap nodes first, then the IK solutions apart
                sep = self.goal_ik.config.min_separation
                apart = [np.linalg.norm(nodes - q, axis=1).min() >= sep for q in Q_goal]
                Q_goal = np.vstack([nodes, Q_goal[apart]])[:max(n, len(nodes))]
            return Q_goal, "" if len(Q_goal) else "no_ik", why
        assert goal.q is not None
        q_to, status, why = self._way_out(goal.q, "goal", deadline)
        return (np.empty((0, len(goal.q))) if q_to is None else q_to[None]), status, why

    def _way_out(self, q: Array, end: str, deadline: float) -> tuple[Array | None, str, str]:
        """(q, or where the route leaves from instead: ``collision.exits.exact_exit`` when
        the fast checker rejects q and the exact checker does not, "", ""), or (None,
        failure status, reason): ``end`` ("start" / "goal") outside the limits or in
        collision, or no exit found ("no_connection", "timeout")."""
        w = self.world
        q = w.robot.check_configuration(q, f"{end} configuration")
        if not w.robot.within_limits(q)[0]:
            return None, f"invalid_{end}", f"{end} outside the limits"
        if w.fast.is_valid(q):
            return q, "", ""
        out = self._exits.get(q.tobytes())   # asked again for more routes
        if out is None:
            if not w.exact.is_valid(q):
                return None, f"invalid_{end}", f"{end} in collision"
            out = exact_exit(w.fast, w.exact, q, w.robot.lower, w.robot.upper, deadline)
            if out is None:
                return self._no_exit(end, deadline)
            self._exits.put(q.tobytes(), out)
        return out, "", ""

    @staticmethod
    def _no_exit(end: str, deadline: float) -> tuple[None, str, str]:
        """(None, "timeout" when ``deadline`` passed else "no_connection", why)."""
        if time.perf_counter() >= deadline:
            return None, "timeout", f"the time limit passed looking for a way out of the {end}"
        return None, "no_connection", (f"the {end} is exactly free, but the fast checker "
                                       f"rejects it and no exactly free way out was found")

    def _connect_ends(self, q_start: Array, Q_goal: Array, n_routes: int, deadline: float,
                      last_resorts: bool = True
                      ) -> tuple[list[Connection], list[list[tuple[int, Connection]]]]:
        """Connections of the start, and of up to n_routes goal configurations (each a list
        of (goal index, connection)), to the roadmap; none of the goals' when the start has
        none.

        Every goal configuration's cheap connections are tried first. The last resorts (a
        tree, a wide search: up to ``tree_time_s`` each) go, in order until one connects, to
        every goal when none connected so — or, asked for more routes, to the goals nearer
        the start than the first that did: a shelf task's nearest IK solution, its hand
        wedged between two boxes, grew its tree for 0.5 s before the first answer while the
        next one connected directly. Without ``last_resorts``, none (Roadmap + TrajOpt's
        more-routes stage: see ``RoadmapTrajOpt._more_routes``)."""
        starts = self.connector.connect(q_start, deadline=deadline)
        goals: list[list[tuple[int, Connection]]] = []
        if not starts:
            return starts, goals
        for gi, qg in enumerate(Q_goal):
            if time.perf_counter() >= deadline or len(goals) == n_routes:
                break
            g = [(gi, c) for c in self.connector.connect(qg, last_resorts=False,
                                                         deadline=deadline)]
            if g:
                goals.append(g)
        # the goals to try the last resorts on (none without them)
        if not last_resorts:
            nearer = 0
        elif not goals:
            nearer = len(Q_goal)
        else:
            nearer = goals[0][0][0] if n_routes > 1 else 0
        for gi in range(nearer):
            if time.perf_counter() >= deadline or len(goals) == n_routes:
                break
            g = [(gi, c) for c in self.connector.connect(Q_goal[gi], last_resorts=True,
                                                         deadline=deadline)]
            if g:
                goals.append(g)
                break
        return starts, goals

    def repair(self, q_start: Array, Q_goal: Array, deadline: float) -> RepairResult:
        """When :meth:`seeds` found nothing (no connection, or every route cut): a path
        q_start (K,) → a row of Q_goal (n, K) by a bidirectional tree that connects into the
        roadmap, searching until ``deadline`` (``time.perf_counter()`` value, s)."""
        self.validity.refresh()
        t0 = time.perf_counter()
        q_from, status, _ = self._way_out(np.asarray(q_start, dtype=float), "start", deadline)
        outs = [self._way_out(q, "goal", deadline) for q in np.atleast_2d(Q_goal)]
        exits = [(q, out) for q, (out, _, _) in zip(np.atleast_2d(Q_goal), outs, strict=True)
                 if out is not None]
        if q_from is None or not exits:
            return RepairResult(None, "timeout" if status == "timeout" else "exhausted", None,
                                time.perf_counter() - t0, {"tree_nodes": 0})
        r = self.tree_repair.search(q_from, np.array([out for _, out in exits]), deadline)
        if r.path is None:
            return r
        ends = np.array([out for _, out in exits])   # the tree ends at one of them
        q_goal = exits[int(np.argmin(np.linalg.norm(ends - r.path[-1], axis=1)))][0]
        path, _, _, _ = _with_ends((r.path, np.empty(0, dtype=np.int64), q_goal, {}),
                                   q_start, q_goal)
        return replace(r, path=path, q_goal=q_goal, time_s=time.perf_counter() - t0)

    def _route_nodes(self, s: int, g: int, deadline: float) -> IntArray | None:
        found = self._roadmap_path(s, g, {"search": 0.0, "validate": 0.0}, deadline)
        return None if found is None else found[0]

    def _route(self, q_start: Array, Q_goal: Array, starts: list[Connection],
               goals: list[tuple[int, Connection]], timing: dict[str, float],
               deadline: float = math.inf
               ) -> tuple[Array, IntArray, Array, dict[str, object]] | None:
        rm = self.roadmap
        t = time.perf_counter()
        s_nodes = np.array([c.node for c in starts])
        g_nodes = np.array([c.node for _, c in goals])
        total = (np.array([c.cost for c in starts])[:, None]
                 + rm.dist[s_nodes[:, None], g_nodes[None, :]]
                 + np.array([c.cost for _, c in goals])[None, :])
        order = np.argsort(total, axis=None)[: self.config.max_pair_tries]
        timing["search"] += time.perf_counter() - t
        for flat in order:
            si, gi = np.unravel_index(flat, total.shape)
            if not np.isfinite(total[si, gi]) or time.perf_counter() >= deadline:
                break
            sc, (qi, gc) = starts[si], goals[gi]
            found = self._roadmap_path(sc.node, gc.node, timing, deadline)
            if found is None:
                continue
            nodes, rank = found
            q_goal = Q_goal[qi]
            path = np.vstack([q_start[None], *sc.via, rm.nodes[nodes], *gc.via[::-1],
                              q_goal[None]])
            keep = np.ones(len(path), dtype=bool)  # drop repeated configurations
            keep[1:] = np.abs(np.diff(path, axis=0)).max(axis=1) > 1e-12
            info: dict[str, object] = {"start_connection": sc.kind, "goal_connection": gc.kind,
                                       "path_rank": rank, "start_node": sc.node,
                                       "goal_node": gc.node}
            return path[keep], nodes, q_goal, info
        return None

    def _roadmap_path(self, s: int, g: int, timing: dict[str, float],
                      deadline: float = math.inf) -> tuple[IntArray, int] | None:
        """Roadmap nodes s → g free of the current obstacles: the cached shortest path, else
        the next stored k shortest, else a lazy A* on the remaining graph (rank -1)."""
        rm, val = self.roadmap, self.validity
        t = time.perf_counter()
        nodes = rm.shortest_path(s, g)
        timing["search"] += time.perf_counter() - t
        if len(nodes) == 0:
            return None
        if val.all_valid:
            return nodes, 0
        t = time.perf_counter()
        try:
            if val.path_valid(nodes, path_edges(rm.indptr, rm.indices, rm.edge_id, nodes)):
                return nodes, 0
            for rank, p in enumerate(self.kpaths.paths(s, g)[1:], start=1):
                if val.path_valid(p, path_edges(rm.indptr, rm.indices, rm.edge_id, p)):
                    return p, rank
            lazy = self._lazy_search(s, g, deadline)
            return None if lazy is None else (lazy, -1)
        finally:
            timing["validate"] += time.perf_counter() - t

    def _lazy_search(self, s: int, g: int, deadline: float = math.inf) -> IntArray | None:
        """A* treating unchecked nodes and edges as free; check the found path, forbid what
        fails, repeat (LazyPRM). The heuristic is the static all-pairs distance to g."""
        rm, val = self.roadmap, self.validity
        h = rm.dist[:, g].astype(np.float64)
        for _ in range(self.config.lazy_iterations):
            if time.perf_counter() >= deadline:
                return None
            nodes, _ = astar(rm.indptr, rm.indices, rm.weights, rm.edge_id, s, g, h,
                             val.node_state != INVALID, val.edge_state != INVALID)
            if len(nodes) == 0:
                return None
            if val.path_valid(nodes, path_edges(rm.indptr, rm.indices, rm.edge_id, nodes)):
                return nodes
        return None


_Route = tuple[Array, IntArray, Array, dict[str, object]]


class _Ask(NamedTuple):
    """One :meth:`RoadmapSeeder.seeds` query as its stages share it: its arguments, when it
    began (perf_counter s), its timing by phase (s) and the validity checks made before."""

    q_start: Array
    goal: Goal
    n_routes: int
    deadline: float
    shorter_than_rad: float
    last_resorts: bool
    t0: float
    timing: dict[str, float]
    checks0: dict[str, int]

    def fail(self, status: str, **info: object) -> list[SeedResult]:
        """The query's one unsuccessful result."""
        self.timing["total"] = time.perf_counter() - self.t0
        return [SeedResult(False, status, None, np.empty(0, dtype=np.int64), None,
                           self.timing, dict(info))]


def _with_ends(route: _Route, q_start: Array, q_goal: Array | None) -> _Route:
    """A route between the ends' exits (``RoadmapSeeder._way_out``) with the ends themselves
    added where they differ: q_start (K,) before, the goal configuration ``q_goal`` after."""
    path, nodes, q_end, info = route
    if not np.array_equal(path[0], q_start):
        path = np.vstack([q_start, path])
        info = {**info, "start_exit": True}
    if q_goal is not None and not np.array_equal(path[-1], q_goal):
        path, q_end = np.vstack([path, q_goal]), np.asarray(q_goal, dtype=float)
        info = {**info, "goal_exit": True}
    return path, nodes, q_end, info
