"""LazyPRM (Bohlin & Kavraki, "Path planning using lazy PRM", ICRA 2000), on our fast checker.

The algorithm, as in the paper:

1. **Roadmap without collision checks**: the start, the goal configurations (IK solutions of
   the goal pose) and ``n_init`` configurations drawn uniformly within the joint limits; each
   node is joined to its ``k_neighbors`` nearest nodes within ``max_edge`` rad (joint-space
   L2). Nothing is checked.
2. **Search**: A* for the shortest path (edge cost: joint-space length; heuristic: distance to
   the nearest goal node, admissible) from the start to any goal node over the nodes and edges
   not yet found invalid.
3. **Lazy validation** of that path: first its nodes not checked before (in one batch); any in
   collision is removed with its edges and the search is repeated. Then its edges not checked
   before, coarse to fine: at ``coarse_factor × resolution`` first (a collision found there is
   real), then at ``resolution``; edges in collision are removed and the search is repeated.
   Check results are cached, so nothing is checked twice.
4. **Node enhancement** when the start and the goals are disconnected: ``n_enhance`` new nodes,
   ``enhance_uniform_fraction`` of them uniform and the rest normally distributed (σ =
   ``enhance_sigma`` rad) around the midpoints of the edges removed so far (the paper's seeds),
   joined to the roadmap like the others; back to 2.
5. Until a path is found or the time limit is reached.

The roadmap is built anew for every query (as the paper's LazyPRM runs were). The hot parts are
compiled or vectorised: A* is numba on a CSR adjacency with validity masks, neighbour search is
``scipy.spatial.cKDTree``, collision checks are batched ``FastChecker.valid`` /
``FastChecker.motions_valid`` calls.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from chekhov.planners.base import PlannerBase, PlanResult, solve_goal_ik
from chekhov.planners.query import PlanQuery
from chekhov.planners.status import PlanStatus
from chekhov.roadmap.search import astar_any, csr_adjacency
from chekhov.world import World

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]
NodeValid = Callable[[Array], BoolArray]
EdgeValid = Callable[[Array, Array, float], BoolArray]

UNKNOWN, VALID, INVALID = 0, 1, -1


@dataclass(frozen=True)
class LazyPRMConfig:
    """Settings of :class:`LazyPRM`.

    Attributes:
        resolution: rad, joint-space step of edge checks (``FastChecker.motions_valid``).
        n_init: nodes sampled for the initial roadmap (besides start and goals).
        n_enhance: nodes added by each node enhancement.
        k_neighbors: each node is joined to at most this many nearest nodes …
        max_edge: … within this distance (rad); None: 0.2 × the joint-space diagonal of the
            limits (OMPL's default range).
        coarse_factor: edges are first checked at ``coarse_factor × resolution``.
        enhance_uniform_fraction: share of uniform nodes in an enhancement.
        enhance_sigma: rad, spread of enhancement nodes around seeds; None: max_edge / 4.
        n_ik: IK solutions of a goal pose used as goal nodes.
    """

    resolution: float = 0.02
    n_init: int = 1000
    n_enhance: int = 500
    k_neighbors: int = 10
    max_edge: float | None = None
    coarse_factor: int = 8
    enhance_uniform_fraction: float = 0.5
    enhance_sigma: float | None = None
    n_ik: int = 4


class LazyPRM(PlannerBase):
    """LazyPRM planner (see the module docstring) for one world.

    ``node_valid(Q (N, K)) -> bool (N,)`` and ``edge_valid(Q0, Q1, resolution) -> bool (N,)``
    (end points excluded) default to the world's fast checker; tests inject their own. An end
    that only the exact checker accepts is planned to through its exit (``fast_free_ends``).
    """

    fast_free_ends = True

    def __init__(self, world: World, config: LazyPRMConfig | None = None, seed: int | None = None,
                 node_valid: NodeValid | None = None, edge_valid: EdgeValid | None = None
                 ) -> None:
        self.world = world
        self.config = config if config is not None else LazyPRMConfig()
        self.name = "LazyPRM"
        self.rng = np.random.default_rng(seed)
        self.node_valid: NodeValid = node_valid if node_valid is not None else world.fast.valid
        self.edge_valid: EdgeValid = (edge_valid if edge_valid is not None
                                      else world.fast.motions_valid)
        lo, hi = world.robot.lower, world.robot.upper
        self.max_edge = (self.config.max_edge if self.config.max_edge is not None
                         else 0.2 * float(np.linalg.norm(hi - lo)))
        # s per node of sampling and connecting (the largest measured lately): a build or an
        # enhancement that cannot finish by the deadline is not started
        self._build_s_per_node = 0.0
        _warm_up()
        world.goal_ik.warmup()   # its IK kernel compiles now, not in the first timed query

    def _plan(self, query: PlanQuery) -> PlanResult:
        """Plan for a checked query within its time limit (s, IK included)."""
        t0, deadline, q_start = query.t0, query.deadline, query.q_start
        cfg, robot = self.config, self.world.robot
        timing: dict[str, float] = {}
        info: dict[str, object] = {"planner": self.name, **asdict(self.config),
                                   "max_edge": self.max_edge}

        def done(status: PlanStatus, path: Array | None = None) -> PlanResult:
            return PlanResult(path is not None, path, status, time.perf_counter() - t0,
                              timing, info=info)

        goals = solve_goal_ik(self.world, query, cfg.n_ik, timing, info)
        if goals is None:
            return done(PlanStatus.TIMEOUT if query.expired() else PlanStatus.NO_IK)
        if query.expired():
            return done(PlanStatus.TIMEOUT)
        if not (robot.within_limits(q_start)[0] and self.node_valid(q_start[None])[0]):
            return done(PlanStatus.INVALID_START)
        if not self._can_build(cfg.n_init, deadline):
            return done(PlanStatus.TIMEOUT)
        t = time.perf_counter()
        X = np.vstack([q_start, goals, robot.sample_uniform(self.rng, cfg.n_init)])
        node_state = np.zeros(len(X), dtype=np.int8)
        node_state[: 1 + len(goals)] = VALID          # start checked above, goals by IK
        edges = connect(X, np.arange(len(X)), cfg.k_neighbors, self.max_edge)
        edge_state = np.zeros(len(edges), dtype=np.int8)
        timing["roadmap"] = self._built(len(X), t)
        goal_idx = np.arange(1, 1 + len(goals))
        stats = {"searches": 0, "node_checks": 0, "edge_checks": 0, "enhancements": 0}
        while True:
            path, node_state, edge_state = lazy_shortest_path(
                X, edges, 0, goal_idx, self.node_valid, self.edge_valid, cfg.resolution,
                node_state, edge_state, deadline, cfg.coarse_factor, stats, timing)
            info.update(stats, nodes=len(X), edges=len(edges))
            if path is not None:
                return done(PlanStatus.SOLVED, X[path])
            if not self._can_build(cfg.n_enhance, deadline):
                return done(PlanStatus.TIMEOUT)
            t = time.perf_counter()
            new = self._enhance(X, edges, edge_state)
            first = len(X)
            X = np.vstack([X, new])
            node_state = np.concatenate([node_state, np.zeros(len(new), dtype=np.int8)])
            more = connect(X, np.arange(first, len(X)), cfg.k_neighbors, self.max_edge)
            edges = np.vstack([edges, more])
            edge_state = np.concatenate([edge_state, np.zeros(len(more), dtype=np.int8)])
            stats["enhancements"] += 1
            timing["roadmap"] += self._built(len(new), t)

    def _can_build(self, n: int, deadline: float) -> bool:
        """Whether sampling and connecting n nodes can end before ``deadline``."""
        return time.perf_counter() + n * self._build_s_per_node < deadline

    def _built(self, n: int, t0: float) -> float:
        """Record that n nodes took from t0 until now; returns that time (s)."""
        dt = time.perf_counter() - t0
        self._build_s_per_node = max(dt / max(n, 1), 0.9 * self._build_s_per_node)
        return dt

    def _enhance(self, X: Array, edges: IntArray, edge_state: NDArray[np.int8]) -> Array:
        """New nodes: uniform, and Gaussian around midpoints of removed edges (seeds)."""
        cfg, robot = self.config, self.world.robot
        removed = edges[edge_state == INVALID]
        n_seeded = 0 if len(removed) == 0 else round(
            cfg.n_enhance * (1.0 - cfg.enhance_uniform_fraction))
        uniform = robot.sample_uniform(self.rng, cfg.n_enhance - n_seeded)
        if n_seeded == 0:
            return uniform
        sigma = cfg.enhance_sigma if cfg.enhance_sigma is not None else self.max_edge / 4
        mid = 0.5 * (X[removed[:, 0]] + X[removed[:, 1]])
        seeds = mid[self.rng.integers(0, len(mid), n_seeded)]
        near = np.clip(seeds + self.rng.normal(0.0, sigma, seeds.shape), robot.lower,
                       robot.upper)
        return np.vstack([uniform, near])


# --- roadmap graph ----------------------------------------------------------------------
def _warm_up() -> None:
    """Compile (or load from numba's cache) the search before the first timed query."""
    X = np.array([[0.0], [1.0]])
    lazy_shortest_path(X, np.array([[0, 1]]), 0, np.array([1]),
                       lambda Q: np.ones(len(Q), dtype=bool),
                       lambda A, B, r: np.ones(len(A), dtype=bool), 0.1)


def connect(X: Array, new: IntArray, k: int, max_edge: float) -> IntArray:
    """Edges (E, 2), i < j, joining each node in ``new`` to its k nearest nodes of X within
    max_edge (rad), without duplicates among themselves."""
    if len(new) == 0 or len(X) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    kk = min(k + 1, len(X))
    d, j = cKDTree(X).query(X[new], k=kk, distance_upper_bound=max_edge)
    d, j = np.asarray(d).reshape(len(new), kk), np.asarray(j).reshape(len(new), kk)
    i = np.repeat(new, kk).reshape(len(new), kk)
    keep = np.isfinite(d) & (j != i)
    a, b = i[keep], j[keep]
    lo, hi = np.minimum(a, b).astype(np.int64), np.maximum(a, b).astype(np.int64)
    key = np.unique(lo * len(X) + hi)   # one integer per pair: far faster than rows
    return np.stack([key // len(X), key % len(X)], axis=1).astype(np.int64)


def lazy_shortest_path(X: Array, edges: IntArray, start: int, goals: IntArray,
                       node_valid: NodeValid, edge_valid: EdgeValid, resolution: float,
                       node_state: NDArray[np.int8] | None = None,
                       edge_state: NDArray[np.int8] | None = None,
                       deadline: float = math.inf, coarse_factor: int = 8,
                       stats: dict[str, int] | None = None,
                       timing: dict[str, float] | None = None,
                       ) -> tuple[IntArray | None, NDArray[np.int8], NDArray[np.int8]]:
    """Steps 2–3 of LazyPRM on a fixed roadmap: search, lazily validate, remove, re-search.

    Args:
        X: node configurations (N, K). edges: (E, 2) node indices, undirected.
        start, goals: node indices. node_valid, edge_valid, resolution: the checks (above).
        node_state, edge_state: 0 unknown, 1 valid, -1 invalid (removed); updated and returned.
        deadline: ``time.perf_counter()`` value after which the search gives up.
        stats, timing: optional counters ("searches", "node_checks", "edge_checks") and
            seconds ("search", "check") accumulated in place.

    Returns:
        (node indices start → goal of a path whose nodes and edges are all valid, or None when
        the start and goals are disconnected or the deadline passed; node_state; edge_state).
    """
    n = len(X)
    node_state = np.zeros(n, dtype=np.int8) if node_state is None else node_state
    edge_state = np.zeros(len(edges), dtype=np.int8) if edge_state is None else edge_state
    stats = stats if stats is not None else {}
    timing = timing if timing is not None else {}
    for key in ("searches", "node_checks", "edge_checks"):
        stats.setdefault(key, 0)
    for key in ("search", "check"):
        timing.setdefault(key, 0.0)
    indptr, nbr, w_entry, eid = csr_adjacency(
        n, edges, np.linalg.norm(X[edges[:, 1]] - X[edges[:, 0]], axis=1))
    goals = np.asarray(goals, dtype=np.int64)
    is_goal = np.zeros(n, dtype=np.bool_)
    is_goal[goals] = True
    h = np.min(np.linalg.norm(X[:, None, :] - X[goals][None, :, :], axis=2), axis=1)
    while time.perf_counter() < deadline:
        t = time.perf_counter()
        path, _ = astar_any(indptr, nbr, w_entry, eid, int(start), is_goal, h,
                            node_state != INVALID, edge_state != INVALID)
        stats["searches"] += 1
        timing["search"] += time.perf_counter() - t
        if len(path) == 0:
            return None, node_state, edge_state
        t = time.perf_counter()
        try:
            if _check_nodes(X, path, node_valid, node_state, stats):
                continue
            pe = _path_edges(indptr, nbr, eid, path)
            if _check_edges(X, edges, pe, edge_valid, resolution, coarse_factor, edge_state,
                            stats):
                continue
        finally:
            timing["check"] += time.perf_counter() - t
        return path, node_state, edge_state
    return None, node_state, edge_state


def _check_nodes(X: Array, path: IntArray, node_valid: NodeValid,
                 node_state: NDArray[np.int8], stats: dict[str, int]) -> bool:
    """Check the path's unknown nodes; True when some were invalid (now removed)."""
    todo = path[node_state[path] == UNKNOWN]
    if len(todo) == 0:
        return False
    ok = np.asarray(node_valid(X[todo]), dtype=bool)
    stats["node_checks"] += len(todo)
    node_state[todo] = np.where(ok, VALID, INVALID)
    return not bool(ok.all())


def _path_edges(indptr: IntArray, nbr: IntArray, eid: IntArray, path: IntArray) -> IntArray:
    out = np.empty(len(path) - 1, dtype=np.int64)
    for i in range(len(path) - 1):
        u, v = path[i], path[i + 1]
        lo, hi = indptr[u], indptr[u + 1]
        out[i] = eid[lo + int(np.flatnonzero(nbr[lo:hi] == v)[0])]
    return out


def _check_edges(X: Array, edges: IntArray, pe: IntArray, edge_valid: EdgeValid,
                 resolution: float, coarse_factor: int, edge_state: NDArray[np.int8],
                 stats: dict[str, int]) -> bool:
    """Check the path's unknown edges coarse to fine; True when some were invalid."""
    todo = pe[edge_state[pe] == UNKNOWN]
    if len(todo) == 0:
        return False
    Q0, Q1 = X[edges[todo, 0]], X[edges[todo, 1]]
    stats["edge_checks"] += len(todo)
    if coarse_factor > 1:
        ok = np.asarray(edge_valid(Q0, Q1, resolution * coarse_factor), dtype=bool)
        if not ok.all():
            edge_state[todo[~ok]] = INVALID
            return True
    ok = np.asarray(edge_valid(Q0, Q1, resolution), dtype=bool)
    edge_state[todo] = np.where(ok, VALID, INVALID)
    return not bool(ok.all())


__all__ = ["LazyPRM", "LazyPRMConfig", "connect", "lazy_shortest_path"]
