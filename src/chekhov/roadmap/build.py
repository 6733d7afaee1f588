"""Offline roadmap construction against a scene's static obstacles (the paper's PRM variant
plus semantic and wrist node families, see :class:`RoadmapConfig`)."""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable
from datetime import UTC, datetime
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, shortest_path
from scipy.spatial import cKDTree

from chekhov.collision.exact import ExactChecker
from chekhov.collision.fast import FastChecker
from chekhov.collision.path_check import CERTIFICATION_ID, motion_certified
from chekhov.roadmap.config import RoadmapConfig
from chekhov.roadmap.errors import RoadmapError
from chekhov.roadmap.graph import FORMAT_VERSION, NODE_KINDS, Roadmap, RoadmapMeta
from chekhov.roadmap.search import csr_adjacency, yen_k_shortest
from chekhov.robot.chain_kinematics import ChainKinematics
from chekhov.world import World

Array = NDArray[np.float64]
Progress = Callable[[str], None]
_EDGE_CHUNK = 4000


def distal_values(world: World, config: RoadmapConfig) -> tuple[int, Array]:
    """(number of proximal joints, values of the distal joints, rad) for uniform nodes."""
    desc = world.robot.description
    P = desc.proximal_joints if config.proximal_joints is None else config.proximal_joints
    K = world.robot.dof
    if not 1 <= P <= K:
        raise RoadmapError(f"roadmap: proximal_joints must be in 1..{K}, got {P}")
    values = config.distal_values if config.distal_values is not None else (
        desc.roadmap_fixed if desc.roadmap_fixed else (0.0,) * (K - P))
    if len(values) != K - P:
        raise RoadmapError(f"roadmap: {K - P} distal joint values needed for robot "
                           f"'{world.robot.name}', got {len(values)}")
    return P, np.asarray(values, dtype=float)


def random_rotations(rng: np.random.Generator, n: int) -> Array:
    """n rotation matrices (n, 3, 3) uniform over SO(3) (normalised Gaussian quaternions)."""
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=1)


