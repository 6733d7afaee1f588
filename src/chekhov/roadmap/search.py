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


@njit(cache=True)
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


@njit(cache=True, inline="always")
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


@njit(cache=True)
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
