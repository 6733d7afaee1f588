"""Drawing a world onto a viser server: scene objects by semantic class, the robot's visual
meshes, the fast checker's spheres, the roadmap's end-effector graph, plan traces."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import viser
from numpy.typing import NDArray

from chekhov.roadmap.graph import Roadmap
from chekhov.scene.model import SceneObject
from chekhov.transforms import make_transform, quat_to_matrix
from chekhov.viewer.meshes import (
    RobotMeshes,
    object_color,
    se3_to_wxyz_xyz,
    shape_mesh,
    sphere_mesh,
)
from chekhov.viewer.planning import polyline_segments
from chekhov.world import World

Array = NDArray[np.float64]

SEED_RGB = (240, 150, 30)
PATH_RGB = (30, 110, 230)
ROADMAP_NODE_RGB = (70, 160, 90)
ROADMAP_EDGE_RGB = (150, 200, 160)
SPHERE_RGB = (80, 200, 255)


def draw_object(server: viser.ViserServer, name: str, obj: SceneObject,
                T: Array | None = None) -> viser.MeshHandle:
    """One scene object as a mesh coloured by its class (dynamic: the dynamic colour,
    translucent), at ``T`` (default: the object's pose)."""
    V, F = shape_mesh(obj.shape)
    wxyz, xyz = se3_to_wxyz_xyz(obj.T_world_obj() if T is None else T)
    return server.scene.add_mesh_simple(
        name, V.astype(np.float32), F.astype(np.uint32), color=object_color(obj),
        opacity=0.75 if obj.dynamic else None, flat_shading=obj.shape.kind == "box",
        side="double" if obj.dynamic else "front", wxyz=wxyz, position=xyz)


def pose_of(handle: Any) -> Array:
    """T (4, 4) of a scene node from its wxyz / position."""
    return make_transform(np.asarray(handle.position, dtype=float),
                          quat_to_matrix(tuple(float(x) for x in handle.wxyz)))


def draw_draggable(server: viser.ViserServer, obj: SceneObject, T: Array,
                   on_move: Callable[[Array], None]
                   ) -> tuple[viser.TransformControlsHandle, viser.MeshHandle]:
    """A dynamic object under a transform gizmo at ``T`` (T_world_obj (4, 4), m), node
    ``/obstacles/{name}``; ``on_move(T_world_obj)`` on every drag update. (gizmo, mesh)."""
    name = obj.name
    wxyz, xyz = se3_to_wxyz_xyz(T)
    gizmo = server.scene.add_transform_controls(f"/obstacles/{name}", scale=0.25, wxyz=wxyz,
                                                position=xyz)
    mesh = draw_object(server, f"/obstacles/{name}/mesh", obj, np.eye(4))

    def moved(_: Any) -> None:
        on_move(pose_of(gizmo))

    gizmo.on_update(moved)
    return gizmo, mesh


def draw_scene(server: viser.ViserServer, world: World) -> dict[str, Any]:
    """Ground grid and every static scene object (dynamic objects are drawn by the viewer
    with their gizmos). Returns the handles by node name."""
    handles: dict[str, Any] = {}
    handles["/ground"] = server.scene.add_grid("/ground", width=6.0, height=6.0,
                                               cell_size=0.25, section_size=1.0,
                                               plane_opacity=0.35,
                                               plane_color=(235, 235, 235))
    for o in world.scene.static_objects:
        name = f"/scene/static/{o.name}"
        handles[name] = draw_object(server, name, o)
    return handles


class RobotDrawing:
    """The robot's visual meshes on the server; ``show(q)`` moves the group's links."""

    def __init__(self, server: viser.ViserServer, meshes: RobotMeshes, q: Array,
                 prefix: str = "/robot", opacity: float | None = None) -> None:
        self.meshes = meshes
        self.handles: list[viser.MeshHandle] = []
        for part, T in zip(meshes.parts, meshes.placements(q), strict=True):
            wxyz, xyz = se3_to_wxyz_xyz(T)
            self.handles.append(server.scene.add_mesh_simple(
                f"{prefix}/{'arm' if part.moving else 'body'}/{part.name}",
                part.vertices.astype(np.float32), part.faces.astype(np.uint32),
                color=part.rgb, opacity=opacity, wxyz=wxyz, position=xyz))

    def show(self, q: Array) -> None:
        for part, h, T in zip(self.meshes.parts, self.handles, self.meshes.placements(q),
                              strict=True):
            if part.moving:
                h.wxyz, h.position = se3_to_wxyz_xyz(T)


class SphereDrawing:
    """The fast checker's spheres (one instanced mesh); updated only while visible."""

    def __init__(self, server: viser.ViserServer, world: World, q: Array,
                 visible: bool = False) -> None:
        self.world = world
        V, F = sphere_mesh(1.0, 10)
        r = np.asarray(world.fast.spheres.radii, dtype=np.float32)
        c = world.fast.sphere_centers(q).astype(np.float32)
        self.handle = server.scene.add_batched_meshes_simple(
            "/robot/spheres", V.astype(np.float32), F.astype(np.uint32),
            batched_wxyzs=np.tile(np.array([1, 0, 0, 0], np.float32), (len(r), 1)),
            batched_positions=c, batched_scales=r, batched_colors=SPHERE_RGB, opacity=0.35,
            visible=visible)
        self._q = np.asarray(q, dtype=float)

    def show(self, q: Array) -> None:
        self._q = np.asarray(q, dtype=float)
        if self.handle.visible:
            self.handle.batched_positions = self.world.fast.sphere_centers(self._q).astype(
                np.float32)

    def set_visible(self, visible: bool) -> None:
        self.handle.visible = visible
        self.show(self._q)


def draw_roadmap(server: viser.ViserServer, roadmap: Roadmap, nodes_visible: bool = True,
                 edges_visible: bool = False
                 ) -> tuple[viser.PointCloudHandle, viser.LineSegmentsHandle]:
    """The roadmap as end-effector positions of its nodes (points) and edges (segments)."""
    P = np.asarray(roadmap.ee_position, dtype=np.float32)
    nodes = server.scene.add_point_cloud("/roadmap/nodes", P, ROADMAP_NODE_RGB,
                                         point_size=0.006, point_shape="circle",
                                         precision="float32", visible=nodes_visible)
    E = np.asarray(roadmap.edges, dtype=np.int64).reshape(-1, 2)
    segs = P[E] if len(E) else np.zeros((1, 2, 3), np.float32)
    edges = server.scene.add_line_segments("/roadmap/edges", segs, ROADMAP_EDGE_RGB,
                                           thickness=1.0, thickness_units="screen",
                                           visible=edges_visible)
    return nodes, edges


def draw_trace(server: viser.ViserServer, name: str, points: Array | None,
               rgb: tuple[int, int, int], thickness: float) -> viser.LineSegmentsHandle:
    """An end-effector trace (T, 3) as line segments; hidden when there is none."""
    P = np.zeros((2, 3)) if points is None else np.asarray(points, dtype=float)
    return server.scene.add_line_segments(
        name, polyline_segments(P).astype(np.float32), rgb, thickness=thickness,
        thickness_units="screen", visible=points is not None)


def camera_for(world: World) -> tuple[Array, Array]:
    """(camera position, look-at point): in front of the robot, on its left arm's side,
    looking at the arm's workspace."""
    Tb = world.robot.T_world_base
    base, fwd, left = Tb[:3, 3], Tb[:3, 0], Tb[:3, 1]
    look = base + 0.4 * fwd + 0.2 * left - np.array([0.0, 0.0, 0.2])
    eye = base + 1.5 * fwd + 2.6 * left + np.array([0.0, 0.0, 0.8])
    return eye, look
