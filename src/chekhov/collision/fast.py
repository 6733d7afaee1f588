"""The fast checker: the robot as covering spheres against primitive obstacles, numba-compiled.

Used by every planner. It is conservative by construction (the spheres contain the robot's
collision geometry and meshes of fixed robot parts are replaced by boxes containing them), so it
never calls a configuration free that the exact checker calls colliding.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin
from numba import typeof
from numpy.typing import NDArray

from chekhov.collision import dense_path, kernels, validity
from chekhov.collision.codes import NONE
from chekhov.collision.motion_memo import MotionMemo
from chekhov.collision.packed import (
    GridCache,
    PackedWorld,
    pack_world,
    scene_obstacles,
    with_obstacles,
)
from chekhov.collision.primitives import (
    PrefixPacker,
    Primitive,
    Primitives,
    pack_primitives,
    shape_primitive,
)
from chekhov.collision.trajectory_distances import TrajectoryDistances
from chekhov.errors import RobotError
from chekhov.robot.chain_kinematics import chain_fk
from chekhov.robot.robot import Robot
from chekhov.robot.spheres import SphereModel, build_sphere_model
from chekhov.scene.model import Scene, Shape

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
_NO_MARGIN = np.zeros(0)   # dense_path.first_dense_collision in the world as it is


@dataclass(frozen=True)
class Contacts:
    """Sphere contacts within a margin at one configuration (C contacts).

    Attributes:
        sphere: sphere index (C,).
        other: obstacle index (``source`` ``codes.OBSTACLE``: into ``obstacle_names``), fixed
            robot part (``FIXED``) or sphere (``SELF``), (C,).
        source: (C,) as above.
        distance: signed surface distance (C,), metres, negative in penetration.
        normal: unit world direction (C, 3) along which moving the sphere increases distance.
        point: witness point on the sphere's surface, world (C, 3).
    """

    sphere: NDArray[np.int64]
    other: NDArray[np.int64]
    source: NDArray[np.int64]
    distance: Array
    normal: Array
    point: Array

    def __len__(self) -> int:
        return len(self.distance)


class FastChecker:
    """Batched collision checks of the robot's spheres against the scene's primitives.

    Configurations are arrays of shape (K,) or (N, K) in radians. Obstacles from the scene
    (static and dynamic) are named; dynamic ones can be added, moved and removed at run time
    without rebuilding anything else; ``obstacles_version`` counts those changes, so callers
    can tell when cached validity results went stale. Static obstacles and fixed robot parts
    are compiled once into distance grids (``grid_spacing`` m) that clear most spheres with one
    lookup. A sphere hit is confirmed on the covered geometry itself when it is a primitive
    (see ``validity.py``), so the spheres' overhang past the geometry raises no false alarms.

    Everything the kernels read is :attr:`packed` (``packed.pack_world``); ``seed`` and
    ``grid_cache`` are handed to it (the grids' sample of configurations, 0 by default, and
    where fixed-part grids are reused from: by default a cache the robot keeps in
    ``Robot.caches``, so that checkers of one robot, e.g. a world's and its roadmap
    builder's, build them once). The kernels compile (or load
    from numba's cache) on first use; :meth:`warm_up` does it ahead of a time limit.
    """

    def __init__(self, robot: Robot, scene: Scene | None = None,
                 spheres: SphereModel | None = None, static_only: bool = False,
                 grid_spacing: float = 0.02, seed: int | np.random.Generator = 0,
                 grid_cache: GridCache | None = None) -> None:
        self.robot = robot
        self.spheres = spheres if spheres is not None else build_sphere_model(robot)
        if grid_cache is None:   # the robot's own: its fixed parts' grids depend on it alone
            cache = robot.caches.setdefault("fixed_part_grids", GridCache())
            assert isinstance(cache, GridCache)
            grid_cache = cache
        self.packed: PackedWorld = pack_world(
            robot, scene, spheres=self.spheres, static_only=static_only,
            grid_spacing=grid_spacing, seed=seed, grid_cache=grid_cache)
        obstacles = scene_obstacles(scene, static_only)
        self._obstacles: dict[str, Primitive] = {n: p for n, (p, _) in obstacles.items()}
        self._dynamic: set[str] = {n for n, (_, dyn) in obstacles.items() if dyn}
        self._scene_dynamic = frozenset(self._dynamic)   # set_obstacles keeps these
        self._entries: dict[Any, Any] = {}
        self._layout = _layout(self.packed)
        self._clear_worlds: dict[float, tuple[int, PackedWorld]] = {}
        self._motion_memo = MotionMemo()
        self._packers = (PrefixPacker(), PrefixPacker())
        # packed_with's: the scene's own obstacles packed (dynamic ones, all), until they change
        self._scene_packed: tuple[Primitives, Primitives] | None = None
        self.obstacles_version = 0
        self.obstacle_names = list(self._obstacles)

    # --- obstacles ----------------------------------------------------------------------
    def _pack_env(self) -> None:
        """Repack the obstacles. The compiled entry points stay when the new arrays have the
        old ones' numba types (they do: ``pack_primitives`` makes C-contiguous arrays of
        fixed dtypes and dimensions, and :func:`_layout` compares them as numba types them):
        typing the packed world again, on the first call of each kernel after every change,
        cost about 1 ms — 40% of the executive's control step, which sets the obstacles
        several times a tick."""
        self.obstacles_version += 1
        self.packed = with_obstacles(
            self.packed, [self._obstacles[n] for n in self._obstacles if n in self._dynamic],
            self._obstacles.values(), self._packers)
        self.obstacle_names = list(self._obstacles)
        layout = _layout(self.packed)
        if layout != self._layout:
            self._entries.clear()
            self._layout = layout

    def add_obstacle(self, name: str, shape: Shape, T_world_obj: Array) -> None:
        """Add a dynamic obstacle; nothing else is rebuilt."""
        if name in self._obstacles:
            raise KeyError(f"obstacle '{name}' already exists; use move_obstacle")
        self._obstacles[name] = shape_primitive(shape, np.asarray(T_world_obj, dtype=float))
        self._dynamic.add(name)
        self._scene_packed = None   # packed_with's scene part
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

    def packed_with(self, added: Primitives) -> PackedWorld:
        """:attr:`packed` as :meth:`set_obstacles` would make it with ``added`` (already
        packed primitives) as the obstacles added since construction, the scene's own
        staying — without changing this checker: for :meth:`valid_in` (the executive packs
        each time window's predicted sweep every sensor frame; through obstacle objects and
        :meth:`set_obstacles`, ~0.3 ms a window). The same arrays as :meth:`set_obstacles`
        makes of obstacles that pack to ``added``: the scene's obstacles in their order, then
        ``added``."""
        if self._scene_packed is None:
            kept = [(n, p) for n, p in self._obstacles.items()
                    if n in self._scene_dynamic or n not in self._dynamic]
            self._scene_packed = (
                pack_primitives([p for n, p in kept if n in self._scene_dynamic]),
                pack_primitives([p for _, p in kept]))
        dynamic, everything = (
            Primitives(*(np.concatenate([a, b]) for a, b in zip(base, added, strict=True)))
            for base in self._scene_packed)
        return self.packed._replace(dynamic=dynamic, obstacles=everything)

    def move_obstacle(self, name: str, T_world_obj: Array) -> None:
        """Move a dynamic obstacle to a new pose T_world_obj (4, 4)."""
        if name not in self._dynamic:
            raise KeyError(f"'{name}' is not a dynamic obstacle; dynamic: {self.dynamic_obstacles}")
        old = self._obstacles[name]
        self._obstacles[name] = Primitive(old.kind, np.asarray(T_world_obj, dtype=float), old.size)
        self._scene_packed = None   # packed_with's scene part
        self._pack_env()

    def remove_obstacle(self, name: str) -> None:
        """Remove a dynamic obstacle."""
        if name not in self._dynamic:
            raise KeyError(f"'{name}' is not a dynamic obstacle; dynamic: {self.dynamic_obstacles}")
        del self._obstacles[name]
        self._dynamic.discard(name)
        self._scene_packed = None   # packed_with's scene part
        self._pack_env()

    @property
    def dynamic_obstacles(self) -> list[str]:
        return sorted(self._dynamic)

    @property
    def nbytes(self) -> int:
        """Memory held by the distance grids (bytes)."""
        return self.packed.grid_bytes

    # --- checks -------------------------------------------------------------------------
    def run_kernel(self, kernel: Any, *args: Any) -> Any:
        """kernel(*args, self.packed), through the compiled version's entry point once it is
        known: numba's dispatch would type the packed world's ~50 arrays on every call (a few
        µs, as much as checking a configuration). Entry points are kept per kernel and per the
        types of ``args`` (arrays: dtype, dimensions, numba layout, writability; others: their
        Python type), and forgotten when the packed world's obstacle arrays change type
        (``_pack_env``)."""
        return self._run_in(self.packed, kernel, args)

    def _run_in(self, packed: PackedWorld, kernel: Any, args: tuple[Any, ...]) -> Any:
        """kernel(*args, packed) for a ``packed`` of :attr:`packed`'s numba type."""
        key = (kernel, *[(a.dtype, a.ndim, _numba_layout(a), a.flags.writeable)
                         if isinstance(a, np.ndarray) else type(a) for a in args])
        entry = self._entries.get(key)
        if entry is None:
            if any(isinstance(a, np.ndarray) and not a.flags.writeable for a in args):
                # a read-only array (a timed trajectory's positions) is another numba type:
                # the kernel's version for it would be loaded or compiled at its first call,
                # mid-query (53 ms for dense_path's walk), so it gets a writable copy
                return self._run_in(packed, kernel, tuple(
                    np.array(a) if isinstance(a, np.ndarray) and not a.flags.writeable else a
                    for a in args))
            full = (*args, packed)
            out = kernel(*full)
            compiled = kernel.overloads.get(tuple(typeof(a) for a in full))
            if compiled is not None:
                self._entries[key] = compiled.entry_point
            return out
        return entry(*args, packed)

    def _as_batch(self, Q: Array) -> Array:
        Q = np.ascontiguousarray(np.atleast_2d(np.asarray(Q, dtype=float)))
        if Q.ndim != 2 or Q.shape[1] != self.robot.dof:
            raise RobotError(f"expected configurations of shape (N, {self.robot.dof}), "
                             f"got {Q.shape}")
        return Q

    def valid(self, Q: Array) -> BoolArray:
        """Collision-free flag for each configuration; Q (N, K) → (N,)."""
        return self.run_kernel(validity.valid_batch, self._as_batch(Q))

    def valid_in(self, packed: PackedWorld, Q: Array) -> BoolArray:
        """:meth:`valid` in ``packed``: this checker's packed world as it was with other
        obstacles (an earlier :attr:`packed`), without changing this checker — for checks
        that alternate between a few obstacle sets (the executive's time windows)."""
        Q = self._as_batch(Q)
        if packed is not self.packed and _layout(packed) != self._layout:
            # another numba type: plain dispatch
            return validity.valid_batch(Q, packed)
        return self._run_in(packed, validity.valid_batch, (Q,))

    def is_valid(self, q: Array) -> bool:
        """Whether one configuration (K,) is collision-free."""
        return bool(self.valid(q)[0])

    def motions_valid(self, Q0: Array, Q1: Array, resolution: float = 0.02,
                      deadline: float = math.inf, *, clearance_m: float = 0.0) -> BoolArray:
        """Whether each straight motion Q0[i] → Q1[i] is free at every ``resolution`` (rad)
        step of joint-space distance, visited in bisection order; end points are not checked.
        With a ``deadline`` (a ``time.perf_counter()`` value, s) the compiled calls are
        budgeted (``validity.check_budget``) and the clock is looked at between them: a
        motion not decided by then counts as blocked. ``clearance_m`` > 0: free only where
        the checks in :meth:`clearance_world` pass (every link's geometry at least that far
        from everything)."""
        Q0, Q1 = self._as_batch(Q0), self._as_batch(Q1)
        return self._check_motions(Q0, Q1, resolution, deadline, False, clearance_m)[0]

    def clearance_world(self, clearance_m: float) -> PackedWorld:
        """:attr:`packed` with every sphere and group bound ``clearance_m`` (m) larger and
        every confirmation on the covered geometry asked to prove at least that gap
        (``dense_path.with_margin``, as the certification's screen widens it): a
        configuration it calls free keeps each link's collision geometry at least
        ``clearance_m`` from obstacles and fixed robot parts and 2 ``clearance_m`` from other
        links. Kept until the obstacles change."""
        kept = self._clear_worlds.get(clearance_m)
        if kept is not None and kept[0] == self.obstacles_version:
            return kept[1]
        margin = np.full(self.packed.groups.radius.shape[0], float(clearance_m))
        world = dense_path.with_margin(self.packed, margin, margin)
        self._clear_worlds[clearance_m] = (self.obstacles_version, world)
        return world

    def first_free_motion(self, Q0: Array, Q1: Array, resolution: float = 0.02,
                          deadline: float = math.inf, *, clearance_m: float = 0.0
                          ) -> int | None:
        """Index of the first motion Q0[i] → Q1[i] (candidates in order of preference) that
        :meth:`motions_valid` calls free, or None — also when ``deadline`` passes first (once
        passed, none is checked: a caller looping over candidate lists, as the shortcuts do,
        would otherwise make a budgeted call per list). The motions after it are not checked,
        and all go through one compiled call (each costs ~10 µs of argument passing, as much
        as checking several configurations). ``clearance_m``: as in :meth:`motions_valid`.

        A motion decided in an earlier call in the world as it is now is not checked again
        (:class:`~chekhov.collision.motion_memo.MotionMemo`; one cut by the deadline is not
        remembered): the shortcuts of a query's routes try the same jumps from the same
        waypoints. Not :meth:`motions_valid`, whose callers seldom ask twice — OMPL's motion
        validator asks one motion at a time, and the memo's ~15 µs a call made RRTConnect
        4-17% slower on 80 random cases of tabletop_pole and shelf_boxes."""
        if time.perf_counter() >= deadline:
            return None
        Q0, Q1 = self._as_batch(Q0), self._as_batch(Q1)
        memo = self._motion_memo
        keys, known = memo.lookup(Q0, Q1, float(resolution), float(clearance_m),
                                  self.obstacles_version)   # 1 free, 0 blocked, -1 not known
        # only the unknown motions before the first one known to be free need a check
        first = int(np.argmax(known == 1)) if (known == 1).any() else len(known)
        ask = np.flatnonzero(known[:first] < 0)
        if len(ask):
            part, done = self._check_motions(Q0[ask], Q1[ask], resolution, deadline, True,
                                             clearance_m)
            memo.store(float(resolution), float(clearance_m), [keys[i] for i in ask[:done]],
                       part[:done])
            if part.any():
                return int(ask[int(np.argmax(part))])
        return first if first < len(known) else None

    def _check_motions(self, Q0: Array, Q1: Array, resolution: float, deadline: float,
                       until_free: bool, clearance_m: float) -> tuple[BoolArray, int]:
        """(free flags, how many of the motions were decided — the rest, cut by the
        deadline, count as blocked): the compiled checks in budgeted calls (``until_free``:
        ending after the first free motion)."""
        world = self.packed if clearance_m <= 0.0 else self.clearance_world(clearance_m)
        out = np.zeros(len(Q0), dtype=bool)
        done = resume = calls = 0
        while done < len(Q0) and not (until_free and out.any()):
            left = deadline - time.perf_counter()
            if calls > 0 and left <= 0.0:
                break
            part, done, resume = self._run_in(world, validity.motions_valid, (
                Q0, Q1, float(resolution), done, resume, validity.check_budget(max(left, 0.0)),
                until_free))
            out |= part
            calls += 1
        return out, done

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
        i, _ = self.run_kernel(dense_path.first_dense_collision, P, int(substeps), int(start),
                               dense_path.NO_BUDGET, _NO_MARGIN, _NO_MARGIN)
        return None if i == NONE else int(i)

    def dense_path_valid(self, path: Array, substeps: int = 100) -> bool:
        """Whether every waypoint of path (T, K) and ``substeps`` interpolated configurations
        per segment are free (the paper's check, on this checker)."""
        return self.first_dense_collision(path, substeps) is None

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the validity, motion and path kernels and the
        optimiser's distance terms (``TrajectoryDistances``) now, so that no planner pays for
        compilation inside its time limit."""
        q0 = 0.5 * (self.robot.lower + self.robot.upper)
        q1 = q0 + 0.1
        self.valid(np.vstack([q0, q1]))
        self.motions_valid(q0[None], q1[None])
        self.motions_valid(q0[None], q1[None], clearance_m=1e-3)   # and with_margin
        self.first_dense_collision(np.vstack([q0, q1]), 2)
        TrajectoryDistances(self).warm_up()

    def min_distance(self, Q: Array) -> Array:
        """Smallest signed distance (m) between the spheres and anything, per configuration."""
        return kernels.min_distance_batch(self._as_batch(Q), self.packed)

    def contacts(self, q: Array, margin: float) -> Contacts:
        """Per-sphere contacts closer than ``margin`` (m) at one configuration (K,)."""
        q = self._as_batch(q)[0]
        return Contacts(*kernels.sphere_contacts(q, float(margin), self.packed))

    def sphere_centers(self, q: Array) -> Array:
        """World centres of every sphere at q, shape (M, 3)."""
        Rb, pb = self.joint_placements(q)
        out = np.empty((len(self.spheres), 3))
        sph = self.packed.spheres
        kernels.transform_points(Rb, pb, sph.joint, sph.centre, out)
        return out

    def joint_placements(self, q: Array) -> tuple[Array, Array]:
        """World rotation (K, 3, 3) and origin (K, 3) of each group joint at q (numba FK)."""
        q = self._as_batch(q)[0]
        Rb, pb = np.empty((self.robot.dof, 3, 3)), np.empty((self.robot.dof, 3))
        chain_fk(q, self.packed.chain, Rb, pb)
        return Rb, pb


def _layout(packed: PackedWorld) -> tuple[tuple[object, ...], ...]:
    """What numba's type of ``packed`` depends on in the arrays ``with_obstacles`` replaces:
    each one's dtype, dimensions, layout (as numba reads it: "C" when C-contiguous, else "F"
    when Fortran-contiguous, else "A"), writability and alignment. Not both contiguity flags:
    an array of one row (one obstacle) or none is both, of two rows only C-contiguous, the same
    numba type — telling them apart dropped the compiled entry points whenever the number of
    obstacles crossed 1 (38 times in one react episode, each costing ~1-3 ms of typing)."""
    return tuple((a.dtype, a.ndim, _numba_layout(a), a.flags.writeable, a.flags.aligned)
                 for prims in (packed.dynamic, packed.obstacles) for a in prims)


def _numba_layout(a: np.ndarray) -> str:
    """numba's layout letter of ``a`` (``numba.np.numpy_support.map_layout``)."""
    return "C" if a.flags.c_contiguous else "F" if a.flags.f_contiguous else "A"


def pinocchio_joint_placements(robot: Robot, q: Array) -> list[pin.SE3]:
    """Reference for tests: pinocchio's world placement of each group joint."""
    pin.forwardKinematics(robot.model, robot.data, np.asarray(q, dtype=float))
    return [robot.data.oMi[k].copy() for k in range(1, robot.model.njoints)]
