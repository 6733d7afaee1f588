"""RRT-Connect's two trees (Kuffner & LaValle 2000), seeded and bounded by a node count.

:class:`BiTrees` holds a tree grown from the start and one grown from every goal
configuration, and the three moves of RRT-Connect: extend one tree a step towards a sample,
pull the other straight towards the new node, join the two branches when they meet. The
motion test is the caller's (``free(q0, q1)``: q1 and the straight motion to it are free,
q0 known free), so the same trees serve :mod:`chekhov.roadmap.repair` (which also tries to
reach the roadmap) and :func:`rrt_connect` (the plain search: no roadmap, no clock).

:func:`rrt_connect` draws its samples from ``numpy.random.default_rng(seed)`` and stops after
``max_nodes`` tree nodes, not at a time: the same query with the same seed gives the same
answer on every machine. That is what a reproducible decision needs ("is this case
solvable?", :func:`chekhov.bench.solvability_pass`); OMPL's RRTConnect, timed and seeded
once per process, cannot give it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from chekhov.collision.fast import FastChecker

Array = NDArray[np.float64]
MotionFn = Callable[[Array, Array], bool]
"""(q0 known free, q1) → q1 and the straight motion q0 → q1 are free."""


def fast_motion(fast: FastChecker, resolution: float) -> MotionFn:
    """The fast checker's :data:`MotionFn`: q1, and the motion at every ``resolution`` rad."""
    def free(q0: Array, q1: Array) -> bool:
        return bool(fast.valid(q1[None])[0] and fast.motions_valid(
            q0[None], q1[None], resolution)[0])
    return free


class Tree:
    """A tree of configurations (rows of X) with parent links; roots have parent -1."""

    def __init__(self, roots: Array) -> None:
        roots = np.atleast_2d(np.asarray(roots, dtype=float))
        self.X = np.empty((max(64, 2 * len(roots)), roots.shape[1]))
        self.parent = np.full(len(self.X), -1, dtype=np.int64)
        self.n = 0
        for q in roots:
            self.add(q, -1)

    def add(self, q: Array, parent: int) -> int:
        if self.n == len(self.X):
            self.X = np.vstack([self.X, np.empty_like(self.X)])
            self.parent = np.concatenate([self.parent, np.full(len(self.parent), -1)])
        self.X[self.n], self.parent[self.n] = q, parent
        self.n += 1
        return self.n - 1

    def nearest(self, q: Array) -> int:
        d = self.X[: self.n] - q
        return int(np.argmin(np.einsum("ij,ij->i", d, d)))

    def prune(self, i: int) -> None:
        """Node i and its descendants leave the tree (its edge from its parent was refused):
        they are never nearest again. Children come after their parents in X."""
        dead = np.zeros(self.n, dtype=bool)
        dead[i] = True
        for k in range(i + 1, self.n):
            dead[k] = self.parent[k] >= 0 and dead[self.parent[k]]
        self.X[: self.n][dead] = np.inf

    def branch(self, i: int) -> Array:
        """Configurations from the root down to node i, (m, K)."""
        chain = []
        while i >= 0:
            chain.append(self.X[i])
            i = int(self.parent[i])
        return np.array(chain[::-1])


