"""The robot and its world packed once, as named tuples of arrays for the compiled kernels.

:func:`pack_world` builds a :class:`PackedWorld`: the kinematic chain, the covering spheres and
their groups, the geometry each group covers, the fixed robot parts, the scene's obstacles and
the distance grids. The fast checker (``fast.py``), the dense path check (``dense_path.py``)
and the optimiser's distance terms (``distance_terms.py``) all read it by attribute
(``world.chain.parent``, ``world.spheres.radius``, …): numba takes a ``NamedTuple`` of arrays as
a tuple with named fields, so the names cost nothing in compiled code. Dynamic obstacles live
in their own fields (:func:`with_obstacles` replaces them and nothing else), so adding, moving
or removing one repacks a few small arrays. Integer codes are those of ``codes.py``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from itertools import pairwise
from typing import NamedTuple

import coal
import numpy as np
from numpy.typing import NDArray

from chekhov.collision import codes, validity
from chekhov.collision.grid import DistanceGrid, build_grid, build_surface_grid, point_field
from chekhov.collision.kernels import signed_distance, transform_points
from chekhov.collision.primitives import (
    PrefixPacker,
    Primitive,
    Primitives,
    bounding_radius,
    cluster_primitives,
    fixed_points,
    geometry_primitives,
    hull_depth,
    hull_parts,
    pack_primitives,
    shape_primitive,
    split_triangles,
)
from chekhov.collision.self_table import SelfTables, robot_self_tables
from chekhov.robot.chain_kinematics import KinematicChain, chain_fk, kinematic_chain
from chekhov.robot.robot import Robot
from chekhov.robot.spheres import SphereModel, build_sphere_model
from chekhov.scene.model import Scene

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

CONFIRM_PAD = 1e-4
"""m: how far apart a confirmation (GJK on the covered geometry) must prove two shapes. Its
certificate is an exact support-function bound, so this only has to absorb rounding and the
exact checker's own tolerances (coal's GJK: about 1e-6 m). The spheres' padding (1-2 mm)
would call every configuration within it colliding: a third of those within 5 mm of contact
(measured with benchmarks/collision.py on the near-contact configurations)."""
HULL_DEPTH_SLACK = 1e-6
"""m taken off a mesh sphere's inner radius: qhull's facet planes are exact to rounding only."""
GRID_SAMPLES = 4000
"""Random configurations whose spheres size the grids' box (the arm's reach); the first 2000
also rank the groups for :attr:`Grids.order`."""


class Spheres(NamedTuple):
    """The covering spheres (S of them), grouped by covered geometry (contiguous).

    centre (S, 3) in its joint's frame, m; radius (S,) m, padding included; joint (S,) int64;
    inner (S,) m: radius of the ball about the centre that lies inside the covered geometry
    when that is a solid primitive (0 otherwise): such a ball touching something is certain
    contact."""

    centre: Array
    radius: Array
    joint: IntArray
    inner: Array


class Groups(NamedTuple):
    """The spheres covering one collision geometry form a group (G of them).

    start (G+1,): group g's spheres are start[g]:start[g+1]; centre (G, 3) (joint frame) and
    radius (G,) of a bounding sphere of them, m; joint (G,); lever (G, K): bounds on the
    distance (m) from joint k's origin to the centre over all configurations, 0 for joints
    that do not move it (:func:`lever_arms`); self_pairs (P, 2): the group pairs
    checked for self-collision."""

    start: IntArray
    centre: Array
    radius: Array
    joint: IntArray
    lever: Array
    self_pairs: IntArray


class GroupGeometry(NamedTuple):
    """The geometry each group covers, in its joint's frame, to confirm sphere hits on it.

    kind (G,): ``SPHERE`` / ``BOX`` / ``CYLINDER`` (size as the kernels read it), ``HULL`` for
    a mesh (the convex hulls of its connected parts) or ``NO_GEOMETRY``; R (G, 3, 3), p (G, 3)
    its placement; size (G, 3); pad (G,) m: the margin a confirmation keeps. Group g's parts
    are part_start[g]:part_start[g+1] (one with no points for a primitive); part k's support
    points verts[vert_start[k]:vert_start[k+1]] (geometry frame), part_centre[k] a point inside
    it, part_radius[k] (m) the radius of a ball about it that holds the part."""

    kind: IntArray
    R: Array
    p: Array
    size: Array
    pad: Array
    part_start: IntArray
    vert_start: IntArray
    verts: Array
    part_centre: Array
    part_radius: Array


class Clusters(NamedTuple):
    """Fixed robot parts grouped in space (L clusters): centre (L, 3) and radius (L,) of a
    bounding sphere, m; members[start[c]:start[c+1]] the parts of cluster c."""

    centre: Array
    radius: Array
    start: IntArray
    members: IntArray


class FixedParts(NamedTuple):
    """The robot's parts that do not move with the group (F primitives; meshes are boxes that
    contain them, see ``primitives.geometry_primitives``).

    prims: the primitives; hull_kind (F,): what a hit on part f is confirmed against — ``HULL``
    (the support points verts[vert_start[f]:vert_start[f+1]], primitive frame, of the mesh
    part inside the box) or the primitive's own kind; centre (F, 3) a point inside it, world;
    pairs (P, 2) the (group, part) pairs checked, sorted; allowed (G, F) bool, the same as a
    table; clusters: :class:`Clusters`."""

    prims: Primitives
    hull_kind: IntArray
    vert_start: IntArray
    verts: Array
    centre: Array
    pairs: IntArray
    allowed: NDArray[np.bool_]
    clusters: Clusters


class Grids(NamedTuple):
    """Distance grids (``grid.py``) over the arm's reach, stacked.

    origin (3,) m; h, inv_h: the fine spacing (m) and its inverse; delta (m) the quantum;
    fine (M, n0, n1, n2) uint8: [0] static obstacles, then one grid per set of fixed parts a
    group is checked against, then the surface grids; coarse_h, inv_coarse_h, coarse: the same
    static and fixed-part grids at three times the spacing (for the groups' bounding spheres),
    then, per set of fixed parts, the nearer of the static grid and that set's (elementwise
    minimum: a sphere it proves clear is clear of both, so one lookup clears most groups);
    clear (G,): that coarse grid for group g (the static grid when g has no fixed parts);
    fixed (G,): group g's fixed-part grid, ``NONE`` when it has none; surface (G,): the grid
    that proves an inner ball touches g's fixed parts (their own grid when all are solids,
    else a surface grid), ``NONE`` when none; order (G,): the order the validity test visits
    the groups in (the most often blocked first)."""

    origin: Array
    h: float
    inv_h: float
    delta: float
    fine: NDArray[np.uint8]
    coarse_h: float
    inv_coarse_h: float
    coarse: NDArray[np.uint8]
    clear: IntArray
    fixed: IntArray
    surface: IntArray
    order: IntArray


class PackedWorld(NamedTuple):
    """Everything the compiled kernels read, built once by :func:`pack_world`.

    chain: :class:`~chekhov.robot.chain_kinematics.KinematicChain`; spheres, groups, geometry
    (the geometry each group covers), fixed (fixed robot parts), grids: see their classes;
    static, dynamic: the scene's static and dynamic obstacles; obstacles: all of them, in the
    order of ``FastChecker.obstacle_names`` (contacts and distance terms index it);
    self_tables: gap bounds of the self pairs one or two joints move, and of the groups one or
    two joints move against the fixed parts (``self_table.py``)."""

    chain: KinematicChain
    spheres: Spheres
    groups: Groups
    geometry: GroupGeometry
    fixed: FixedParts
    grids: Grids
    static: Primitives
    dynamic: Primitives
    obstacles: Primitives
    self_tables: SelfTables

    @property
    def grid_bytes(self) -> int:
        """Memory held by the distance grids (bytes)."""
        return int(self.grids.fine.nbytes + self.grids.coarse.nbytes)


def with_obstacles(world: PackedWorld, dynamic: Iterable[Primitive],
                   obstacles: Iterable[Primitive],
                   packers: tuple[PrefixPacker, PrefixPacker] | None = None) -> PackedWorld:
    """``world`` with new dynamic obstacles and obstacle list (all obstacles, static ones
    included, in name order); nothing else is rebuilt. ``packers`` (one for each list) reuse
    what the lists share with their last call's."""
    if packers is None:
        return world._replace(dynamic=pack_primitives(dynamic),
                              obstacles=pack_primitives(obstacles))
    return world._replace(dynamic=packers[0].pack(dynamic), obstacles=packers[1].pack(obstacles))


