"""The task family (private; import from :mod:`chekhov.cases`).

This module holds issue 17's pick-and-place cases: their shares and limits (``READY_SHARE``,
``PLACE_SHARE``, ``TASK_TRIES``, ``GOAL_SOLUTIONS``, ``PLACE_CLEARANCE``, ``READY_STATES``),
what they are drawn from (:class:`PregraspTarget`, :class:`TaskTargets`, :func:`task_targets`,
:func:`ready_configuration`), :func:`sample_task_case` (one task case) and :func:`place_pose`
(a pre-grasp of an object set down in a region), with their helpers.
"""

from __future__ import annotations

import weakref
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chekhov._case_sampling import DrawnCase, case_rng
from chekhov.errors import ChekhovError
from chekhov.robot.goal import Goal
from chekhov.scene.model import Grasp, Region, Scene, SceneObject
from chekhov.world import World

Array = NDArray[np.float64]


# --- the task family ----------------------------------------------------------------------
READY_SHARE = 0.25        # share of task starts at the ready configuration (when there is one)
PLACE_SHARE = 0.2         # share of task goals that are place poses
TASK_TRIES = 200          # draws per case before giving up
GOAL_SOLUTIONS = 4        # IK solutions asked of the goal resolver per pose
PLACE_CLEARANCE = 0.005   # m, gap under and around a placed object
READY_STATES = ("ready", "home", "default")   # SRDF group_state names taken as "ready"


@dataclass(frozen=True, eq=False)
class PregraspTarget:
    """A pre-grasp pose and its collision-free IK solutions.

    Attributes:
        label: ``SceneObject.pregrasp_poses`` label ("cup/top", "door/handle@open").
        obj: the object's name. T: (4, 4) the pre-grasp pose in the world (m).
        Q: (m, K) rad, its IK solutions free by both checkers, within limits (m ≥ 1).
    """

    label: str
    obj: str
    T: Array
    Q: Array


@dataclass(frozen=True, eq=False)
class TaskTargets:
    """What task cases of a world are drawn from: the reachable pre-grasps (in scene order)
    and the ready configuration (None when the robot has none that is free here)."""

    pregrasps: tuple[PregraspTarget, ...]
    ready: Array | None


_TARGETS: weakref.WeakKeyDictionary[World, TaskTargets] = weakref.WeakKeyDictionary()


def task_targets(world: World) -> TaskTargets:
    """The world's :class:`TaskTargets`, computed once per world (the scene's obstacles; the
    dynamic obstacles added to a world later are not seen). Each pre-grasp pose goes to
    ``world.goal_ik.resolve`` (no deadline, so the result is the same on every machine), and
    its solutions are kept when the exact checker calls them free."""
    got = _TARGETS.get(world)
    if got is None:
        out = []
        for obj in world.scene.objects:
            for label, T in obj.pregrasp_poses():
                Q = _free_solutions(world, T)
                if len(Q):
                    out.append(PregraspTarget(label, obj.name, T, Q))
        got = TaskTargets(tuple(out), ready_configuration(world))
        _TARGETS[world] = got
    return got


def _free_solutions(world: World, T: Array, near: Array | None = None) -> Array:
    """IK solutions of pose T (4, 4) that are within limits and free by the exact checker (the
    resolver's are free by the fast one), nearest ``near`` first when given; (m, K)."""
    found = world.goal_ik.resolve(Goal.pose(T), n=GOAL_SOLUTIONS, near=near)
    Q = [q for q in found.Q if world.robot.within_limits(q)[0] and world.exact.is_valid(q)]
    return np.array(Q).reshape(len(Q), world.robot.dof)


def ready_configuration(world: World) -> Array | None:
    """The robot's ready configuration (K,) rad: the first SRDF ``group_state`` named one of
    :data:`READY_STATES` that sets every planned joint (the Panda's "default"; Baxter's SRDF
    has none), when it is within limits and free in this scene by both checkers; else None."""
    srdf = world.robot.description.srdf
    if not srdf:
        return None
    try:
        root = ET.parse(world.robot.description.resolve(srdf)).getroot()
    except (OSError, ET.ParseError):
        return None
    states = {s.get("name"): {j.get("name"): j.get("value") for j in s.iter("joint")}
              for s in root.iter("group_state")}
    for name in READY_STATES:
        values = states.get(name, {})
        try:
            q = np.array([float(values[j]) for j in world.robot.joint_names])  # type: ignore[arg-type]
        except (KeyError, TypeError, ValueError):
            continue
        if (world.robot.within_limits(q)[0] and world.fast.valid(q[None])[0]
                and world.exact.is_valid(q)):
            return q
    return None


