"""Triangle meshes for the 3D viewer: scene primitives, and the robot's visual geometry from the
URDF (pinocchio ``visual_model``, meshes already loaded by pinocchio into coal BVH models, so no
mesh loader and no network is needed). No viser import here."""

from __future__ import annotations

from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from chekhov.robot.robot import Robot
from chekhov.scene.model import SceneObject, Shape
from chekhov.transforms import matrix_to_quat

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]
Mesh = tuple[Array, IntArray]  # vertices (V, 3) m, faces (F, 3) indices

# colours (RGB 0-255) per semantic class; dynamic obstacles get one loud colour
CLASS_RGB: dict[str, tuple[int, int, int]] = {
    "table": (176, 136, 80), "pole": (112, 112, 112), "box": (217, 164, 65),
    "container": (95, 143, 191), "shelf": (160, 120, 80), "cabinet": (156, 138, 112),
    "fridge": (200, 208, 216), "door": (138, 160, 176), "drawer": (138, 160, 176),
    "wall": (216, 208, 192), "counter": (160, 160, 160), "sink": (176, 192, 208),
    "appliance": (144, 144, 144), "handle": (64, 64, 64), "object": (192, 192, 192),
    "person": (224, 96, 64),
}
DYNAMIC_RGB = (230, 60, 30)


def object_color(obj: SceneObject) -> tuple[int, int, int]:
    """Display colour of a scene object: by semantic class; dynamic ones stand out."""
    return DYNAMIC_RGB if obj.dynamic else CLASS_RGB.get(obj.cls, (192, 192, 192))


