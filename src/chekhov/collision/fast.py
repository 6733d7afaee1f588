"""The fast checker: the robot as covering spheres against primitive obstacles, numba-compiled.

Used by every planner. It is conservative by construction (the spheres contain the robot's
collision geometry and meshes of fixed robot parts are replaced by boxes containing them), so it
never calls a configuration free that the exact checker calls colliding.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from itertools import pairwise

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from chekhov.collision import dense_path, kernels, validity
from chekhov.collision.gjk import HULL
from chekhov.collision.grid import build_grid, build_surface_grid, point_field
from chekhov.collision.primitives import (
    Primitive,
    cluster_primitives,
    fixed_points,
    geometry_primitives,
    hull_parts,
    pack,
    shape_primitive,
    split_triangles,
)
from chekhov.errors import RobotError
from chekhov.robot.robot import Robot
from chekhov.robot.spheres import SphereModel, build_sphere_model
from chekhov.scene.model import Scene, Shape

Array = NDArray[np.float64]
# m: how far apart a confirmation (GJK on the covered geometry) must prove two shapes. Its
# certificate is an exact support-function bound, so this only has to absorb rounding and the
# exact checker's own tolerances (coal's GJK: about 1e-6 m). The spheres' padding (1-2 mm)
# would call every configuration within it colliding: a third of those within 5 mm of contact
# (measured with benchmarks/collision.py on the near-contact configurations).
CONFIRM_PAD = 1e-4
BoolArray = NDArray[np.bool_]
_FIXED_GRID_CACHE: dict[tuple, list] = {}


@dataclass(frozen=True)
class Contacts:
    """Sphere contacts within a margin at one configuration (C contacts).

    Attributes:
        sphere: sphere index (C,).
        other: obstacle index (``kind`` 0: environment, 1: fixed robot part) or sphere (2).
        kind: (C,) as above.
        distance: signed surface distance (C,), metres, negative in penetration.
        normal: unit world direction (C, 3) along which moving the sphere increases distance.
        point: witness point on the sphere's surface, world (C, 3).
    """

    sphere: NDArray[np.int64]
    other: NDArray[np.int64]
    kind: NDArray[np.int64]
    distance: Array
    normal: Array
    point: Array

    def __len__(self) -> int:
        return len(self.distance)


def chain_arrays(robot: Robot) -> tuple[NDArray[np.int64], Array, Array, Array]:
    """Parent index, placement (R, p) and axis of each group joint, for the kernels."""
    m = robot.model
    K = robot.dof
    parent = np.array([m.parents[k] - 1 for k in range(1, K + 1)], dtype=np.int64)
    R0 = np.array([m.jointPlacements[k].rotation for k in range(1, K + 1)])
    p0 = np.array([m.jointPlacements[k].translation for k in range(1, K + 1)])
    return parent, R0, p0, robot.compute_joint_axes()


class FastChecker:
    """Batched collision checks of the robot's spheres against the scene's primitives.

    Configurations are arrays of shape (K,) or (N, K) in radians. Obstacles from the scene
    (static and dynamic) are named; dynamic ones can be added, moved and removed at run time
    without rebuilding anything else; ``obstacles_version`` counts those changes, so callers
    can tell when cached validity results went stale. Static obstacles and fixed robot parts
    are compiled once into distance grids (``grid_spacing`` m) that clear most spheres with one
    lookup. A sphere hit is confirmed on the covered geometry itself when it is a primitive
    (see ``validity.py``), so the spheres' overhang past the geometry raises no false alarms.
    """

    def __init__(self, robot: Robot, scene: Scene | None = None,
                 spheres: SphereModel | None = None, static_only: bool = False,
                 grid_spacing: float = 0.02) -> None:
        self.robot = robot
        self.spheres = spheres if spheres is not None else build_sphere_model(robot)
        sp = self.spheres
        self._chain = chain_arrays(robot)
        self._sphere_arrays = (sp.centers.astype(float), sp.radii.astype(float),
                               sp.joints.astype(np.int64))
        # one group per covered geometry, with a bounding sphere in its joint's frame
        geoms = list(dict.fromkeys(sp.geometries.tolist()))
        starts = [int(np.flatnonzero(sp.geometries == g)[0]) for g in geoms] + [len(sp)]
        gc = np.array([sp.centers[a:b].mean(axis=0) for a, b in pairwise(starts)])
        gr = np.array([np.max(np.linalg.norm(sp.centers[a:b] - gc[i], axis=1) + sp.radii[a:b])
                       for i, (a, b) in enumerate(pairwise(starts))])
        gj = np.array([sp.joints[a] for a in starts[:-1]], dtype=np.int64)
        self._groups = (np.array(starts, dtype=np.int64), gc, gr, gj)
        self._gexact, self._rin = exact_geometry(robot, geoms, sp)
        group_of = {g: i for i, g in enumerate(geoms)}
        # fixed robot parts and self-collision pairs, from the robot's pair list
        fixed: list[Primitive] = []
        fixed_of: dict[int, list[int]] = {}
        fixed_pairs, self_pairs = [], []
        cm = robot.collision_model
        for a, b in robot.self_collision_pairs:
            if a in group_of and b in group_of:
                self_pairs.append((group_of[a], group_of[b]))
                continue
            g, f = (a, b) if a in group_of else (b, a)
            if f not in fixed_of:
                go = cm.geometryObjects[f]
                prims = geometry_primitives(go.geometry, go.placement.homogeneous)
                fixed_of[f] = list(range(len(fixed), len(fixed) + len(prims)))
                fixed += prims
            fixed_pairs += [(group_of[g], i) for i in fixed_of[f]]
        self.fixed_primitives = fixed
        self._fixed_of = fixed_of   # fixed geometry → its primitives' indices
        self._fixed = pack(fixed)
        self._gexact = (*self._gexact, *fixed_points(fixed))  # and gsurf: _build_grids
        self._fixed_pairs = np.array(sorted(fixed_pairs), dtype=np.int64).reshape(-1, 2)
        G = len(gr)
        fstart = np.searchsorted(self._fixed_pairs[:, 0], np.arange(G + 1)).astype(np.int64)
        self._fixed_csr = (fstart, self._fixed_pairs[:, 1].copy(),
                           *cluster_primitives(self._fixed, self._fixed_pairs, G))
        self._self_pairs = np.array(self_pairs, dtype=np.int64).reshape(-1, 2)
        self._lever: Array | None = None  # (G, K) for dense path checks, on first use
        self._obstacles: dict[str, Primitive] = {}
        self._dynamic: set[str] = set()
        if scene is not None:
            for o in scene.objects:
                if o.dynamic and static_only:
                    continue
                self._obstacles[o.name] = shape_primitive(o.shape, o.T_world_obj())
                if o.dynamic:
                    self._dynamic.add(o.name)
        self._scene_dynamic = frozenset(self._dynamic)   # set_obstacles keeps these
        self._static = pack([p for n, p in self._obstacles.items() if n not in self._dynamic])
        self._build_grids(grid_spacing)
        self._pack_env()

    def _build_grids(self, h: float) -> None:
        """Distance grids over the arm's reach: [0] static obstacles, then fixed robot parts."""
        rng = np.random.default_rng(0)
        sample = self.robot.sample_uniform(rng, 4000)
        Rb, pb = np.empty((self.robot.dof, 3, 3)), np.empty((self.robot.dof, 3))
        pts = np.empty((len(sample) * len(self.spheres), 3))
        out = np.empty((len(self.spheres), 3))
        for n, q in enumerate(sample):
            kernels.chain_fk(q, *self._chain, Rb, pb)
            kernels.transform_points(Rb, pb, self._sphere_arrays[2], self._sphere_arrays[0], out)
            pts[n * len(out):(n + 1) * len(out)] = out
        pad = float(self.spheres.radii.max()) + 0.15
        lo = np.floor((pts.min(axis=0) - pad) * 10) / 10  # round so equal robots share grids
        hi = np.ceil((pts.max(axis=0) + pad) * 10) / 10
        h = max(h, float(np.cbrt(np.prod(hi - lo) / 4e6)))  # at most ~4 M cells a grid
        # grid 0: static obstacles; then one grid per distinct set of fixed robot parts that
        # a group is checked against (few sets: most groups share one). These depend on the
        # robot alone and are cached for the process.
        fstart, fidx = self._fixed_csr[:2]
        sets: dict[tuple[int, ...], int] = {}
        gfix = np.full(len(fstart) - 1, -1, dtype=np.int64)
        for g in range(len(gfix)):
            key = tuple(sorted(set(fidx[fstart[g]:fstart[g + 1]].tolist())))
            if key:
                gfix[g] = sets.setdefault(key, len(sets) + 1)
        rkey = (self.robot.description, self.robot.T_world_base.tobytes(), lo.tobytes(),
                hi.tobytes(), h)
        # Each grid also comes at three times the spacing (1/27 of the memory) for the groups'
        # bounding spheres: those lookups, a few dozen per configuration at random places,
        # then mostly hit the cache; spheres keep the fine grids, which decide more of them.
        # Same decisions; measured in one process on 100k configurations against fine grids
        # only: 13% less time on shelf_boxes and kitchen, the same on tabletop_pole.
        if rkey not in _FIXED_GRID_CACHE:
            _FIXED_GRID_CACHE.clear()  # keep one robot's grids at most
            _FIXED_GRID_CACHE[rkey] = [
                build_grid(lo, hi, hh, pack([self.fixed_primitives[i] for i in key]))
                for hh in (h, 3 * h) for key in sets] + self._surface_grids(lo, hi, h, sets)
        fixed_grids = _FIXED_GRID_CACHE[rkey]
        n = len(sets)
        grids = [build_grid(lo, hi, h, self._static), *fixed_grids[:n], *fixed_grids[2 * n:]]
        coarse = [build_grid(lo, hi, 3 * h, self._static), *fixed_grids[n:2 * n]]
        # the grid that proves an inner ball touches group g's fixed parts: their own grid when
        # all are solids, else a surface grid (after the fixed ones), none without inner balls
        gsurf = gfix.copy()
        surface = iter(range(n + 1, len(grids)))   # in the order _surface_grids made them
        for m, key in enumerate(sets, start=1):
            if any(self.fixed_primitives[i].triangles is not None for i in key):
                gsurf[gfix == m] = next(surface, -1)
        self._gexact = (*self._gexact[:13], gsurf)
        self.grids = grids + coarse
        # (origin, h, delta, fine values (M, n0, n1, n2), gfix, coarse h, coarse values,
        #  group visiting order) — what validity.config_collides unpacks
        self._grids = (grids[0].origin, grids[0].h, grids[0].delta,
                       np.stack([g.values for g in grids]), gfix, coarse[0].h,
                       np.stack([g.values for g in coarse]),
                       np.arange(len(gfix), dtype=np.int64))
        # visit the groups that are most often near something first (same decisions; a
        # colliding configuration is then usually settled by its first groups)
        rate = validity.group_block_rates(sample[:2000], self._chain, self._groups, self._grids)
        order = np.argsort(-rate, kind="stable").astype(np.int64)
        self._grids = (*self._grids[:7], order)

    def _surface_grids(self, lo: Array, hi: Array, h: float, sets: dict[tuple[int, ...], int]
                       ) -> list:
        """A surface grid (``grid.build_surface_grid``) for each set of fixed parts that has
        mesh clusters (none when no sphere has an inner ball): distances to its solids and to
        points on its meshes' triangles (the corners of pieces with edges of at most 2 cm:
        every surface point is within 12 mm of one), within the largest inner ball radius
        plus two voxels."""
        reach = float(self._rin.max(initial=0.0)) + 2 * h
        if reach <= 2 * h:
            return []
        fields = {}   # per fixed mesh: its point field, shared by the sets holding it
        for f, idx in self._fixed_of.items():
            tris = [t for i in idx if (t := self.fixed_primitives[i].triangles) is not None]
            if len(tris) == len(idx):
                corners = split_triangles(np.concatenate(tris), 0.02).reshape(-1, 3)
                fields[f] = point_field(lo, hi, h, corners, reach)
        out = []
        for key in sets:
            owners = [f for f, idx in self._fixed_of.items() if f in fields and idx[0] in key]
            if owners:
                solid = pack([self.fixed_primitives[i] for i in key
                              if self.fixed_primitives[i].triangles is None])
                out.append(build_surface_grid(lo, hi, h, solid, [fields[f] for f in owners],
                                              reach))
        return out

    # --- obstacles ----------------------------------------------------------------------
    def _pack_env(self) -> None:
        self.obstacles_version = getattr(self, "obstacles_version", -1) + 1
        self._env = pack(list(self._obstacles.values()))
        self._dyn = pack([self._obstacles[n] for n in self._obstacles if n in self._dynamic])
        self.obstacle_names = list(self._obstacles)

    def add_obstacle(self, name: str, shape: Shape, T_world_obj: Array) -> None:
        """Add a dynamic obstacle; nothing else is rebuilt."""
        if name in self._obstacles:
            raise KeyError(f"obstacle '{name}' already exists; use move_obstacle")
        self._obstacles[name] = shape_primitive(shape, np.asarray(T_world_obj, dtype=float))
        self._dynamic.add(name)
        self._pack_env()

    def set_obstacles(self, obstacles: Mapping[str, tuple[Shape, Array]]) -> None:
        """Make ``obstacles`` (name → (shape, T_world_obj (4, 4))) the obstacles added since
        construction, all
        at once (one repacking, however many change); the scene's own dynamic objects stay."""
        added = self._dynamic - self._scene_dynamic
        clash = set(obstacles) & (set(self._obstacles) - added)
        if clash:
            raise KeyError(f"obstacle names already used by the scene: {sorted(clash)}")
        for name in added:
            del self._obstacles[name]
        self._dynamic = set(self._scene_dynamic)
        for name, (shape, T) in obstacles.items():
            self._obstacles[name] = shape_primitive(shape, np.asarray(T, dtype=float))
            self._dynamic.add(name)
        self._pack_env()

    def move_obstacle(self, name: str, T_world_obj: Array) -> None:
        """Move a dynamic obstacle to a new pose T_world_obj (4, 4)."""
        if name not in self._dynamic:
            raise KeyError(f"'{name}' is not a dynamic obstacle; dynamic: {self.dynamic_obstacles}")
        old = self._obstacles[name]
        self._obstacles[name] = Primitive(old.kind, np.asarray(T_world_obj, dtype=float), old.size)
        self._pack_env()

    def remove_obstacle(self, name: str) -> None:
        """Remove a dynamic obstacle."""
        if name not in self._dynamic:
            raise KeyError(f"'{name}' is not a dynamic obstacle; dynamic: {self.dynamic_obstacles}")
        del self._obstacles[name]
        self._dynamic.discard(name)
        self._pack_env()

    @property
    def dynamic_obstacles(self) -> list[str]:
        return sorted(self._dynamic)

    @property
    def nbytes(self) -> int:
        """Memory held by the distance grids (bytes)."""
        return sum(g.nbytes for g in self.grids)

    # --- checks -------------------------------------------------------------------------
    def _args(self) -> tuple:
        return (self._chain, self._sphere_arrays, self._groups, self._static, self._dyn,
                self._fixed, self._fixed_csr, self._self_pairs, self._grids, self._gexact,
                self._rin)

    def _exact_args(self) -> tuple:
        return (self._chain, self._sphere_arrays, self._groups, self._env, self._fixed,
                self._fixed_pairs, self._self_pairs)

    def _as_batch(self, Q: Array) -> Array:
        Q = np.ascontiguousarray(np.atleast_2d(np.asarray(Q, dtype=float)))
        if Q.ndim != 2 or Q.shape[1] != self.robot.dof:
            raise RobotError(f"expected configurations of shape (N, {self.robot.dof}), "
                             f"got {Q.shape}")
        return Q

    def valid(self, Q: Array) -> BoolArray:
        """Collision-free flag for each configuration; Q (N, K) → (N,)."""
        return validity.valid_batch(self._as_batch(Q), *self._args())

    def is_valid(self, q: Array) -> bool:
        """Whether one configuration (K,) is collision-free."""
        return bool(self.valid(q)[0])

    def motions_valid(self, Q0: Array, Q1: Array, resolution: float = 0.02) -> BoolArray:
        """Whether each straight motion Q0[i] → Q1[i] is free at every ``resolution`` (rad)
        step of joint-space distance; end points are not checked."""
        Q0, Q1 = self._as_batch(Q0), self._as_batch(Q1)
        return dense_path.motions_valid_dense(Q0, Q1, float(resolution), self._levers(),
                                              *self._args())

    def motion_valid(self, q0: Array, q1: Array, resolution: float = 0.02) -> bool:
        """Whether the straight motion q0 → q1 and both end points are collision-free."""
        return bool(self.valid(np.vstack([q0, q1])).all()
                    and self.motions_valid(q0, q1, resolution)[0])

    def path_valid(self, path: Array, resolution: float = 0.02) -> bool:
        """Whether a waypoint path (T, K) is free at waypoints and along every segment."""
        P = self._as_batch(path)
        return bool(self.valid(P).all() and self.motions_valid(P[:-1], P[1:], resolution).all())

    def first_dense_collision(self, path: Array, substeps: int = 100, start: int = 0
                              ) -> int | None:
        """Index (>= ``start``) into ``densify(path, substeps)`` of the first configuration
        this checker calls colliding, or None: the same answer as
        ``valid(densify(path, substeps)[start:])``, computed with clearance certificates that
        skip most configurations (see ``dense_path.py``)."""
        P = self._as_batch(path)
        i = dense_path.first_dense_collision(P, int(substeps), int(start), self._levers(),
                                             *self._args())
        return None if i < 0 else int(i)

    def _levers(self) -> Array:
        """(G, K) lever-arm bounds of the groups (``dense_path.lever_arms``), built once."""
        if self._lever is None:
            parent, _, p0, _ = self._chain
            self._lever = dense_path.lever_arms(parent, p0, self._groups[3], self._groups[1])
        return self._lever

    def dense_path_valid(self, path: Array, substeps: int = 100) -> bool:
        """Whether every waypoint of path (T, K) and ``substeps`` interpolated configurations
        per segment are free (the paper's check, on this checker)."""
        return self.first_dense_collision(path, substeps) is None

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the validity, motion and path kernels now, so
        that no planner pays for compilation inside its time limit."""
        q0 = 0.5 * (self.robot.lower + self.robot.upper)
        q1 = q0 + 0.1
        self.valid(np.vstack([q0, q1]))
        self.motions_valid(q0[None], q1[None])
        self.first_dense_collision(np.vstack([q0, q1]), 2)

    def min_distance(self, Q: Array) -> Array:
        """Smallest signed distance (m) between the spheres and anything, per configuration."""
        return kernels.min_distance_batch(self._as_batch(Q), *self._exact_args())

    def contacts(self, q: Array, margin: float) -> Contacts:
        """Per-sphere contacts closer than ``margin`` (m) at one configuration (K,)."""
        q = self._as_batch(q)[0]
        return Contacts(*kernels.sphere_contacts(q, float(margin), *self._exact_args()))

    def sphere_centers(self, q: Array) -> Array:
        """World centres of every sphere at q, shape (M, 3)."""
        Rb, pb = self.joint_placements(q)
        out = np.empty((len(self.spheres), 3))
        kernels.transform_points(Rb, pb, self._sphere_arrays[2], self._sphere_arrays[0], out)
        return out

    def joint_placements(self, q: Array) -> tuple[Array, Array]:
        """World rotation (K, 3, 3) and origin (K, 3) of each group joint at q (numba FK)."""
        q = self._as_batch(q)[0]
        Rb, pb = np.empty((self.robot.dof, 3, 3)), np.empty((self.robot.dof, 3))
        kernels.chain_fk(q, *self._chain, Rb, pb)
        return Rb, pb


def exact_geometry(robot: Robot, geoms: list[int], sp: SphereModel
                   ) -> tuple[tuple, Array]:
    """The covered geometry of each sphere group in its joint's frame, for confirming sphere
    hits (``validity.py``), and each sphere's inner radius.

    Returns ((kind (G,), R (G, 3, 3), p (G, 3), size (G, 3), pad (G,), pstart (G+1,),
    vstart (P+1,), V (NV, 3), centre (P, 3)), rin (M,)). Group g's geometry is a box,
    cylinder or sphere (kind 0-2, size as the kernels read it) or, for a mesh, the convex
    hulls of its connected parts (kind ``gjk.HULL``); -1 where neither (its sphere hits are
    collisions). Its parts are pstart[g]:pstart[g+1] (one with no points for a primitive, one
    per mesh part), part k's support points V[vstart[k]:vstart[k+1]] in the geometry's frame
    (R, p) and centre[k] a point inside it. pad (m): the margin the confirmation keeps
    (:data:`CONFIRM_PAD`, or the spheres' padding when smaller). rin (m): the radius of the
    ball about each sphere's centre that lies inside its primitive (0 when none, and for
    meshes: the inner ball tests are for solids).
    """
    G = len(geoms)
    kind = np.full(G, -1, dtype=np.int64)
    R = np.tile(np.eye(3), (G, 1, 1))
    p = np.zeros((G, 3))
    size = np.zeros((G, 3))
    pad = np.full(G, float(np.clip(robot.description.spheres.padding, 1e-5, CONFIRM_PAD)))
    rin = np.zeros(len(sp))
    parts: list[list[Array]] = []
    cm = robot.collision_model
    for i, gi in enumerate(geoms):
        go = cm.geometryObjects[gi]
        g = go.geometry
        R[i], p[i] = go.placement.rotation, go.placement.translation
        parts.append([np.zeros((0, 3))])
        if isinstance(g, coal.Box):
            kind[i], size[i] = kernels.BOX, np.asarray(g.halfSide, dtype=float)
        elif isinstance(g, coal.Cylinder):
            kind[i], size[i] = kernels.CYLINDER, (g.radius, g.halfLength, 0.0)
        elif isinstance(g, coal.Sphere):
            kind[i], size[i] = kernels.SPHERE, (g.radius, 0.0, 0.0)
        elif hasattr(g, "num_tris"):
            kind[i], parts[i] = HULL, hull_parts(g)
            continue
        else:
            parts[i] = []
            continue
        for s in np.flatnonzero(sp.geometries == gi):
            d = kernels.signed_distance(kind[i], R[i], p[i], size[i], sp.centers[s])
            rin[s] = max(0.0, -d - 1e-9)
    return (kind, R, p, size, pad, *_pack_parts(parts)), rin


def _pack_parts(parts: list[list[Array]]
                ) -> tuple[NDArray[np.int64], NDArray[np.int64], Array, Array]:
    """(pstart (G+1,), vstart (P+1,), V (NV, 3), centre (P, 3)) of each group's parts (lists
    of support points, (n, 3) each; n = 0 for a primitive, whose centre is its origin)."""
    flat = [pts for group in parts for pts in group]
    pstart = np.cumsum([0] + [len(group) for group in parts]).astype(np.int64)
    vstart = np.cumsum([0] + [len(pts) for pts in flat]).astype(np.int64)
    V = np.vstack([np.zeros((0, 3)), *flat]).astype(float)
    centre = np.array([pts.mean(axis=0) if len(pts) else np.zeros(3) for pts in flat],
                      dtype=float).reshape(-1, 3)
    return pstart, vstart, V, centre


def pinocchio_joint_placements(robot: Robot, q: Array) -> list[pin.SE3]:
    """Reference for tests: pinocchio's world placement of each group joint."""
    pin.forwardKinematics(robot.model, robot.data, np.asarray(q, dtype=float))
    return [robot.data.oMi[k].copy() for k in range(1, robot.model.njoints)]