def scene_obstacles(scene: Scene | None, static_only: bool = False
                    ) -> dict[str, tuple[Primitive, bool]]:
    """Name → (primitive, dynamic?) of the scene's objects, dynamic ones left out with
    ``static_only``."""
    if scene is None:
        return {}
    return {o.name: (shape_primitive(o.shape, o.T_world_obj()), o.dynamic)
            for o in scene.objects if not (o.dynamic and static_only)}


class GridCache:
    """Distance grids of fixed robot parts, which depend on the robot alone, kept between
    :func:`pack_world` calls that are handed this cache (one robot's at most). Owned by whoever
    builds several checkers for one robot (a ``World``: its planning and roadmap checkers)."""

    def __init__(self) -> None:
        self._key: tuple | None = None
        self._grids: list[DistanceGrid] = []

    def get(self, key: tuple, build: Callable[[], list[DistanceGrid]]) -> list[DistanceGrid]:
        """The grids stored under ``key``, built (and kept, replacing any others) if absent."""
        if self._key != key:
            self._grids = build()
            self._key = key
        return self._grids


def pack_world(robot: Robot, scene: Scene | None = None, *, spheres: SphereModel | None = None,
               static_only: bool = False, grid_spacing: float = 0.02,
               seed: int | np.random.Generator = 0, grid_cache: GridCache | None = None
               ) -> PackedWorld:
    """Pack ``robot`` in ``scene`` for the kernels.

    spheres: the cover (``build_sphere_model(robot)`` by default); static_only: leave the
    scene's dynamic objects out; grid_spacing (m): of the fine grids (coarser when the reach
    would need more than ~4 M cells); seed: of the :data:`GRID_SAMPLES` random configurations
    that size the grids and order the groups (0 by default, so that equal robots get equal
    grids); grid_cache: where fixed-part grids are reused from (none by default)."""
    sp = spheres if spheres is not None else build_sphere_model(robot)
    chain = kinematic_chain(robot)
    geoms = list(dict.fromkeys(sp.geometries.tolist()))
    geometry, inner = exact_geometry(robot, geoms, sp)
    sph = Spheres(sp.centers.astype(float), sp.radii.astype(float), sp.joints.astype(np.int64),
                  inner)
    fixed_prims, fixed_of, fixed, self_pairs = _fixed_parts(robot, geoms)
    groups = _groups(sp, geoms, chain, self_pairs)
    obstacles = scene_obstacles(scene, static_only)
    static = pack_primitives(p for p, dyn in obstacles.values() if not dyn)
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    sample = robot.sample_uniform(rng, GRID_SAMPLES)
    grids = _build_grids(robot, chain, sph, sample, fixed_prims, fixed_of, fixed.pairs,
                         len(geoms), static, grid_spacing, grid_cache)
    rate = validity.group_block_rates(sample[:2000], chain, groups, grids)
    grids = grids._replace(order=np.argsort(-rate, kind="stable").astype(np.int64))
    return PackedWorld(
        chain=chain, spheres=sph, groups=groups, geometry=geometry, fixed=fixed, grids=grids,
        static=static, dynamic=pack_primitives(p for p, dyn in obstacles.values() if dyn),
        obstacles=pack_primitives(p for p, _ in obstacles.values()),
        self_tables=robot_self_tables(robot, chain, groups, geometry, fixed,
                                      sph.centre.tobytes() + sph.radius.tobytes()))


