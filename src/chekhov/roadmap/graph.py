"""The built roadmap: nodes, edges, all-pairs shortest paths, stored k shortest paths."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.path_check import CERTIFICATION_ID
from chekhov.roadmap.config import RoadmapConfig
from chekhov.roadmap.search import recover_path, yen_k_shortest

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

FORMAT_VERSION = 1
NODE_KINDS: tuple[str, ...] = ("uniform", "pregrasp", "region", "wrist")


def edges_certified(config: RoadmapConfig, notes: dict[str, object]) -> bool:
    """Whether a roadmap's edges passed this code's certification of a segment
    (``certify_edges``, and its notes name ``path_check.CERTIFICATION_ID``): a route's
    check may then rest on them, and a cached file without it is rebuilt."""
    return bool(config.certify_edges and notes.get("edges_certified_by") == CERTIFICATION_ID)


@dataclass(frozen=True)
class RoadmapMeta:
    """What a roadmap was built for and how.

    Attributes:
        format_version: file format (``FORMAT_VERSION`` when written by this code).
        robot: robot name; scene: scene name; scene_hash: ``Scene.content_hash()``.
        robot_hash: ``Robot.content_hash()`` (URDF, locked joints, spheres, base pose; "" in
            files written before it was recorded, which then match no robot).
        build_s: wall time of the build, s. created: UTC time, ISO 8601.
        dropped_nodes: nodes outside the largest connected component, removed.
        node_counts: nodes per kind after pruning, e.g. {"uniform": 995, ...}.
        notes: build facts worth reporting (pre-grasps without IK, candidate edges checked …).
    """

    format_version: int
    robot: str
    scene: str
    scene_hash: str
    config: RoadmapConfig
    build_s: float
    created: str
    dropped_nodes: int
    node_counts: dict[str, int] = field(default_factory=dict)
    notes: dict[str, object] = field(default_factory=dict)
    robot_hash: str = ""


@dataclass(frozen=True, eq=False)
class Roadmap:
    """A roadmap over the static obstacles of one scene (N nodes, E undirected edges).

    Attributes:
        nodes: (N, K) configurations, rad.
        node_kind: (N,) index into ``NODE_KINDS``.
        node_label: (N,) e.g. ``"box_0_0/front"`` for pre-grasp nodes, ``""`` otherwise.
        ee_position: (N, 3) end-effector position of each node, world, m.
        ee_rotation: (N, 3, 3) end-effector rotation of each node, world.
        edges: (E, 2) node pairs, i < j. edge_length: (E,) joint-space L2 length, rad.
        indptr, indices, weights, edge_id: CSR adjacency (both directions, sorted rows).
        dist: (N, N) float32 shortest-path length, rad (inf: unreachable).
        pred: (N, N) int16 or int32 predecessor matrix (scipy's convention, -9999: none).
        kpath_key: (M, 3) int32 rows (src, dst, rank) of stored k shortest paths;
            kpath_ptr (M + 1,), kpath_nodes: their nodes, concatenated.
        meta: what and how it was built.
    """

    nodes: Array
    node_kind: NDArray[np.int8]
    node_label: NDArray[np.str_]
    ee_position: Array
    ee_rotation: Array
    edges: NDArray[np.int32]
    edge_length: Array
    indptr: IntArray
    indices: IntArray
    weights: Array
    edge_id: IntArray
    dist: NDArray[np.float32]
    pred: NDArray[np.integer]
    kpath_key: NDArray[np.int32]
    kpath_ptr: IntArray
    kpath_nodes: NDArray[np.int32]
    meta: RoadmapMeta

    @property
    def config(self) -> RoadmapConfig:
        return self.meta.config

    @property
    def n_nodes(self) -> int:
        return len(self.nodes)

    @property
    def n_edges(self) -> int:
        return len(self.edges)

    def nodes_of_kind(self, kind: str) -> IntArray:
        """Indices of the nodes of one family (see ``NODE_KINDS``)."""
        return np.flatnonzero(self.node_kind == NODE_KINDS.index(kind))

    @property
    def semantic_nodes(self) -> IntArray:
        """Pre-grasp nodes (those guaranteed on the roadmap by semantic sampling)."""
        return self.nodes_of_kind("pregrasp")

    def shortest_path(self, src: int, dst: int) -> IntArray:
        """Node indices of the cached shortest path src → dst; empty when unreachable."""
        return recover_path(self.pred[src], int(src), int(dst))

    def path_configurations(self, node_path: IntArray) -> Array:
        return self.nodes[np.asarray(node_path, dtype=np.int64)]

    def k_shortest(self, src: int, dst: int, k: int) -> list[tuple[float, IntArray]]:
        """Up to k loopless paths src → dst (Yen), shortest first, as (length rad, nodes)."""
        return yen_k_shortest(self.indptr, self.indices, self.weights, self.edge_id, int(src),
                              int(dst), k, heuristic=self.dist[:, dst].astype(np.float64))

    def stored_k_paths(self) -> dict[tuple[int, int], list[IntArray]]:
        """The k shortest paths precomputed at build time, keyed by (src, dst)."""
        out: dict[tuple[int, int], list[IntArray]] = {}
        for m, (a, b, _rank) in enumerate(self.kpath_key):
            nodes = self.kpath_nodes[self.kpath_ptr[m]:self.kpath_ptr[m + 1]].astype(np.int64)
            out.setdefault((int(a), int(b)), []).append(nodes)
        return out

    @property
    def nbytes(self) -> int:
        """Memory held by the roadmap's arrays (bytes)."""
        return int(sum(getattr(self, f).nbytes for f in (
            "nodes", "node_kind", "node_label", "ee_position", "ee_rotation", "edges",
            "edge_length", "indptr", "indices", "weights", "edge_id", "dist", "pred",
            "kpath_key", "kpath_ptr", "kpath_nodes")))

    @property
    def kpaths_nbytes(self) -> int:
        """Memory of the stored k shortest paths (bytes)."""
        return int(self.kpath_key.nbytes + self.kpath_ptr.nbytes + self.kpath_nodes.nbytes)

    def summary(self) -> dict[str, object]:
        """Figures for ``chekhov roadmap info`` and the benchmark."""
        m = self.meta
        finite = np.isfinite(self.dist)
        return {
            "robot": m.robot, "scene": m.scene, "scene_hash": m.scene_hash[:16],
            "format_version": m.format_version, "created": m.created,
            "build_s": round(m.build_s, 3), "nodes": self.n_nodes, "edges": self.n_edges,
            "dropped_nodes": m.dropped_nodes, "node_counts": m.node_counts,
            "mean_degree": round(2 * self.n_edges / max(1, self.n_nodes), 2),
            "mean_edge_rad": round(float(self.edge_length.mean()), 4) if self.n_edges else 0.0,
            "connected": bool(finite.all()),
            "stored_k_paths": len(self.kpath_key), "k_paths": m.config.k_paths,
            "roadmap_bytes": self.nbytes, "kpaths_bytes": self.kpaths_nbytes,
            "config": m.config.to_dict(), "notes": m.notes,
        }
