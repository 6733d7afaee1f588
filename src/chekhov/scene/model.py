"""Scenes: primitive obstacles with poses and the meaning of each (a semantic object map)."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from chekhov.transforms import make_transform, matrix_to_quat, quat_to_matrix, rotation_about

Array = NDArray[np.float64]
ShapeKind = Literal["box", "cylinder", "sphere"]
SHAPE_KINDS: tuple[str, ...] = ("box", "cylinder", "sphere")
OBJECT_CLASSES: tuple[str, ...] = (
    "table", "pole", "box", "container", "shelf", "cabinet", "fridge", "door", "drawer",
    "wall", "counter", "sink", "appliance", "handle", "object", "person",
)


@dataclass(frozen=True)
class Pose:
    """A rigid pose: translation (m) and unit quaternion (w, x, y, z)."""

    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quat_wxyz: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)

    @property
    def T(self) -> Array:
        """Homogeneous matrix of shape (4, 4)."""
        return make_transform(self.xyz, quat_to_matrix(self.quat_wxyz))


@dataclass(frozen=True)
class Shape:
    """A primitive. ``size``: box (x, y, z) full lengths; cylinder (radius, length) along its z
    axis; sphere (radius,). Metres."""

    kind: ShapeKind
    size: tuple[float, ...]

    @property
    def half_extents(self) -> Array:
        """Half extents of the shape's local bounding box, shape (3,)."""
        if self.kind == "box":
            return np.asarray(self.size) / 2
        if self.kind == "cylinder":
            r, length = self.size
            return np.array([r, r, length / 2])
        return np.full(3, self.size[0])


@dataclass(frozen=True)
class Grasp:
    """An end-effector grasp in the object's frame; the pre-grasp backs off along the approach."""

    name: str
    T_obj_grasp: Array
    T_obj_pregrasp: Array

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, Grasp) and self.name == other.name
                and np.allclose(self.T_obj_grasp, other.T_obj_grasp)
                and np.allclose(self.T_obj_pregrasp, other.T_obj_pregrasp))

    def __hash__(self) -> int:
        return hash(self.name)


@dataclass(frozen=True)
class Articulation:
    """A hinge or slide joint moving the object; named states give its value (rad or m).

    ``axis`` and ``origin`` (a point on the axis) are in the object's frame at value 0."""

    kind: Literal["hinge", "slide"]
    axis: tuple[float, float, float]
    origin: tuple[float, float, float]
    states: tuple[tuple[str, float], ...]
    state: str

    def value(self, state: str | None = None) -> float:
        name = self.state if state is None else state
        return dict(self.states)[name]

    def T_zero_moved(self, value: float) -> Array:
        """Motion, in the object's frame at value 0, that puts the object at ``value``."""
        a = np.asarray(self.axis, dtype=float)
        a = a / np.linalg.norm(a)
        if self.kind == "slide":
            return make_transform(a * value)
        o = np.asarray(self.origin, dtype=float)
        R = rotation_about(a, value)
        return make_transform(o - R @ o, R)


@dataclass(frozen=True)
class SceneObject:
    """One obstacle and its meaning.

    Attributes:
        name: unique within the scene.
        shape: its primitive.
        pose: T_world_obj with the articulation (if any) at value 0.
        cls: semantic class (table, pole, box, shelf, door …).
        dynamic: False for static obstacles (the roadmap is built against these only).
        grasps: grasp / pre-grasp end-effector poses, in the object's frame.
        articulation: a hinge or slide that moves the object between named states.
    """

    name: str
    shape: Shape
    pose: Pose
    cls: str = "object"
    dynamic: bool = False
    grasps: tuple[Grasp, ...] = ()
    articulation: Articulation | None = None

    def T_world_obj(self, state: str | None = None) -> Array:
        """Pose of the object in the world, at its current (or the named) articulation state."""
        T = self.pose.T
        if self.articulation is not None:
            T = T @ self.articulation.T_zero_moved(self.articulation.value(state))
        return T

    def pregrasp_poses(self) -> list[tuple[str, Array]]:
        """(label, T_world_ee) of every pre-grasp, for every articulation state."""
        states = [None] if self.articulation is None else [s for s, _ in self.articulation.states]
        out = []
        for s in states:
            T = self.T_world_obj(s)
            for g in self.grasps:
                label = f"{self.name}/{g.name}" + (f"@{s}" if s else "")
                out.append((label, T @ g.T_obj_pregrasp))
        return out