class _Builder:
    def __init__(self, world: World, config: RoadmapConfig, progress: Progress | None) -> None:
        self.world = world
        self.config = config
        self.say: Progress = progress or (lambda _msg: None)
        self.rng = np.random.default_rng(config.seed)
        self.robot = world.robot
        self.fast = FastChecker(world.robot, world.scene, static_only=True)
        self.exact = ExactChecker(world.robot, world.scene)
        self._uncertified = 0
        self.kin = ChainKinematics.from_robot(world.robot)
        self.notes: dict[str, object] = {}

    # --- nodes ------------------------------------------------------------------------
    def uniform_nodes(self) -> Array:
        n = self.config.n_nodes
        P, distal = distal_values(self.world, self.config)
        out: list[Array] = []
        have, drawn = 0, 0
        while have < n:
            batch = max(256, 2 * (n - have))
            Q = self.robot.sample_uniform(self.rng, batch)
            Q[:, P:] = distal
            drawn += batch
            Q = Q[self.fast.valid(Q)]
            out.append(Q)
            have += len(Q)
            if drawn > 200 * n:
                raise RoadmapError(f"roadmap: only {have} of {n} collision-free samples in "
                                   f"{drawn} draws; {self._what_collides()}")
        Q = np.concatenate(out)[:n]
        self.notes["uniform_free_fraction"] = round(have / drawn, 4)
        return Q

    def _what_collides(self, n: int = 50) -> str:
        """What the exact checker finds colliding most often at ``n`` random configurations
        (sampled as the roadmap's uniform nodes are): the reason it finds no free samples."""
        P, distal = distal_values(self.world, self.config)
        Q = self.robot.sample_uniform(np.random.default_rng(0), n)
        Q[:, P:] = distal
        seen: Counter[tuple[str, ...]] = Counter()
        for q in Q:
            seen.update({tuple(sorted(p)) for p in self.exact.colliding_pairs(q)})
        top = ", ".join(f"{' / '.join(p)} ({k} of {n})" for p, k in seen.most_common(3))
        if not top:
            return "is the robot stuck in an obstacle?"
        return (f"the geometries most often in collision: {top} (an obstacle where the robot "
                f"stands, or two links whose meshes overlap: an SRDF's disable_collisions "
                f"leaves a pair out)")

    def _ik_nodes(self, T_world_ee: Array, seeds: Array, n_max: int, existing: list[Array]
                  ) -> list[Array]:
        """Up to n_max collision-free IK solutions from the seeds, at least 0.1 rad from each
        other and from ``existing``."""
        Q, ok = self.kin.solve(T_world_ee, seeds)
        Q = Q[ok]
        if len(Q) == 0:
            return []
        Q = Q[self.fast.valid(Q)]
        found: list[Array] = []
        for q in Q:
            if all(np.linalg.norm(q - s) >= 0.1 for s in found + existing):
                found.append(q)
                if len(found) >= n_max:
                    break
        return found

    def _seeds_near(self, tree: cKDTree, base: Array, p_world: Array, n_near: int,
                    n_random: int) -> Array:
        _, idx = tree.query(p_world, k=min(n_near, len(base)))
        return np.vstack([base[np.atleast_1d(idx)], self.robot.sample_uniform(self.rng,
                                                                               n_random)])

    def pregrasp_nodes(self, base: Array, tree: cKDTree) -> tuple[list[Array], list[str]]:
        nodes: list[Array] = []
        labels: list[str] = []
        missing: list[str] = []
        for obj in self.world.scene.objects:
            for label, T in obj.pregrasp_poses():
                seeds = self._seeds_near(tree, base, T[:3, 3], 24, 24)
                found = self._ik_nodes(T, seeds, self.config.pregrasp_solutions, [])
                if not found:
                    missing.append(label)
                nodes += found
                labels += [label] * len(found)
        self.notes["pregrasps_without_ik"] = missing
        return nodes, labels

    def region_nodes(self, base: Array, tree: cKDTree) -> list[Array]:
        regions = [r for r in self.world.scene.regions if r.weight > 0]
        n = self.config.n_region_nodes
        if not regions or n == 0:
            return []
        w = np.array([r.weight for r in regions])
        nodes: list[Array] = []
        attempts = 0
        while len(nodes) < n and attempts < 6 * n:
            attempts += 1
            region = regions[int(self.rng.choice(len(regions), p=w / w.sum()))]
            T = np.eye(4)
            T[:3, :3] = random_rotations(self.rng, 1)[0]
            T[:3, 3] = region.sample(self.rng, 1)[0]
            seeds = self._seeds_near(tree, base, T[:3, 3], 4, 2)
            nodes += self._ik_nodes(T, seeds, 1, [])
        self.notes["region_ik_attempts"] = attempts
        return nodes

    def wrist_nodes(self, base: Array) -> Array:
        """Up to ``n_wrist_nodes`` copies of uniform nodes with random distal joints; none
        when every joint is sampled (the copies would be duplicates: a URDF robot's 990 of
        them gave zero-length self-loop edges, and the saved roadmap did not load)."""
        n = self.config.n_wrist_nodes
        P, _ = distal_values(self.world, self.config)
        if n == 0 or self.robot.dof - P == 0:
            return np.empty((0, self.robot.dof))
        out: list[Array] = []
        have = 0
        for _ in range(200):
            Q = base[self.rng.integers(0, len(base), size=2 * n)].copy()
            Q[:, P:] = self.rng.uniform(self.robot.lower[P:], self.robot.upper[P:],
                                        size=(len(Q), self.robot.dof - P))
            Q = Q[self.fast.valid(Q)]
            out.append(Q)
            have += len(Q)
            if have >= n:
                break
        return np.concatenate(out)[:n]

    # --- edges ------------------------------------------------------------------------
    def _edges_free(self, A: Array, B: Array) -> NDArray[np.bool_]:
        """Which straight edges A[i] → B[i] (N, K) are free: the fast checker's motion check at
        the config's resolution, and with ``certify_edges`` the certification's own check
        (counted in ``_uncertified`` where only that fails)."""
        ok = self.fast.motions_valid(A, B, self.config.resolution)
        if self.config.certify_edges:
            for i in np.flatnonzero(ok):
                if not motion_certified(self.fast, self.exact, A[i], B[i]):
                    ok[i] = False
                    self._uncertified += 1
        return ok

    def connect(self, nodes: Array) -> tuple[NDArray[np.int64], Array]:
        cfg = self.config
        N = len(nodes)
        n_cand = min(cfg.max_neighbor_candidates, N - 1)
        _, nbr = cKDTree(nodes).query(nodes, k=n_cand + 1)
        nbr = nbr[:, 1:]
        degree_valid = np.zeros(N, dtype=np.int64)
        checked: dict[tuple[int, int], bool] = {}
        n_checked = 0
        for lo in range(0, n_cand, cfg.k_neighbors):
            need = np.flatnonzero(degree_valid < cfg.k_neighbors)
            if len(need) == 0:
                break
            pairs = {(min(i, j), max(i, j)) for i in need.tolist()
                     for j in nbr[i, lo:lo + cfg.k_neighbors].tolist()}
            todo = np.array(sorted(p for p in pairs if p not in checked), dtype=np.int64)
            todo = todo.reshape(-1, 2)
            for c in range(0, len(todo), _EDGE_CHUNK):
                chunk = todo[c:c + _EDGE_CHUNK]
                ok = self._edges_free(nodes[chunk[:, 0]], nodes[chunk[:, 1]])
                for (a, b), v in zip(chunk.tolist(), ok.tolist(), strict=True):
                    checked[(a, b)] = v
                    if v:
                        degree_valid[a] += 1
                        degree_valid[b] += 1
                n_checked += len(chunk)
                self.say(f"  edges: {n_checked} candidate edges checked, "
                         f"{sum(checked.values())} free")
        self.notes["candidate_edges_checked"] = n_checked
        self.notes["edges_failing_certification"] = self._uncertified
        if cfg.certify_edges:   # what they passed (a route's check may rest on it)
            self.notes["edges_certified_by"] = CERTIFICATION_ID
        edges = np.array(sorted(p for p, v in checked.items() if v), dtype=np.int64)
        edges = edges.reshape(-1, 2)
        lengths = np.linalg.norm(nodes[edges[:, 1]] - nodes[edges[:, 0]], axis=1)
        return edges, lengths