class BiTrees:
    """The start tree (``trees[0]``, rooted at q_start (K,)) and the goal tree (``trees[1]``,
    rooted at every row of Q_goal (n, K)); steps of at most ``step`` rad (joint-space norm)."""

    def __init__(self, q_start: Array, Q_goal: Array, free: MotionFn, step: float) -> None:
        self.trees = (Tree(q_start), Tree(Q_goal))
        self.free = free
        self.step = step

    @property
    def n_nodes(self) -> int:
        return self.trees[0].n + self.trees[1].n

    def toward(self, q_from: Array, q_to: Array) -> Array:
        d = q_to - q_from
        n = float(np.linalg.norm(d))
        return q_to if n <= self.step else q_from + d * (self.step / n)

    def extend(self, a: int, q: Array) -> int | None:
        """Tree a's new node one step from its nearest node towards q, or None (blocked)."""
        tree = self.trees[a]
        i = tree.nearest(q)
        q_new = self.toward(tree.X[i], q)
        if not self.free(tree.X[i], q_new):
            return None
        return tree.add(q_new, i)

    def connect(self, b: int, q: Array, deadline: float = math.inf) -> int | None:
        """Pull tree b straight towards q in steps; its node at q when it gets there (None
        when blocked, or at ``deadline``, a ``time.perf_counter()`` value)."""
        tree = self.trees[b]
        i = tree.nearest(q)
        while True:
            if time.perf_counter() >= deadline:
                return None
            q_new = self.toward(tree.X[i], q)
            if not self.free(tree.X[i], q_new):
                return None
            i = tree.add(q_new, i)
            if np.array_equal(q_new, q):
                return i

    def refused_edge(self, a: int, i_a: int, i_b: int, certify: MotionFn,
                     passed: set[tuple[int, int]]) -> tuple[int, int] | None:
        """The first edge (tree, child node) on the path :meth:`join` would give that
        ``certify(parent, child)`` refuses, or None; edges that passed are added to
        ``passed`` and not asked again."""
        for t, i in ((a, i_a), (1 - a, i_b)):
            tree = self.trees[t]
            while tree.parent[i] >= 0:
                if (t, i) not in passed:
                    if not certify(tree.X[tree.parent[i]], tree.X[i]):
                        return t, i
                    passed.add((t, i))
                i = int(tree.parent[i])
        return None

    def join(self, a: int, i_a: int, i_b: int) -> Array:
        """The path (m, K), start → goal, through tree a's node i_a and tree (1 - a)'s node
        i_b (the same configuration)."""
        ends = {a: self.trees[a].branch(i_a), 1 - a: self.trees[1 - a].branch(i_b)}
        return np.vstack([ends[0], ends[1][::-1][1:]])


@dataclass(frozen=True, eq=False)
class TreeSearch:
    """What :func:`rrt_connect` found.

    Attributes:
        path: (T, K) rad from the start to one goal configuration, or None.
        status: "solved", "exhausted" (``max_nodes`` reached) or "timeout" (the deadline).
        n_nodes: tree nodes grown (both trees, roots included).
    """

    path: Array | None
    status: str
    n_nodes: int


def rrt_connect(q_start: Array, Q_goal: Array, free: MotionFn, sample: Callable[[], Array],
                *, step: float, max_nodes: int, deadline: float = math.inf,
                certify: MotionFn | None = None) -> TreeSearch:
    """RRT-Connect from q_start (K,) to any row of Q_goal (n, K), both free: alternately
    extend one tree towards ``sample()`` (K,) and pull the other to the new node. Stops when
    they meet, after ``max_nodes`` nodes, or at ``deadline`` (``time.perf_counter()`` value;
    inf: only the node count bounds it, and a seeded ``sample`` makes the answer
    reproducible).

    ``certify`` (a stricter motion test than ``free``, e.g. the exact checker's at the
    certification's substeps) is asked, lazily, only about the edges of a path found: a
    refused edge's subtree is pruned and the search goes on. (One that keeps the deadline by
    refusing once it has passed only prunes what the search, ending then, no longer needs.)
    """
    bi = BiTrees(q_start, Q_goal, free, step)
    passed: set[tuple[int, int]] = set()
    a = 0
    while bi.n_nodes < max_nodes:
        if time.perf_counter() >= deadline:
            return TreeSearch(None, "timeout", bi.n_nodes)
        i_new = bi.extend(a, sample())
        if i_new is not None:
            j = bi.connect(1 - a, bi.trees[a].X[i_new], deadline)
            if j is not None:
                refused = None if certify is None else bi.refused_edge(a, i_new, j, certify,
                                                                       passed)
                if refused is None:
                    return TreeSearch(bi.join(a, i_new, j), "solved", bi.n_nodes)
                bi.trees[refused[0]].prune(refused[1])
        a = 1 - a
    return TreeSearch(None, "exhausted", bi.n_nodes)