def lever_arms(parent: np.ndarray, p_parent_joint: np.ndarray, group_joint: np.ndarray,
               group_centre: np.ndarray) -> np.ndarray:
    """(G, K) bounds on the distance (m) from each joint's origin to each group's centre over
    all configurations: the sum of the joint-to-joint offsets along the chain plus the centre's
    offset from its own joint (triangle inequality); 0 for joints that do not move the group."""
    G, K = len(group_joint), len(parent)
    out = np.zeros((G, K))
    offset = np.linalg.norm(p_parent_joint, axis=1)
    for g in range(G):
        j = int(group_joint[g])
        reach = float(np.linalg.norm(group_centre[g]))
        i = j
        while i >= 0:
            out[g, i] = reach
            reach += offset[i]  # joint i's origin from its parent's
            i = int(parent[i])
    return out


def _groups(sp: SphereModel, geoms: list[int], chain: KinematicChain, self_pairs: IntArray
            ) -> Groups:
    """One group per covered geometry, with a bounding sphere in its joint's frame."""
    starts = [int(np.flatnonzero(sp.geometries == g)[0]) for g in geoms] + [len(sp)]
    gc = np.array([sp.centers[a:b].mean(axis=0) for a, b in pairwise(starts)]).reshape(-1, 3)
    gr = np.array([np.max(np.linalg.norm(sp.centers[a:b] - gc[i], axis=1) + sp.radii[a:b])
                   for i, (a, b) in enumerate(pairwise(starts))])
    gj = np.array([sp.joints[a] for a in starts[:-1]], dtype=np.int64)
    return Groups(start=np.array(starts, dtype=np.int64), centre=gc, radius=gr, joint=gj,
                  lever=lever_arms(chain.parent, chain.p_parent_joint, gj, gc),
                  self_pairs=self_pairs)