class _NodeSet(NamedTuple):
    """The roadmap's nodes: configurations (N, K) rad, family (N,) int8 (index into
    ``NODE_KINDS``) and label (N,) str (the grasp of a pre-grasp node, else "")."""

    q: Array
    kind: NDArray[np.int8]
    label: NDArray[np.str_]


class _Graph(NamedTuple):
    """The largest connected component: its nodes, edges (E, 2) node indices, edge lengths
    (E,) rad, how many nodes were dropped and how many components there were."""

    nodes: _NodeSet
    edges: NDArray[np.int64]
    lengths: Array
    dropped: int
    n_components: int


def build_roadmap(world: World, config: RoadmapConfig | None = None,
                  progress: Progress | None = None) -> Roadmap:
    """Build a roadmap for ``world``'s scene and robot against its static obstacles only.

    ``progress`` receives one-line messages (e.g. ``print``) during long builds.
    """
    config = config or RoadmapConfig()
    t0 = time.perf_counter()
    b = _Builder(world, config, progress)
    say = b.say
    sampled = _sample_nodes(b)
    say(f"  connecting {len(sampled.q)} nodes to their {config.k_neighbors} nearest free "
        "neighbours")
    g = _largest_component(sampled, *b.connect(sampled.q))
    nodes, edges, lengths = g.nodes, g.edges, g.lengths
    N = len(nodes.q)
    say(f"  largest component: {N} nodes, {len(edges)} edges ({g.dropped} dropped, "
        f"{g.n_components} components); all-pairs shortest paths")
    A = coo_matrix((lengths, (edges[:, 0], edges[:, 1])), shape=(N, N)).tocsr()
    dist, pred = shortest_path(A, method="D", directed=False, return_predecessors=True)
    pred = pred.astype(np.int16 if N < 32767 else np.int32)
    indptr, indices, weights, edge_id = csr_adjacency(N, edges, lengths)
    R, p = b.kin.ee_poses(nodes.q)
    sem = np.flatnonzero(nodes.kind == 1)
    keys, chunks = _semantic_k_paths(sem, dist, (indptr, indices, weights, edge_id),
                                     config.k_paths)
    kpath_ptr = np.zeros(len(chunks) + 1, dtype=np.int64)
    np.cumsum([len(c) for c in chunks], out=kpath_ptr[1:])
    say(f"  {len(keys)} stored k-shortest paths between {len(sem)} semantic nodes")
    build_s = time.perf_counter() - t0
    meta = RoadmapMeta(
        format_version=FORMAT_VERSION, robot=world.robot.name, scene=world.scene.name,
        scene_hash=world.scene.content_hash(), robot_hash=world.robot.content_hash(),
        config=config, build_s=build_s,
        created=datetime.now(UTC).isoformat(timespec="seconds"), dropped_nodes=g.dropped,
        node_counts={k: int((nodes.kind == i).sum()) for i, k in enumerate(NODE_KINDS)},
        notes=b.notes)
    say(f"  built in {build_s:.1f} s")
    return Roadmap(
        nodes=nodes.q, node_kind=nodes.kind, node_label=nodes.label, ee_position=p,
        ee_rotation=R, edges=edges.astype(np.int32), edge_length=lengths, indptr=indptr,
        indices=indices, weights=weights, edge_id=edge_id, dist=dist.astype(np.float32),
        pred=pred, kpath_key=np.array(keys, dtype=np.int32).reshape(-1, 3),
        kpath_ptr=kpath_ptr,
        kpath_nodes=(np.concatenate(chunks) if chunks else np.empty(0)).astype(np.int32),
        meta=meta)