def sample_task_case(world: World, seed: int, index: int, attempt: int = 0) -> DrawnCase:
    """Case ``index`` of the task family (replacement ``attempt``), from the stream
    ``case_rng(seed, index, attempt)``:

    * start: with probability :data:`READY_SHARE` the ready configuration (when there is one),
      else a pre-grasp drawn uniformly among the reachable ones and one of its free IK
      solutions drawn uniformly;
    * goal: with probability :data:`PLACE_SHARE` a place pose (:func:`place_pose`: the start's
      object — or, from the ready configuration, a drawn graspable one — set down in a region
      drawn by weight), else the pre-grasp pose of another object drawn uniformly; ``q_goal``
      is its free IK solution nearest the start.

    Draws that give no free goal solution are drawn again (up to :data:`TASK_TRIES`)."""
    targets = task_targets(world)
    objects = {t.obj for t in targets.pregrasps}
    if len(objects) < 2:
        raise ChekhovError(f"scene '{world.scene.name}': task cases need reachable pre-grasps "
                           f"of two objects at least, found {sorted(objects)}")
    rng = case_rng(seed, index, attempt)
    for _ in range(TASK_TRIES):
        if targets.ready is not None and rng.random() < READY_SHARE:
            q_start, start_label, start_obj = targets.ready, "ready", None
        else:
            t = targets.pregrasps[int(rng.integers(len(targets.pregrasps)))]
            q_start, start_label, start_obj = t.Q[int(rng.integers(len(t.Q)))], t.label, t.obj
        goal = (_draw_place(world, rng, start_obj) if rng.random() < PLACE_SHARE
                else _draw_pregrasp(targets, rng, start_obj))
        if goal is None:
            continue
        T_goal, goal_label = goal
        Q = _free_solutions(world, T_goal, near=q_start)
        if len(Q) == 0:
            continue
        return DrawnCase(q_start.copy(), Q[0], world.robot.compute_ee_pose(q_start),
                         T_goal, start_label, goal_label)
    raise ChekhovError(f"scene '{world.scene.name}': no task case {index} (seed {seed}, "
                       f"attempt {attempt}) in {TASK_TRIES} draws")


def _draw_pregrasp(targets: TaskTargets, rng: np.random.Generator, start_obj: str | None
                   ) -> tuple[Array, str]:
    others = [t for t in targets.pregrasps if t.obj != start_obj]
    t = others[int(rng.integers(len(others)))]
    return t.T, t.label


def _draw_place(world: World, rng: np.random.Generator, start_obj: str | None
                ) -> tuple[Array, str] | None:
    """A place pose (and its label) of the start's object, or of a drawn one from the ready
    configuration, in a region drawn by weight; None when that draw finds no free spot."""
    scene = world.scene
    regions = [r for r in scene.regions if r.weight > 0]
    movable = [o for o in scene.objects if o.grasps and o.articulation is None]
    if not regions or not movable:
        return None
    if start_obj is None:
        obj = movable[int(rng.integers(len(movable)))]
    else:
        obj = scene.object(start_obj)
        if obj.articulation is not None or not obj.grasps:
            return None
    w = np.array([r.weight for r in regions])
    region = regions[int(rng.choice(len(regions), p=w / w.sum()))]
    grasp = obj.grasps[int(rng.integers(len(obj.grasps)))]
    T = place_pose(scene, obj, grasp, region, rng.random(2))
    if T is None:
        return None
    return T, f"place:{region.name}/{obj.name}/{grasp.name}"


def place_pose(scene: Scene, obj: SceneObject, grasp: Grasp, region: Region, u: Array
               ) -> Array | None:
    """The pre-grasp pose (4, 4) of ``grasp`` with ``obj`` set down in ``region``, or None.

    The object keeps its orientation; its centre goes to the point ``u`` ∈ [0, 1)² of the
    region's horizontal extent (shrunk by the object's half footprint), standing on the highest
    top of the other objects under its footprint within the region's height (or floating on
    the region's floor), :data:`PLACE_CLEARANCE` above it. The spot is free when the object's
    axis-aligned box there, grown by the clearance, overlaps no other object's box and fits
    in the region. Grasps are relative to the object, so the place pre-grasp approaches the
    set-down object as the pick pre-grasp approaches it where it stands."""
    T_obj = obj.T_world_obj()
    ext = _world_half_extents(obj, T_obj)
    c, size = np.asarray(region.center, dtype=float), np.asarray(region.size, dtype=float)
    lo, hi = c - size / 2, c + size / 2
    room = size[:2] - 2 * (ext[:2] + PLACE_CLEARANCE)
    if np.any(room <= 0):
        return None
    xy = lo[:2] + ext[:2] + PLACE_CLEARANCE + np.asarray(u, dtype=float) * room
    boxes = [_aabb(o) for o in scene.objects if o.name != obj.name]
    floor = lo[2]
    for b_lo, b_hi in boxes:
        if (np.all(b_lo[:2] < xy + ext[:2]) and np.all(xy - ext[:2] < b_hi[:2])
                and lo[2] - PLACE_CLEARANCE <= b_hi[2] <= hi[2]):
            floor = max(floor, float(b_hi[2]))
    centre = np.array([xy[0], xy[1], floor + PLACE_CLEARANCE + ext[2]])
    if centre[2] + ext[2] > hi[2]:
        return None
    grown = ext + PLACE_CLEARANCE / 2
    for b_lo, b_hi in boxes:
        if np.all(b_lo < centre + grown) and np.all(centre - grown < b_hi):
            return None
    T = T_obj.copy()
    T[:3, 3] = centre
    return T @ grasp.T_obj_pregrasp


def _world_half_extents(obj: SceneObject, T_world_obj: Array) -> Array:
    """Half extents (3,) of the object's world axis-aligned bounding box (m)."""
    return np.abs(T_world_obj[:3, :3]) @ obj.shape.half_extents


def _aabb(obj: SceneObject) -> tuple[Array, Array]:
    T = obj.T_world_obj()
    ext = _world_half_extents(obj, T)
    return T[:3, 3] - ext, T[:3, 3] + ext