def _fixed_parts(robot: Robot, geoms: list[int]
                 ) -> tuple[list[Primitive], dict[int, list[int]], FixedParts, IntArray]:
    """Fixed robot parts and self-collision pairs, from the robot's pair list: (the parts'
    primitives, fixed geometry → its primitives' indices, the packed parts, the group pairs
    checked for self-collision (P, 2))."""
    group_of = {g: i for i, g in enumerate(geoms)}
    prims: list[Primitive] = []
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
            new = geometry_primitives(go.geometry, go.placement.homogeneous)
            fixed_of[f] = list(range(len(prims), len(prims) + len(new)))
            prims += new
        fixed_pairs += [(group_of[g], i) for i in fixed_of[f]]
    packed = pack_primitives(prims)
    pairs = np.array(sorted(fixed_pairs), dtype=np.int64).reshape(-1, 2)
    allowed, cc, cr, cs, cm_ = cluster_primitives(packed, pairs, len(geoms))
    hull_kind, vert_start, verts, centre = fixed_points(prims)
    fixed = FixedParts(prims=packed, hull_kind=hull_kind, vert_start=vert_start, verts=verts,
                       centre=centre, pairs=pairs, allowed=allowed,
                       clusters=Clusters(cc, cr, cs, cm_))
    return prims, fixed_of, fixed, np.array(self_pairs, dtype=np.int64).reshape(-1, 2)


def _grid_box(robot: Robot, chain: KinematicChain, sph: Spheres, sample: Array, h: float
              ) -> tuple[Array, Array, float]:
    """(lo, hi, h): the box (m) the spheres reach over ``sample`` (padded, rounded to 10 cm so
    that equal robots share grids) and the fine spacing, at most ~4 M cells a grid."""
    K = robot.dof
    Rb, pb = np.empty((K, 3, 3)), np.empty((K, 3))
    S = len(sph.radius)
    pts = np.empty((len(sample) * S, 3))
    out = np.empty((S, 3))
    for n, q in enumerate(sample):
        chain_fk(q, chain, Rb, pb)
        transform_points(Rb, pb, sph.joint, sph.centre, out)
        pts[n * S:(n + 1) * S] = out
    pad = float(sph.radius.max()) + 0.15
    lo = np.floor((pts.min(axis=0) - pad) * 10) / 10
    hi = np.ceil((pts.max(axis=0) + pad) * 10) / 10
    return lo, hi, max(h, float(np.cbrt(np.prod(hi - lo) / 4e6)))


