"""Roadmap build settings."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any

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
    * ``wrist`` (an extension; 0 turns it off): ``n_wrist_nodes`` copies of random uniform
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
        if kw.get("distal_values") is not None:
            kw["distal_values"] = tuple(kw["distal_values"])
        return cls(**kw)