def box_mesh(half: Array) -> Mesh:
    """Box centred at the origin with half extents ``half`` (3,)."""
    V = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    V = V * np.asarray(half, dtype=float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    F = [(a, b, c) for a, b, c, _ in quads] + [(a, c, d) for a, _, c, d in quads]
    return V, np.array(F, dtype=np.int64)


def cylinder_mesh(radius: float, half_length: float, n: int = 24) -> Mesh:
    """Closed cylinder along z, centred at the origin."""
    a = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    ring = np.column_stack([radius * np.cos(a), radius * np.sin(a)])
    V = np.vstack([np.column_stack([ring, np.full(n, -half_length)]),
                   np.column_stack([ring, np.full(n, half_length)]),
                   [[0, 0, -half_length], [0, 0, half_length]]])
    F = []
    for i in range(n):
        j = (i + 1) % n
        F += [(i, j, n + j), (i, n + j, n + i), (2 * n, j, i), (2 * n + 1, n + i, n + j)]
    return V, np.array(F, dtype=np.int64)


def sphere_mesh(radius: float, n: int = 12) -> Mesh:
    """UV sphere centred at the origin (n segments around, n // 2 rings)."""
    m = max(n // 2, 2)
    th = np.linspace(0.0, np.pi, m + 1)[1:-1]
    ph = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    t, p = np.meshgrid(th, ph, indexing="ij")
    rings = np.column_stack([np.sin(t).ravel() * np.cos(p).ravel(),
                             np.sin(t).ravel() * np.sin(p).ravel(), np.cos(t).ravel()])
    V = np.vstack([[[0, 0, 1]], rings, [[0, 0, -1]]]) * radius
    last = len(V) - 1
    F = []
    for j in range(n):
        k = (j + 1) % n
        F.append((0, 1 + j, 1 + k))
        F.append((last, 1 + (m - 2) * n + k, 1 + (m - 2) * n + j))
        for r in range(m - 2):
            a, b = 1 + r * n, 1 + (r + 1) * n
            F += [(a + j, b + j, b + k), (a + j, b + k, a + k)]
    return V, np.array(F, dtype=np.int64)


def shape_mesh(shape: Shape) -> Mesh:
    """Mesh of a scene primitive in its own frame."""
    if shape.kind == "box":
        return box_mesh(shape.half_extents)
    if shape.kind == "cylinder":
        return cylinder_mesh(shape.size[0], shape.size[1] / 2)
    return sphere_mesh(shape.size[0])


def cluster_decimate(V: Array, F: IntArray, cell: float) -> Mesh:
    """Vertex-clustering simplification: vertices snapped to a ``cell`` (m) grid are merged
    and triangles that collapse are dropped. Keeps silhouettes to within a cell."""
    if cell <= 0 or len(V) == 0:
        return V, F
    keys = np.floor(V / cell).astype(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    F2 = inverse[F]
    keep = (F2[:, 0] != F2[:, 1]) & (F2[:, 1] != F2[:, 2]) & (F2[:, 0] != F2[:, 2])
    F2 = F2[keep]
    if len(F2) == 0:
        return V, F
    F2 = np.unique(F2, axis=0)
    return V[first], F2


def geometry_mesh(geometry: coal.CollisionGeometry, cell: float = 0.004) -> Mesh | None:
    """Mesh of a coal geometry in its own frame: BVH meshes (decimated), boxes, cylinders,
    spheres; None for anything else."""
    if isinstance(geometry, coal.Box):
        return box_mesh(np.asarray(geometry.halfSide))
    if isinstance(geometry, coal.Cylinder):
        return cylinder_mesh(float(geometry.radius), float(geometry.halfLength))
    if isinstance(geometry, coal.Sphere):
        return sphere_mesh(float(geometry.radius)) if geometry.radius > 0.01 else None
    if hasattr(geometry, "num_tris") and geometry.num_tris > 0:
        V = np.asarray(geometry.vertices(), dtype=float)
        F = np.array([[t[0], t[1], t[2]] for t in
                      (geometry.tri_indices(i) for i in range(geometry.num_tris))],
                     dtype=np.int64)
        return cluster_decimate(V, F, cell)
    return None


def se3_to_wxyz_xyz(T: Array) -> tuple[Array, Array]:
    """(quaternion w, x, y, z; translation) of a 4x4 transform."""
    return np.asarray(matrix_to_quat(T[:3, :3]), dtype=float), np.asarray(T[:3, 3], dtype=float)


@dataclass(frozen=True)
class RobotPart:
    """One visual geometry of the robot: its mesh (own frame), colour, and whether it moves
    with the planning group's joints."""

    name: str
    index: int
    vertices: Array
    faces: IntArray
    rgb: tuple[int, int, int]
    moving: bool


class RobotMeshes:
    """The robot's visual geometry (the URDF's visual meshes, as pinocchio loaded them) and
    its placements in the world at a configuration."""

    def __init__(self, robot: Robot, cell: float = 0.006) -> None:
        self.robot = robot
        self.model = robot.visual_model
        self._data = robot.model.createData()
        self._gdata = pin.GeometryData(self.model)
        cache: dict[str, Mesh | None] = {}
        parts = []
        for i, g in enumerate(self.model.geometryObjects):
            key = g.meshPath if g.meshPath and not g.meshPath.isupper() else f"#{i}"
            if key not in cache:
                cache[key] = geometry_mesh(g.geometry, cell)
            mesh = cache[key]
            if mesh is None:
                continue
            c = np.asarray(g.meshColor, dtype=float)
            rgb = tuple(round(255 * min(max(float(v), 0.0), 1.0)) for v in c[:3])
            if c[3] <= 0.0 or max(rgb) < 10:  # unset or black: a neutral grey
                rgb = (90, 90, 90)
            parts.append(RobotPart(g.name, i, mesh[0], mesh[1],
                                   (rgb[0], rgb[1], rgb[2]), g.parentJoint > 0))
        self.parts: tuple[RobotPart, ...] = tuple(parts)

    def placements(self, q: Array) -> list[Array]:
        """T_world_geometry (4, 4) of every part at q, in ``parts`` order."""
        pin.updateGeometryPlacements(self.robot.model, self._data, self.model, self._gdata,
                                     np.asarray(q, dtype=float))
        return [self._gdata.oMg[p.index].homogeneous.copy() for p in self.parts]

    @property
    def n_triangles(self) -> int:
        return int(sum(len(p.faces) for p in self.parts))