def _sample_nodes(b: _Builder) -> _NodeSet:
    """Every node family, in ``NODE_KINDS`` order: uniform, then (``config.semantic``)
    pre-grasp and region nodes, then wrist nodes."""
    config, say = b.config, b.say
    say(f"roadmap for '{b.world.scene.name}': sampling {config.n_nodes} uniform nodes")
    uniform = b.uniform_nodes()
    _, p = b.kin.ee_poses(uniform)
    tree = cKDTree(p)
    groups: list[tuple[int, Array, list[str]]] = [
        (0, uniform, [""] * len(uniform))]
    if config.semantic:
        pg, labels = b.pregrasp_nodes(uniform, tree)
        say(f"  semantic: {len(pg)} pre-grasp nodes")
        if pg:
            groups.append((1, np.array(pg), labels))
        rn = b.region_nodes(uniform, tree)
        say(f"  semantic: {len(rn)} region nodes")
        if rn:
            groups.append((2, np.array(rn), [""] * len(rn)))
    wn = b.wrist_nodes(uniform)
    if len(wn):
        say(f"  {len(wn)} wrist nodes")
        groups.append((3, wn, [""] * len(wn)))
    return _NodeSet(np.concatenate([g[1] for g in groups]),
                    np.concatenate([np.full(len(g[1]), g[0], dtype=np.int8) for g in groups]),
                    np.array([s for g in groups for s in g[2]], dtype=np.str_))


def _largest_component(nodes: _NodeSet, edges: NDArray[np.int64], lengths: Array) -> _Graph:
    """The largest connected component of the graph, nodes renumbered; edge lengths at least
    1e-9 rad (csgraph reads explicit zeros as no edge)."""
    N = len(nodes.q)
    lengths = np.maximum(lengths, 1e-9)
    A = coo_matrix((lengths, (edges[:, 0], edges[:, 1])), shape=(N, N)).tocsr()
    n_comp, comp = connected_components(A, directed=False)
    keep = comp == np.argmax(np.bincount(comp))
    new_index = np.cumsum(keep) - 1
    e_keep = keep[edges[:, 0]] & keep[edges[:, 1]]
    kept = _NodeSet(nodes.q[keep], nodes.kind[keep], nodes.label[keep])
    return _Graph(kept, new_index[edges[e_keep]], lengths[e_keep], int(N - keep.sum()),
                  int(n_comp))


def _semantic_k_paths(sem: NDArray[np.int64], dist: Array,
                      csr: tuple[NDArray[np.int64], NDArray[np.int64], Array,
                                 NDArray[np.int64]], k_paths: int
                      ) -> tuple[list[tuple[int, int, int]], list[NDArray[np.int64]]]:
    """Yen's k shortest paths between every pair (a < b) of semantic nodes ``sem``, with the
    all-pairs distances ``dist`` (N, N) rad as A*'s heuristic: the keys (a, b, rank) and the
    node paths. ``csr``: the adjacency (indptr, indices, weights, edge_id)."""
    keys: list[tuple[int, int, int]] = []
    chunks: list[NDArray[np.int64]] = []
    heuristic_cols = {int(j): dist[:, j].astype(np.float64) for j in sem}
    for ai, a in enumerate(sem):
        for bb in sem[ai + 1:]:
            for rank, (_, path) in enumerate(yen_k_shortest(
                    *csr, int(a), int(bb), k_paths, heuristic=heuristic_cols[int(bb)])):
                keys.append((int(a), int(bb), rank))
                chunks.append(path)
    return keys, chunks