def _build_grids(robot: Robot, chain: KinematicChain, sph: Spheres, sample: Array,
                 fixed_prims: list[Primitive], fixed_of: dict[int, list[int]],
                 fixed_pairs: IntArray, n_groups: int, static: Primitives, spacing: float,
                 cache: GridCache | None) -> Grids:
    """The :class:`Grids` (group order: as packed; :func:`pack_world` ranks them after).

    Grid 0 holds the static obstacles; then one grid per distinct set of fixed robot parts
    that a group is checked against (few sets: most groups share one). Each grid also comes at
    three times the spacing (1/27 of the memory) for the groups' bounding spheres: those
    lookups, a few dozen per configuration at random places, then mostly hit the cache;
    spheres keep the fine grids, which decide more of them. Same decisions; measured in one
    process on 100k configurations against fine grids only: 13% less time on shelf_boxes and
    kitchen, the same on tabletop_pole."""
    lo, hi, h = _grid_box(robot, chain, sph, sample, spacing)
    sets: dict[tuple[int, ...], int] = {}
    gfix = np.full(n_groups, codes.NONE, dtype=np.int64)
    for g in range(len(gfix)):
        key = tuple(sorted(set(fixed_pairs[fixed_pairs[:, 0] == g, 1].tolist())))
        if key:
            gfix[g] = sets.setdefault(key, len(sets) + 1)

    def build() -> list[DistanceGrid]:
        return [build_grid(lo, hi, hh, pack_primitives(fixed_prims[i] for i in key))
                for hh in (h, 3 * h) for key in sets] + _surface_grids(
            lo, hi, h, sets, fixed_prims, fixed_of, float(sph.inner.max(initial=0.0)))

    key = (robot.description, robot.T_world_base.tobytes(), lo.tobytes(), hi.tobytes(), h)
    fixed_grids = build() if cache is None else cache.get(key, build)
    n = len(sets)
    fine = [build_grid(lo, hi, h, static), *fixed_grids[:n], *fixed_grids[2 * n:]]
    coarse = [build_grid(lo, hi, 3 * h, static), *fixed_grids[n:2 * n]]
    both = [np.minimum(coarse[0].values, g.values) for g in coarse[1:]]
    clear = np.where(gfix >= 0, gfix + n, 0).astype(np.int64)
    gsurf = gfix.copy()
    surface = iter(range(n + 1, len(fine)))   # in the order _surface_grids made them
    for m, fkey in enumerate(sets, start=1):
        if any(fixed_prims[i].triangles is not None for i in fkey):
            gsurf[gfix == m] = next(surface, codes.NONE)
    return Grids(origin=fine[0].origin, h=fine[0].h, inv_h=1.0 / fine[0].h,
                 delta=fine[0].delta, fine=np.stack([g.values for g in fine]),
                 coarse_h=coarse[0].h, inv_coarse_h=1.0 / coarse[0].h,
                 coarse=np.stack([g.values for g in coarse] + both), clear=clear, fixed=gfix,
                 surface=gsurf,
                 order=np.arange(len(gfix), dtype=np.int64))


def _surface_grids(lo: Array, hi: Array, h: float, sets: dict[tuple[int, ...], int],
                   fixed_prims: list[Primitive], fixed_of: dict[int, list[int]],
                   inner_max: float) -> list[DistanceGrid]:
    """A surface grid (``grid.build_surface_grid``) for each set of fixed parts that has
    mesh clusters (none when no sphere has an inner ball): distances to its solids and to
    points on its meshes' triangles (the corners of pieces with edges of at most 2 cm:
    every surface point is within 12 mm of one), within the largest inner ball radius
    plus two voxels."""
    reach = inner_max + 2 * h
    if reach <= 2 * h:
        return []
    fields = {}   # per fixed mesh: its point field, shared by the sets holding it
    for f, idx in fixed_of.items():
        tris = [t for i in idx if (t := fixed_prims[i].triangles) is not None]
        if len(tris) == len(idx):
            corners = split_triangles(np.concatenate(tris), 0.02).reshape(-1, 3)
            fields[f] = point_field(lo, hi, h, corners, reach)
    out = []
    for key in sets:
        owners = [f for f, idx in fixed_of.items() if f in fields and idx[0] in key]
        if owners:
            solid = pack_primitives(fixed_prims[i] for i in key
                                    if fixed_prims[i].triangles is None)
            out.append(build_surface_grid(lo, hi, h, solid, [fields[f] for f in owners],
                                          reach))
    return out


