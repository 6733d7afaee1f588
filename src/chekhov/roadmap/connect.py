"""Joining a start or goal configuration to the roadmap with collision-free straight motions.

Direct connections (the paper's definition) are tried first, nearest nodes in joint space in
small batches so that the usual case costs one or two motion checks. When none is free, and
``SeederConfig.bridges`` is on, two-segment connections through an intermediate configuration
are tried, cheapest idea first:

* ``wrist``: keep the proximal joints, move the distal joints to the roadmap's fixed values
  (the configuration then lies in the subspace the uniform nodes cover densely), then go
  straight to a node;
* ``proximal``: move the proximal joints to a node's values with the wrist as it is, then turn
  the wrist;
* ``random``: a random configuration within ``bridge_radius`` rad, then straight to a node;
* ``tree``: a small RRT grown from q (steps of ``tree_step`` rad, at most ``tree_nodes``
  nodes and ``tree_time_s`` s) until one of its nodes has a free straight motion to a
  roadmap node, for configurations wedged close to obstacles. The last resort: a wider direct search
  (``wide_candidates`` nearest nodes).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from chekhov.roadmap.config import SeederConfig
from chekhov.roadmap.graph import Roadmap
from chekhov.roadmap.memo import ObstacleMemo
from chekhov.roadmap.nearest import NearestNodes
from chekhov.roadmap.validity import RoadmapValidity
from chekhov.world import World

Array = NDArray[np.float64]
_BATCHES = (1, 2, 6)
_CACHE_SIZE = 1024
"""Connections kept per obstacle set (each a few hundred bytes)."""


@dataclass(frozen=True, eq=False)
class Connection:
    """A free way from a configuration q to roadmap node ``node``: q → via rows → node.

    Attributes:
        node: roadmap node index. cost: joint-space length, rad. via: (m, K) intermediates.
        kind: "direct", "wrist", "proximal" or "random".
    """

    node: int
    cost: float
    via: Array
    kind: str


class Connector:
    """Connections of arbitrary configurations to one roadmap, against the world's current
    obstacles (``world.fast``)."""

    def __init__(self, world: World, roadmap: Roadmap, validity: RoadmapValidity,
                 config: SeederConfig, resolution: float, proximal: int, distal: Array) -> None:
        self.world = world
        self.roadmap = roadmap
        self.validity = validity
        self.config = config
        self.resolution = resolution
        self.proximal = proximal
        self.distal = distal
        self.tree = cKDTree(roadmap.nodes)
        self.nearest = NearestNodes(roadmap.nodes)
        self.rng = np.random.default_rng(config.seed)
        # connect()'s answers in the current world: (q's bytes, last_resorts) → connections
        self._kept: ObstacleMemo[list[Connection]] = ObstacleMemo(world.fast, _CACHE_SIZE)

    def _motions(self, Q0: Array, Q1: Array, deadline: float = math.inf
                 ) -> NDArray[np.bool_]:
        """Whether each straight motion Q0[i] → Q1[i] (N, K) is free; those not decided by
        ``deadline`` (a ``time.perf_counter()`` value, s) count as blocked
        (``FastChecker.motions_valid``)."""
        return self.world.fast.motions_valid(Q0, Q1, self.resolution, deadline)

    def direct(self, q: Array, n_candidates: int, batches: tuple[int, ...] = _BATCHES,
               deadline: float = math.inf) -> list[tuple[int, float]]:
        """(node, length rad) of free straight connections from q (itself known free), nearest
        nodes first, stopping after the first batch that yields one; no batch after the first
        is started after ``deadline`` (a ``time.perf_counter()`` value, s)."""
        k = min(n_candidates, self.roadmap.n_nodes)
        d, idx = self.nearest.query(q, k)
        ok_node = self.validity.nodes_valid(idx)
        d, idx = d[ok_node], idx[ok_node]
        out: list[tuple[int, float]] = []
        lo = 0
        for size in (*batches, len(idx)):
            hi = min(lo + size, len(idx))
            if hi <= lo or (lo > 0 and time.perf_counter() >= deadline):
                break
            sel = idx[lo:hi]
            ok = self._motions(np.repeat(q[None], len(sel), axis=0), self.roadmap.nodes[sel],
                               deadline)
            out += [(int(n), float(c)) for n, c, v in zip(sel, d[lo:hi], ok, strict=True) if v]
            if out:
                break
            lo = hi
        return out[: self.config.max_connections]

    def connect(self, q: Array, last_resorts: bool = True, deadline: float = math.inf
                ) -> list[Connection]:
        """Free connections of q (K,) (known free) to the roadmap, cheapest first; empty when
        there is none (the roadmap failure). ``last_resorts`` False skips the tree and the
        wide search (for a configuration the query can do without). No attempt starts, and
        the tree stops growing, after ``deadline`` (a ``time.perf_counter()`` value, s).

        The answer is a function of q and the world's obstacles, so an answer completed
        before its deadline is kept until the obstacles change (``obstacles_version``): an
        anytime query connects its start and first goal again for more routes, and a
        pick-and-place start recurs."""
        key = (np.ascontiguousarray(q, dtype=np.float64).tobytes(), last_resorts)
        found = self._kept.get(key)
        if found is None:
            found = self._connect(q, last_resorts, deadline)
            if time.perf_counter() < deadline:
                self._kept.put(key, found)
        return list(found)

    def _connect(self, q: Array, last_resorts: bool, deadline: float) -> list[Connection]:
        self.rng = np.random.default_rng(self.config.seed)   # the same q, the same answer
        found = [Connection(n, c, q[:0].reshape(0, len(q)), "direct")
                 for n, c in self.direct(q, self.config.connect_candidates,
                                         deadline=deadline)]
        if found or not self.config.bridges:
            return found
        attempts: list[Callable[[Array, float], list[Connection]]] = [
            self._via_wrist, self._via_proximal, self._via_random]
        if last_resorts:
            attempts += [self._via_tree, self._wide]
        for attempt in attempts:
            if time.perf_counter() >= deadline:
                break
            found = attempt(q, deadline)
            if found:
                return sorted(found, key=lambda c: c.cost)
        return []

    def _bridge(self, q: Array, Q_mid: Array, kind: str, n_candidates: int,
                deadline: float = math.inf) -> list[Connection]:
        """Connections q → q_mid → node for the first intermediates (rows of Q_mid) that are
        free and reachable from q in a straight line; no intermediate is tried after
        ``deadline`` (a ``time.perf_counter()`` value, s)."""
        fast = self.world.fast
        within = self.world.robot.within_limits(Q_mid)
        Q_mid = Q_mid[within]
        if len(Q_mid) == 0:
            return []
        Q_mid = Q_mid[fast.valid(Q_mid)]
        if len(Q_mid) == 0:
            return []
        Q_mid = Q_mid[self._motions(np.repeat(q[None], len(Q_mid), axis=0), Q_mid, deadline)]
        out: list[Connection] = []
        for q_mid in Q_mid:
            if time.perf_counter() >= deadline:
                break
            c0 = float(np.linalg.norm(q_mid - q))
            out += [Connection(n, c0 + c, q_mid[None], kind)
                    for n, c in self.direct(q_mid, n_candidates, batches=(4,),
                                            deadline=deadline)]
            if out:
                break
        return out

    def _via_wrist(self, q: Array, deadline: float = math.inf) -> list[Connection]:
        q_mid = q.copy()
        q_mid[self.proximal:] = self.distal
        if np.allclose(q_mid, q):
            return []
        return self._bridge(q, q_mid[None], "wrist", self.config.connect_candidates, deadline)

    def _via_proximal(self, q: Array, deadline: float = math.inf) -> list[Connection]:
        P = self.proximal
        _, idx = self.nearest.query(q, 8)
        idx = np.atleast_1d(idx)
        idx = idx[self.validity.nodes_valid(idx)]
        if len(idx) == 0:
            return []
        Q_mid = np.repeat(q[None], len(idx), axis=0)
        Q_mid[:, :P] = self.roadmap.nodes[idx, :P]
        fast = self.world.fast
        ok = fast.valid(Q_mid)
        ok[ok] = self._motions(np.repeat(q[None], int(ok.sum()), axis=0), Q_mid[ok])
        ok[ok] = self._motions(Q_mid[ok], self.roadmap.nodes[idx[ok]])
        return [Connection(int(n), float(np.linalg.norm(m - q) + np.linalg.norm(
            self.roadmap.nodes[n] - m)), m[None], "proximal")
            for n, m in zip(idx[ok], Q_mid[ok], strict=True)][: self.config.max_connections]

    def _via_random(self, q: Array, deadline: float = math.inf) -> list[Connection]:
        M, K = self.config.bridge_samples, len(q)
        u = self.rng.normal(size=(M, K))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        r = self.rng.uniform(0.1, self.config.bridge_radius, size=(M, 1))
        Q_mid = np.clip(q + u * r, self.world.robot.lower, self.world.robot.upper)
        return self._bridge(q, Q_mid, "random", 8, deadline)

    def _wide(self, q: Array, deadline: float = math.inf) -> list[Connection]:
        return [Connection(n, c, q[:0].reshape(0, len(q)), "wide")
                for n, c in self.direct(q, self.config.wide_candidates, batches=(32,),
                                        deadline=deadline)]

    def _via_tree(self, q: Array, deadline: float = math.inf) -> list[Connection]:
        """Grow an RRT from q in batches, for at most ``tree_time_s`` and not past
        ``deadline``; connect its new nodes straight to the roadmap."""
        cfg = self.config
        robot, fast = self.world.robot, self.world.fast
        K = len(q)
        tree = [q]
        parent = [-1]
        _, targets = self.tree.query(q, k=min(64, self.roadmap.n_nodes))
        targets = np.atleast_1d(targets)
        deadline = min(deadline, time.perf_counter() + cfg.tree_time_s)
        while len(tree) < cfg.tree_nodes and time.perf_counter() < deadline:
            T = np.array(tree)
            # half uniform samples (explore), half nearby roadmap nodes (head for the roadmap)
            X = np.vstack([robot.sample_uniform(self.rng, 8),
                           self.roadmap.nodes[self.rng.choice(targets, 8)]])
            near = np.argmin(((T[None, :, :] - X[:, None, :]) ** 2).sum(-1), axis=1)
            step = X - T[near]
            n = np.linalg.norm(step, axis=1, keepdims=True)
            new = T[near] + step * np.minimum(1.0, cfg.tree_step / np.maximum(n, 1e-12))
            ok = fast.valid(new)
            ok[ok] = self._motions(T[near[ok]], new[ok])
            if not ok.any():
                continue
            new, near = new[ok], near[ok]
            first = len(tree)
            tree += list(new)
            parent += near.tolist()
            _, idx = self.tree.query(new, k=2)
            idx = idx.reshape(len(new), -1)
            src = np.repeat(np.arange(len(new)), idx.shape[1])
            cand = idx.reshape(-1)
            good = self.validity.nodes_valid(cand)
            src, cand = src[good], cand[good]
            free = self._motions(new[src], self.roadmap.nodes[cand])
            if not free.any():
                continue
            i = int(np.flatnonzero(free)[0])
            leaf, node = first + int(src[i]), int(cand[i])
            chain = []
            v = leaf
            while v > 0:
                chain.append(tree[v])
                v = parent[v]
            via = np.array(chain[::-1]).reshape(-1, K)
            pts = np.vstack([q[None], via, self.roadmap.nodes[node][None]])
            cost = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
            return [Connection(node, cost, via, "tree")]
        return []
