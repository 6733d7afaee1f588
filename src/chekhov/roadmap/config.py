"""Roadmap build settings."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from typing import Any

from chekhov._config_checks import in_unit_interval, int_at_least
from chekhov.roadmap.errors import RoadmapError


@dataclass(frozen=True)
class RoadmapConfig:
    """How a roadmap is built.

    Node families (``Roadmap.node_kind``):

    * ``uniform`` (the paper's scheme): ``n_nodes`` collision-free samples, uniform over the
      first ``proximal_joints`` joints, the distal joints at ``distal_values``.
    * ``pregrasp`` (semantic, ``semantic``): IK configurations (full K-DOF) of every
      pre-grasp pose of every object and articulation state, ``pregrasp_solutions`` each.
    * ``region`` (semantic, ``semantic``): ``n_region_nodes`` end-effector poses drawn in the
      scene's regions of interest by weight (random orientation), IK to collision-free
      configurations.
    * ``wrist`` (an extension; 0 turns it off, and there are none when every joint is
      sampled — ``proximal_joints`` = K): ``n_wrist_nodes`` copies of random uniform
      nodes with the distal joints drawn uniformly, so that starts and goals with arbitrary
      wrists find a near roadmap node (shorter, cheaper, more often free connections).

    Attributes:
        n_nodes: collision-free uniform nodes to sample.
        k_neighbors: each node is joined to this many nearest neighbours (joint-space L2) whose
            straight edge is collision-free; up to ``max_neighbor_candidates`` are tried.
        resolution: rad, joint-space step at which edges are checked (the ``resolution`` of
            ``FastChecker.motions_valid``).
        proximal_joints: leading joints sampled by ``uniform`` nodes; None: the robot's.
        distal_values: rad, values of the other joints for ``uniform`` nodes; None: the robot
            description's ``roadmap_fixed`` (zeros if it has none).
        semantic: add ``pregrasp`` and ``region`` nodes.
        n_region_nodes: region-biased nodes to add when ``semantic``.
        pregrasp_solutions: distinct IK configurations per pre-grasp pose.
        n_wrist_nodes: extra nodes with random distal joints (0: none).
        k_paths: loopless paths stored per node pair (Yen), ≥ 1.
        certify_edges: each edge the fast checker passes is also put through the check a
            certified path's segment faces (exact decision, 0.0016 rad apart:
            :func:`~chekhov.collision.path_check.motion_certified`), and dropped when it
            fails (about 0.4 ms an edge: the shelf's build 3 → 9 s; 14 of its 14 000 edges
            failed, on popular routes: every answer using one had waited for TrajOpt). Files
            from before it read False.
        seed: random seed of the whole build.
    """

    n_nodes: int = 1000
    k_neighbors: int = 10
    max_neighbor_candidates: int = 30
    resolution: float = 0.02
    proximal_joints: int | None = None
    distal_values: tuple[float, ...] | None = None
    semantic: bool = True
    n_region_nodes: int = 200
    pregrasp_solutions: int = 2
    n_wrist_nodes: int = 1000
    k_paths: int = 3
    certify_edges: bool = True
    seed: int = 0

    def __post_init__(self) -> None:
        if self.n_nodes < 2:
            raise RoadmapError(f"roadmap config: n_nodes must be ≥ 2, got {self.n_nodes}")
        if self.k_neighbors < 1 or self.max_neighbor_candidates < self.k_neighbors:
            raise RoadmapError("roadmap config: need 1 ≤ k_neighbors ≤ max_neighbor_candidates, "
                               f"got {self.k_neighbors}, {self.max_neighbor_candidates}")
        if not self.resolution > 0:
            raise RoadmapError(f"roadmap config: resolution must be > 0 rad, got "
                               f"{self.resolution}")
        if self.k_paths < 1:
            raise RoadmapError(f"roadmap config: k_paths must be ≥ 1, got {self.k_paths}")
        for name in ("n_region_nodes", "n_wrist_nodes", "pregrasp_solutions"):
            if getattr(self, name) < 0:
                raise RoadmapError(f"roadmap config: {name} must be ≥ 0")
        if self.distal_values is not None:
            object.__setattr__(self, "distal_values",
                               tuple(float(v) for v in self.distal_values))

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> RoadmapConfig:
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise RoadmapError(f"roadmap config: unknown field(s) {sorted(unknown)}")
        kw = dict(d)
        kw.setdefault("certify_edges", False)     # files from before it: not certified
        if kw.get("distal_values") is not None:
            kw["distal_values"] = tuple(kw["distal_values"])
        return cls(**kw)


@dataclass(frozen=True)
class RepairConfig:
    """Settings of :class:`TreeRepair`.

    Attributes:
        range_fraction: longest tree step, as a fraction of the joint space's diagonal
            (OMPL RRTConnect's default 0.2).
        attach_candidates: nearest valid roadmap nodes an extend node tries to reach.
        attach_every: only every n-th extend node tries (the attempts cost motion checks
            the trees need too: measured in a kitchen pocket, trying every node with 2
            candidates made the search 1.5-1.8x slower).
        route_pairs: roadmap routes tried for each new attachment (nearest by roadmap distance).
        max_nodes: tree nodes (both trees) after which the search gives up.
        goal_roots: goal IK solutions the goal tree grows from (a pose goal's; RRTConnect's
            OMPL planner here uses 4: more roots, more ways in).
        seed: seed of the samples (a fresh generator per search: same query, same answer).
    """

    range_fraction: float = 0.2
    attach_candidates: int = 1
    attach_every: int = 4
    route_pairs: int = 2
    max_nodes: int = 50_000
    goal_roots: int = 8
    seed: int = 0

    def __post_init__(self) -> None:
        in_unit_interval("RepairConfig", "range_fraction", self.range_fraction)
        int_at_least("RepairConfig", "attach_every", self.attach_every, 1)
        for name in ("attach_candidates", "route_pairs", "max_nodes", "goal_roots"):
            int_at_least("RepairConfig", name, getattr(self, name), 0)


@dataclass(frozen=True)
class SeederConfig:
    """Query settings.

    Attributes:
        n_goal_ik: distinct IK solutions wanted for a pose goal (:meth:`RoadmapSeeder.seeds`
            asks for more when it is to route to more).
        ik_seeds: roadmap nodes (nearest end-effector pose to the goal) that seed the IK.
        ik_random_seeds, ik_random_rounds: random restarts per round, and rounds, tried only
            when the node seeds give no collision-free solution.
        connect_candidates: nearest roadmap nodes tried for a direct connection (rad L2).
        max_connections: free connections kept per end point; the seed minimises
            start cost + roadmap distance + goal cost over their combinations.
        bridges: when no direct connection exists, try two-segment connections through an
            intermediate configuration (wrist set to the roadmap's distal values, proximal
            joints moved first, or a random nearby configuration).
        bridge_samples: random intermediates tried, at ``bridge_radius`` rad at most.
        tree_nodes, tree_step, tree_time_s: size, step (rad) and time budget (s) of the
            RRT grown from an end point nothing else connects (``roadmap.connect``). Only
            end points in narrow pockets get here (8 of 1,200 first answers, 100 random and
            100 task cases in each of six scenes, 2026-11-30). An end it leaves unconnected
            is not given up: the query goes on to the tree repair (``repair``), which grows
            from both ends into the whole roadmap until the time limit. In those 8 cases the
            trees that connected took 2.6-27 ms, and 117 ms once (kitchen), where the repair
            found a path 2.6 times shorter in 39 ms; one ran its whole 0.5 s (the default
            then) for nothing, where the repair then took 0.6 ms. At 0.05 s: those two 520 →
            70 and 233 → 115 ms, the others the same; benchmarks/completeness.py (boxed,
            empty_roadmap, dynamic; 40 cases each in shelf_boxes, panda_cage, kitchen) still
            solves every case RRTConnect solves, at the same times. (Before the repair,
            0.5 s was needed: 50 ms left 0.6% of the kitchen's ends unconnected.)
        wide_candidates: nearest nodes tried directly as the last resort.
        max_pair_tries: (start node, goal node) pairs tried when dynamic obstacles block paths.
        lazy_iterations: A* rounds of the lazy search on the remaining graph.
        resolution: rad, motion check step; None: the roadmap's.
        repair: the bidirectional tree that connects into the roadmap when it cannot
            answer alone (:mod:`chekhov.roadmap.repair`, :meth:`RoadmapSeeder.repair`).
        seed: seed of the random bridges' and the connection tree's samples; every
            connection attempt starts a fresh generator, so a query's answer does not depend
            on the queries before it.
    """

    n_goal_ik: int = 3
    ik_seeds: int = 6
    ik_random_seeds: int = 32
    ik_random_rounds: int = 4
    connect_candidates: int = 32
    max_connections: int = 3
    bridges: bool = True
    bridge_samples: int = 48
    bridge_radius: float = 0.8
    tree_nodes: int = 5000
    tree_time_s: float = 0.05
    tree_step: float = 0.3
    wide_candidates: int = 160
    max_pair_tries: int = 6
    lazy_iterations: int = 60
    resolution: float | None = None
    repair: RepairConfig = field(default_factory=RepairConfig)
    seed: int = 0
