"""Compiled graph searches on the roadmap's CSR adjacency: path recovery from a predecessor
matrix, and A* with banned nodes / edges (used by Yen's algorithm and the lazy search).

The graph is undirected; every edge e = (u, v) appears twice in the CSR arrays
(``indices``, ``weights``, ``edge_id``), once per direction, both with ``edge_id`` e.
"""

from __future__ import annotations

import heapq
from itertools import pairwise

import numpy as np
from numba import njit
from numpy.typing import NDArray

IntArray = NDArray[np.int64]


@njit(cache=True, nogil=True)
def recover_path(pred_row, src, dst):  # pragma: no cover - compiled
    """Nodes src → dst from the predecessor row of ``src`` (scipy's convention: -9999 for
    none); an empty array when dst is unreachable."""
    if src == dst:
        out = np.empty(1, dtype=np.int64)
        out[0] = src
        return out
    n = 1
    v = dst
    while v != src:
        v = pred_row[v]
        if v < 0:
            return np.empty(0, dtype=np.int64)
        n += 1
    out = np.empty(n, dtype=np.int64)
    v = dst
    for i in range(n - 1, -1, -1):
        out[i] = v
        if i > 0:
            v = pred_row[v]
    return out


@njit(cache=True, nogil=True, inline="always")
def astar_any(indptr, indices, weights, edge_id, src, is_goal, heuristic, node_ok,
              edge_ok, dst=-1):  # pragma: no cover - compiled
    """Shortest path src → the nearest node with ``is_goal`` True (or, with dst ≥ 0, to dst:
    ``is_goal`` is then not read), avoiding nodes with ``node_ok`` False and edges with
    ``edge_ok`` False (by ``edge_id``). ``weights`` are per CSR entry; ``heuristic`` (N,) must
    be admissible for the goal set. Returns (nodes, cost); nodes is empty when no goal is
    reachable."""
    N = indptr.shape[0] - 1
    g = np.full(N, np.inf)
    parent = np.full(N, -1, dtype=np.int64)
    closed = np.zeros(N, dtype=np.bool_)
    if not node_ok[src] or (dst >= 0 and not node_ok[dst]):
        return np.empty(0, dtype=np.int64), np.inf
    g[src] = 0.0
    heap = [(heuristic[src], src)]
    found = -1
    while len(heap) > 0:
        _, u = heapq.heappop(heap)
        if closed[u]:
            continue
        if u == dst if dst >= 0 else is_goal[u]:
            found = u
            break
        closed[u] = True
        for a in range(indptr[u], indptr[u + 1]):
            v = indices[a]
            if closed[v] or not node_ok[v] or not edge_ok[edge_id[a]]:
                continue
            nd = g[u] + weights[a]
            if nd < g[v]:
                g[v] = nd
                parent[v] = u
                heapq.heappush(heap, (nd + heuristic[v], v))
    if found < 0:
        return np.empty(0, dtype=np.int64), np.inf
    n = 1
    v = found
    while v != src:
        v = parent[v]
        n += 1
    out = np.empty(n, dtype=np.int64)
    v = found
    for i in range(n - 1, -1, -1):
        out[i] = v
        v = parent[v]
    return out, g[found]


@njit(cache=True, nogil=True)
def astar(indptr, indices, weights, edge_id, src, dst, heuristic, node_ok,
          edge_ok):  # pragma: no cover - compiled
    """:func:`astar_any` to the single node dst (not reachable when ``node_ok[dst]`` is
    False)."""
    return astar_any(indptr, indices, weights, edge_id, src, node_ok, heuristic, node_ok,
                     edge_ok, dst)


def csr_adjacency(N: int, edges: IntArray, lengths: NDArray[np.float64]
                  ) -> tuple[IntArray, IntArray, NDArray[np.float64], IntArray]:
    """The CSR adjacency of N nodes joined by undirected ``edges`` (E, 2) of ``lengths`` (E,):
    (indptr (N+1,), indices, weights, edge_id), each edge once per direction, every row
    sorted by neighbour (as :func:`edge_lookup` needs)."""
    u = np.concatenate([edges[:, 0], edges[:, 1]])
    v = np.concatenate([edges[:, 1], edges[:, 0]])
    eid = np.concatenate([np.arange(len(edges)), np.arange(len(edges))])
    order = np.lexsort((v, u))
    indptr = np.zeros(N + 1, dtype=np.int64)
    np.cumsum(np.bincount(u, minlength=N), out=indptr[1:])
    w = np.concatenate([lengths, lengths])
    return (indptr, v[order].astype(np.int64), w[order].astype(np.float64),
            eid[order].astype(np.int64))


def edge_lookup(indptr: IntArray, indices: IntArray, edge_id: IntArray, u: int, v: int) -> int:
    """Edge id of (u, v), or -1 when they are not adjacent (rows of ``indices`` sorted)."""
    lo, hi = int(indptr[u]), int(indptr[u + 1])
    a = lo + int(np.searchsorted(indices[lo:hi], v))
    return int(edge_id[a]) if a < hi and indices[a] == v else -1


def path_edges(indptr: IntArray, indices: IntArray, edge_id: IntArray,
               nodes: IntArray) -> IntArray:
    """Edge ids along a node path (len(nodes) - 1,)."""
    return np.array([edge_lookup(indptr, indices, edge_id, int(a), int(b))
                     for a, b in pairwise(nodes)], dtype=np.int64)


def warm_up() -> None:
    """Compile (or load from numba's cache) the kernels, so the first query is not slow."""
    indptr = np.array([0, 1, 2], dtype=np.int64)
    indices = np.array([1, 0], dtype=np.int64)
    eid = np.zeros(2, dtype=np.int64)
    w = np.ones(2)
    astar(indptr, indices, w, eid, 0, 1, np.zeros(2), np.ones(2, dtype=np.bool_),
          np.ones(1, dtype=np.bool_))
    recover_path(np.array([-9999, 0], dtype=np.int32), 0, 1)
    recover_path(np.array([-9999, 0], dtype=np.int16), 0, 1)


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