@dataclass(frozen=True)
class Region:
    """A region of interest: an axis-aligned world box (centre, full size; m) and a sampling
    weight (relative; 0 excludes)."""

    name: str
    center: tuple[float, float, float]
    size: tuple[float, float, float]
    weight: float = 1.0

    def sample(self, rng: np.random.Generator, n: int) -> Array:
        """n points drawn uniformly inside the region, shape (n, 3)."""
        c, s = np.asarray(self.center), np.asarray(self.size)
        return c + (rng.random((n, 3)) - 0.5) * s


@dataclass(frozen=True)
class Scene:
    """A planning scene: obstacles with semantics, regions of interest, the robot's base pose
    and the values of its locked joints (outside the planning group: fingers, the other arm;
    (name, rad or m) pairs over the robot description's own)."""

    name: str
    objects: tuple[SceneObject, ...]
    regions: tuple[Region, ...] = ()
    robot: str = "baxter_left"
    base_pose: Pose | None = None
    description: str = ""
    source: str = field(default="<memory>", compare=False)
    locked_joints: tuple[tuple[str, float], ...] = ()

    def object(self, name: str) -> SceneObject:
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(f"scene '{self.name}' has no object '{name}'")

    @property
    def static_objects(self) -> tuple[SceneObject, ...]:
        return tuple(o for o in self.objects if not o.dynamic)

    @property
    def dynamic_objects(self) -> tuple[SceneObject, ...]:
        return tuple(o for o in self.objects if o.dynamic)

    def content_hash(self) -> str:
        """SHA-256 of the scene's content (what a roadmap or case file is bound to)."""
        d = scene_to_dict(self)
        d.pop("description", None)
        blob = json.dumps(d, sort_keys=True, separators=(",", ":")).encode()
        return hashlib.sha256(blob).hexdigest()


FORMAT_VERSION = 1
"""The scene file format this chekhov reads and writes."""


def _pose_dict(T: np.ndarray) -> dict[str, list[float]]:
    q = matrix_to_quat(T[:3, :3])
    return {"xyz": [round(float(x), 9) for x in T[:3, 3]], "quat": [round(float(x), 12) for x in q]}


def scene_to_dict(scene: Scene) -> dict[str, Any]:
    """A plain mapping that :func:`scene_from_dict` turns back into an equal scene."""
    objects = []
    for o in scene.objects:
        d: dict[str, Any] = {"name": o.name, "class": o.cls,
                             "motion": "dynamic" if o.dynamic else "static",
                             "shape": o.shape.kind, "size": list(o.shape.size),
                             "pose": {"xyz": list(o.pose.xyz), "quat": list(o.pose.quat_wxyz)}}
        if o.grasps:
            d["grasps"] = [{"name": g.name, "grasp": _pose_dict(g.T_obj_grasp),
                            "pregrasp": _pose_dict(g.T_obj_pregrasp)} for g in o.grasps]
        if o.articulation is not None:
            a = o.articulation
            d["articulation"] = {"type": a.kind, "axis": list(a.axis), "origin": list(a.origin),
                                 "states": dict(a.states), "state": a.state}
        objects.append(d)
    out: dict[str, Any] = {"format": FORMAT_VERSION, "name": scene.name,
                           "description": scene.description, "robot": scene.robot}
    if scene.base_pose is not None:
        out["base_pose"] = {"xyz": list(scene.base_pose.xyz),
                            "quat": list(scene.base_pose.quat_wxyz)}
    if scene.locked_joints:
        out["locked_joints"] = dict(scene.locked_joints)
    out["objects"] = objects
    out["regions"] = [{"name": r.name, "center": list(r.center), "size": list(r.size),
                       "weight": r.weight} for r in scene.regions]
    return out