def exact_geometry(robot: Robot, geoms: list[int], sp: SphereModel
                   ) -> tuple[GroupGeometry, Array]:
    """The covered geometry of each sphere group in its joint's frame (:class:`GroupGeometry`)
    and each sphere's inner radius (m): the ball about its centre inside a primitive, or for a
    mesh inside the convex hull of one of its parts (:func:`hull_parts`). The fast checker
    confirms a mesh group's hits on those hulls, so an inner ball touching something decides
    what the confirmation would decide, without it (0 where the centre is outside).

    pad: :data:`CONFIRM_PAD`, or the spheres' padding when smaller."""
    G = len(geoms)
    kind = np.full(G, codes.NO_GEOMETRY, dtype=np.int64)
    R = np.tile(np.eye(3), (G, 1, 1))
    p = np.zeros((G, 3))
    size = np.zeros((G, 3))
    pad = np.full(G, float(np.clip(robot.description.spheres.padding, 1e-5, CONFIRM_PAD)))
    rin = np.zeros(len(sp))
    parts: list[list[Array]] = []
    cm = robot.collision_model
    # a mesh's hull parts take up to a second to cut (hull_split.py): once per robot
    cache = robot.caches.setdefault("hull_parts", {})
    assert isinstance(cache, dict)
    for i, gi in enumerate(geoms):
        go = cm.geometryObjects[gi]
        g = go.geometry
        R[i], p[i] = go.placement.rotation, go.placement.translation
        parts.append([np.zeros((0, 3))])
        if isinstance(g, coal.Box):
            kind[i], size[i] = codes.BOX, np.asarray(g.halfSide, dtype=float)
        elif isinstance(g, coal.Cylinder):
            kind[i], size[i] = codes.CYLINDER, (g.radius, g.halfLength, 0.0)
        elif isinstance(g, coal.Sphere):
            kind[i], size[i] = codes.SPHERE, (g.radius, 0.0, 0.0)
        elif hasattr(g, "num_tris"):
            kind[i] = codes.HULL
            if gi not in cache:
                cache[gi] = hull_parts(g)
            parts[i] = cache[gi]
            mine = np.flatnonzero(sp.geometries == gi)
            X = (sp.centers[mine] - p[i]) @ R[i]       # the mesh's frame
            depth = np.max([hull_depth(v, X) for v in parts[i]], axis=0)
            rin[mine] = np.maximum(0.0, depth - HULL_DEPTH_SLACK)
            continue
        else:
            parts[i] = []
            continue
        for s in np.flatnonzero(sp.geometries == gi):
            d = signed_distance(kind[i], R[i], p[i], size[i], sp.centers[s])
            rin[s] = max(0.0, -d - 1e-9)
    pstart, vstart, V, centre, radius = _pack_parts(parts)
    primitive = (kind != codes.HULL) & (kind != codes.NO_GEOMETRY)   # one part, at its origin
    radius[pstart[:-1][primitive]] = bounding_radius(kind[primitive], size[primitive]) * (
        1 + 1e-12)   # rounding: as the mesh parts' radii
    return GroupGeometry(kind, R, p, size, pad, pstart, vstart, V, centre, radius), rin


def _pack_parts(parts: list[list[Array]]) -> tuple[IntArray, IntArray, Array, Array, Array]:
    """(part_start (G+1,), vert_start (P+1,), verts (NV, 3), part_centre (P, 3), part_radius
    (P,)) of each group's parts (lists of support points, (n, 3) each; n = 0 for a primitive,
    whose centre is its origin and whose radius is left 0)."""
    flat = [pts for group in parts for pts in group]
    pstart = np.cumsum([0] + [len(group) for group in parts]).astype(np.int64)
    vstart = np.cumsum([0] + [len(pts) for pts in flat]).astype(np.int64)
    V = np.vstack([np.zeros((0, 3)), *flat]).astype(float)
    centre = np.array([pts.mean(axis=0) if len(pts) else np.zeros(3) for pts in flat],
                      dtype=float).reshape(-1, 3)
    radius = np.array([np.linalg.norm(pts - c, axis=1).max() * (1 + 1e-12) if len(pts) else 0.0
                       for pts, c in zip(flat, centre, strict=True)], dtype=float)
    return pstart, vstart, V, centre, radius
