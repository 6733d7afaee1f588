"""Static pictures of a scene and the robot (collision geometry) with matplotlib."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import coal
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pinocchio as pin
from mpl_toolkits.mplot3d.art3d import Poly3DCollection
from numpy.typing import NDArray

from chekhov.robot.spheres import mesh_triangles
from chekhov.world import World

Array = NDArray[np.float64]
CLASS_COLORS = {
    "table": "#b08850", "pole": "#707070", "box": "#d9a441", "container": "#5f8fbf",
    "shelf": "#a07850", "cabinet": "#9c8a70", "fridge": "#c8d0d8", "door": "#8aa0b0",
    "drawer": "#8aa0b0", "wall": "#d8d0c0", "counter": "#a0a0a0", "sink": "#b0c0d0",
    "appliance": "#909090", "handle": "#404040", "object": "#c0c0c0", "person": "#e06040",
}
DYNAMIC_COLOR = "#e05a2b"


def _box_faces(half: Array, T: Array) -> list[Array]:
    c = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half
    w = c @ T[:3, :3].T + T[:3, 3]
    idx = [(0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5)]
    return [w[list(f)] for f in idx]


def _cylinder_faces(r: float, half: float, T: Array, n: int = 20) -> list[Array]:
    a = np.linspace(0, 2 * np.pi, n + 1)
    ring = np.stack([r * np.cos(a), r * np.sin(a)], axis=1)
    faces = []
    for i in range(n):
        quad = np.array([[*ring[i], -half], [*ring[i + 1], -half], [*ring[i + 1], half],
                         [*ring[i], half]])
        faces.append(quad)
    for z in (-half, half):
        faces.append(np.column_stack([ring, np.full(len(ring), z)]))
    return [f @ T[:3, :3].T + T[:3, 3] for f in faces]


def _sphere_faces(r: float, T: Array, n: int = 10) -> list[Array]:
    u, v = np.linspace(0, 2 * np.pi, n + 1), np.linspace(0, np.pi, n // 2 + 1)
    faces = []
    for i in range(n):
        for j in range(n // 2):
            pts = [(u[i], v[j]), (u[i + 1], v[j]), (u[i + 1], v[j + 1]), (u[i], v[j + 1])]
            faces.append(np.array([[r * np.cos(a) * np.sin(b), r * np.sin(a) * np.sin(b),
                                    r * np.cos(b)] for a, b in pts]) + T[:3, 3])
    return faces


def shape_faces(kind: str, size: Array, T: Array) -> list[Array]:
    """Polygons (world) of a primitive: kind box (half extents), cylinder (r, half length),
    sphere (r)."""
    if kind == "box":
        return _box_faces(np.asarray(size), T)
    if kind == "cylinder":
        return _cylinder_faces(size[0], size[1], T)
    return _sphere_faces(size[0], T)


def geometry_faces(geometry: coal.CollisionGeometry, T: Array, max_triangles: int = 1500
                   ) -> list[Array]:
    if isinstance(geometry, coal.Box):
        return shape_faces("box", np.asarray(geometry.halfSide), T)
    if isinstance(geometry, coal.Cylinder):
        return shape_faces("cylinder", np.array([geometry.radius, geometry.halfLength]), T)
    if isinstance(geometry, coal.Sphere):
        return shape_faces("sphere", np.array([geometry.radius]), T) if geometry.radius > 0.01 \
            else []
    if hasattr(geometry, "num_tris"):
        tris = mesh_triangles(geometry)
        step = max(1, len(tris) // max_triangles)
        return list(tris[::step] @ T[:3, :3].T + T[:3, 3])
    return []


def robot_faces(world: World, q: Array) -> list[Array]:
    robot = world.robot
    gm = robot.collision_model
    gd = pin.GeometryData(gm)
    pin.updateGeometryPlacements(robot.model, robot.model.createData(), gm, gd,
                                 np.asarray(q, dtype=float))
    faces: list[Array] = []
    for i, g in enumerate(gm.geometryObjects):
        faces += geometry_faces(g.geometry, gd.oMg[i].homogeneous)
    return faces


def render_scene(world: World, q: Array | None = None, path: Array | None = None,
                 out: str | Path = "scene.png", title: str | None = None,
                 ghosts: int = 6, elev: float = 25.0, azim: float | None = None,
                 seed: Array | None = None) -> Path:
    """Write a PNG of the scene with the robot at q (default: the path's start) and, if a path
    (T, K) is given, ghosts of the robot along it, the end-effector trace and its start (green)
    and end (red); with ``seed`` (T', K), the seed's end-effector trace too (orange, dashed).
    ``elev`` / ``azim``: the view's elevation and azimuth, degrees (azimuth default: over the
    robot's shoulder)."""
    fig = plt.figure(figsize=(8, 7), dpi=110)
    ax = fig.add_subplot(projection="3d")
    ax.set_autoscale_on(False)  # limits are set below; autoscaling many polygons can overflow
    _draw_obstacles(ax, world)
    if path is not None:
        P = np.atleast_2d(path)
        _draw_path(ax, world, P, ghosts)
        q = P[0] if q is None else q
    if seed is not None:
        es = world.robot.compute_ee_poses(np.atleast_2d(seed))[:, :3, 3]
        ax.plot(es[:, 0], es[:, 1], es[:, 2], color="#f09020", linewidth=1.5,
                linestyle="--", label="seed (end effector)")
    if path is not None or seed is not None:
        ax.legend(loc="upper left", fontsize=8)
    if q is not None:
        ax.add_collection3d(Poly3DCollection(robot_faces(world, q), facecolor="#d8dde3",
                                             edgecolor="#30303040", linewidth=0.1, alpha=0.9))
    lo, hi = _world_box(world, [a for a in (path, seed) if a is not None])
    _set_view(ax, world, lo, hi, elev, azim)
    ax.set_title(title or world.scene.name)
    return _save_png(fig, Path(out))


def _draw_obstacles(ax: Any, world: World) -> None:
    """The scene's objects, coloured by class (dynamic ones in ``DYNAMIC_COLOR``)."""
    for o in world.scene.objects:
        s = o.shape
        size = s.half_extents if s.kind == "box" else (
            np.array([s.size[0], s.size[1] / 2]) if s.kind == "cylinder" else np.array(s.size))
        color = DYNAMIC_COLOR if o.dynamic else CLASS_COLORS.get(o.cls, "#c0c0c0")
        ax.add_collection3d(Poly3DCollection(shape_faces(s.kind, size, o.T_world_obj()),
                                             facecolor=color, edgecolor="#00000030",
                                             linewidth=0.2, alpha=0.55 if o.dynamic else 0.8))


def _draw_path(ax: Any, world: World, P: Array, ghosts: int) -> None:
    """Up to ``ghosts`` robots along the path P (T, K) rad (fainter towards its start, the
    first left out), the end-effector trace, its start and its end."""
    idx = np.linspace(0, len(P) - 1, min(ghosts, len(P))).astype(int)
    for k, i in enumerate(idx[1:], 1):
        ax.add_collection3d(Poly3DCollection(robot_faces(world, P[i]), facecolor="#3070c0",
                                             alpha=0.08 + 0.2 * k / len(idx), linewidth=0))
    ee = world.robot.compute_ee_poses(P)[:, :3, 3]
    ax.plot(ee[:, 0], ee[:, 1], ee[:, 2], color="#c02020", linewidth=2,
            label="trajectory (end effector)")
    ax.scatter(*ee[0], color="#20a020", s=30, label="start", depthshade=False)
    ax.scatter(*ee[-1], color="#d02020", s=30, label="goal", depthshade=False)


def _world_box(world: World, paths: list[Array]) -> tuple[Array, Array]:
    """(lo, hi) corners (3,) m in the world of the box shown: the workspace around the robot's
    base, grown to hold the end-effector traces of ``paths`` (each (T, K) rad)."""
    lo = np.array([-0.6, -0.9, 0.0])
    hi = np.array([1.4, 1.3, 2.0])
    base = world.robot.T_world_base[:3, 3]
    if np.linalg.norm(base[:2]) > 0.5:  # centre the view on the robot's workspace
        fwd = world.robot.T_world_base[:3, 0]
        c = base + 0.5 * fwd
        lo, hi = np.array([c[0] - 1.1, c[1] - 1.1, 0.0]), np.array([c[0] + 1.1, c[1] + 1.1, 2.0])
    traces = [world.robot.compute_ee_poses(np.atleast_2d(a))[:, :3, 3] for a in paths]
    if traces:  # keep the traces inside the box
        pts = np.vstack(traces)
        lo = np.minimum(lo, pts.min(axis=0) - 0.05)
        hi = np.maximum(hi, pts.max(axis=0) + 0.05)
    return lo, hi


def _set_view(ax: Any, world: World, lo: Array, hi: Array, elev: float, azim: float | None
              ) -> None:
    """Axis limits (the box lo..hi, m, true aspect), labels and the camera (degrees)."""
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(hi - lo)
    if azim is None:  # look over the robot's shoulder
        Rb = world.robot.T_world_base[:3, :3]
        azim = float(np.degrees(np.arctan2(Rb[1, 0], Rb[0, 0]))) - 140.0
    ax.view_init(elev=elev, azim=azim)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")


def _save_png(fig: Any, out: Path) -> Path:
    """Write the figure to ``out`` (a temporary file beside it, renamed) and close it."""
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp.png")
    fig.savefig(tmp, bbox_inches="tight")
    plt.close(fig)
    tmp.replace(out)
    return out
