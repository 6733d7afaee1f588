"""Lazy validity of roadmap nodes and edges against the world's current (dynamic) obstacles.

The roadmap is free of the static obstacles by construction, so nothing needs checking while
the fast checker holds no dynamic obstacle. Otherwise nodes and edges are checked on demand,
only along candidate paths, and the answers are cached until ``FastChecker.obstacles_version``
changes (any obstacle added, moved or removed).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.codes import INVALID, UNKNOWN, VALID
from chekhov.collision.fast import FastChecker
from chekhov.roadmap.graph import Roadmap

IntArray = NDArray[np.int64]


class RoadmapValidity:
    """Per-node and per-edge validity cache (int8: -1 unknown, 0 invalid, 1 valid)."""

    def __init__(self, roadmap: Roadmap, fast: FastChecker, resolution: float) -> None:
        self.roadmap = roadmap
        self.fast = fast
        self.resolution = float(resolution)
        self.node_state = np.full(roadmap.n_nodes, UNKNOWN, dtype=np.int8)
        self.edge_state = np.full(roadmap.n_edges, UNKNOWN, dtype=np.int8)
        self.version = -1
        self.all_valid = True
        self.checks = {"nodes": 0, "edges": 0}
        self.refresh()

    def refresh(self) -> None:
        """Drop cached answers if the obstacles changed since they were computed."""
        if self.fast.obstacles_version == self.version:
            return
        self.version = self.fast.obstacles_version
        self.all_valid = len(self.fast.dynamic_obstacles) == 0
        fill = VALID if self.all_valid else UNKNOWN
        self.node_state.fill(fill)
        self.edge_state.fill(fill)

    def nodes_valid(self, idx: IntArray) -> NDArray[np.bool_]:
        """Validity of nodes ``idx`` (checked and cached where unknown)."""
        idx = np.asarray(idx, dtype=np.int64)
        if self.all_valid:
            return np.ones(len(idx), dtype=np.bool_)
        todo = np.unique(idx[self.node_state[idx] == UNKNOWN])
        if len(todo):
            ok = self.fast.valid(self.roadmap.nodes[todo])
            self.node_state[todo] = np.where(ok, VALID, INVALID)
            self.checks["nodes"] += len(todo)
        return self.node_state[idx] == VALID

    def edges_valid(self, eids: IntArray) -> NDArray[np.bool_]:
        """Validity of edges ``eids`` (interior of the straight motion; end points are nodes,
        checked by :meth:`nodes_valid`)."""
        eids = np.asarray(eids, dtype=np.int64)
        if self.all_valid:
            return np.ones(len(eids), dtype=np.bool_)
        todo = np.unique(eids[self.edge_state[eids] == UNKNOWN])
        if len(todo):
            e = self.roadmap.edges[todo]
            ok = self.fast.motions_valid(self.roadmap.nodes[e[:, 0]], self.roadmap.nodes[e[:, 1]],
                                         self.resolution)
            self.edge_state[todo] = np.where(ok, VALID, INVALID)
            self.checks["edges"] += len(todo)
        return self.edge_state[eids] == VALID

    def path_valid(self, node_path: IntArray, edge_ids: IntArray) -> bool:
        """Whether every node and edge of a roadmap path is free (stops at the first failure
        class: nodes are checked before edges)."""
        if self.all_valid:
            return True
        if not self.nodes_valid(node_path).all():
            return False
        return bool(self.edges_valid(edge_ids).all())
