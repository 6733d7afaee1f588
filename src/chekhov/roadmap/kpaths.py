"""k shortest loopless paths (Yen's algorithm) on the roadmap, with a cache.

Each spur search is an A* whose heuristic is the all-pairs distance to the target on the full
graph (admissible: banning nodes and edges only lengthens paths), so a spur search expands few
nodes; k = 3 paths between two nodes of a 1000-node roadmap take well under a millisecond.
"""

from __future__ import annotations

import heapq
from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from chekhov.roadmap.search import astar, edge_lookup

if TYPE_CHECKING:
    from chekhov.roadmap.graph import Roadmap

IntArray = NDArray[np.int64]


def yen_k_shortest(indptr: IntArray, indices: IntArray, weights: NDArray[np.float64],
                   edge_id: IntArray, src: int, dst: int, k: int,
                   heuristic: NDArray[np.float64] | None = None,
                   node_ok: NDArray[np.bool_] | None = None,
                   edge_ok: NDArray[np.bool_] | None = None) -> list[tuple[float, IntArray]]:
    """Up to k loopless paths src → dst, shortest first, as (cost, nodes) pairs.

    ``heuristic`` (N,): admissible distance-to-dst estimate (zeros: plain Dijkstra).
    ``node_ok`` / ``edge_ok``: nodes and edges that may be used (default all).
    """
    N = len(indptr) - 1
    E = int(edge_id.max()) + 1 if len(edge_id) else 0
    h = np.zeros(N) if heuristic is None else np.asarray(heuristic, dtype=np.float64)
    base_nodes = np.ones(N, dtype=np.bool_) if node_ok is None else node_ok
    base_edges = np.ones(E, dtype=np.bool_) if edge_ok is None else edge_ok
    first, cost = astar(indptr, indices, weights, edge_id, src, dst, h, base_nodes, base_edges)
    if len(first) == 0:
        return []
    found: list[tuple[float, IntArray]] = [(float(cost), first)]
    seen = {tuple(first.tolist())}
    candidates: list[tuple[float, int, IntArray]] = []
    counter = 0
    while len(found) < k:
        last = found[-1][1]
        # prefix costs along the last path
        prefix = np.zeros(len(last))
        for i in range(1, len(last)):
            a = _adjacency_slot(indptr, indices, int(last[i - 1]), int(last[i]))
            prefix[i] = prefix[i - 1] + weights[a]
        for i in range(len(last) - 1):
            spur = int(last[i])
            root = last[: i + 1]
            edge_ok_i = base_edges.copy()
            for _, p in found:
                if len(p) > i + 1 and np.array_equal(p[: i + 1], root):
                    e = edge_lookup(indptr, indices, edge_id, int(p[i]), int(p[i + 1]))
                    if e >= 0:
                        edge_ok_i[e] = False
            node_ok_i = base_nodes.copy()
            node_ok_i[root[:-1]] = False
            spur_path, spur_cost = astar(indptr, indices, weights, edge_id, spur, dst, h,
                                         node_ok_i, edge_ok_i)
            if len(spur_path) == 0:
                continue
            total = np.concatenate([root[:-1], spur_path])
            key = tuple(total.tolist())
            if key in seen:
                continue
            seen.add(key)
            counter += 1
            heapq.heappush(candidates, (float(prefix[i] + spur_cost), counter, total))
        if not candidates:
            break
        c, _, p = heapq.heappop(candidates)
        found.append((c, p))
    return found


def _adjacency_slot(indptr: IntArray, indices: IntArray, u: int, v: int) -> int:
    lo, hi = int(indptr[u]), int(indptr[u + 1])
    return lo + int(np.searchsorted(indices[lo:hi], v))


class KShortestPaths:
    """The k shortest loopless paths between roadmap nodes: those stored in the roadmap (between
    semantic nodes, precomputed at build time) plus an on-demand cache for any other pair."""

    def __init__(self, roadmap: Roadmap, k: int | None = None) -> None:
        self.roadmap = roadmap
        self.k = roadmap.config.k_paths if k is None else int(k)
        self._cache: dict[tuple[int, int], list[IntArray]] = dict(roadmap.stored_k_paths())

    def paths(self, src: int, dst: int) -> list[IntArray]:
        """Up to k node paths src → dst, shortest first (cached)."""
        key = (int(src), int(dst))
        hit = self._cache.get(key)
        if hit is None:
            rev = self._cache.get((key[1], key[0]))
            if rev is not None:
                hit = [p[::-1].copy() for p in rev]
            else:
                hit = [p for _, p in self.roadmap.k_shortest(key[0], key[1], self.k)]
            self._cache[key] = hit
        return hit

    def precompute(self, pairs: Iterable[tuple[int, int]]) -> None:
        for a, b in pairs:
            self.paths(a, b)

    @property
    def cached_pairs(self) -> int:
        return len(self._cache)

    @property
    def nbytes(self) -> int:
        """Approximate memory of the cached paths (bytes)."""
        return sum(p.nbytes + 64 for ps in self._cache.values() for p in ps) + 100 * len(
            self._cache)
