"""Things to pick in every built-in scene (issue 17): at least 12 pre-grasp poses with a
collision-free IK solution, spread over the scene's regions.

A pre-grasp counts when the goal resolver finds a configuration for it that the exact checker
calls free, within the joint limits, whose end effector meets the pose within the default goal
tolerances.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable

import numpy as np
import pytest

from chekhov.robot.goal import Goal
from chekhov.scene.model import Scene, SceneObject
from chekhov.transforms import rotation_angle
from chekhov.world import World

MIN_PREGRASPS = 12
IK_TIME_S = 0.5   # per pose: an unreachable one (the kitchen's handles) costs no more


def _around_pole(scene: Scene, obj: SceneObject) -> str:
    pole = np.asarray(scene.object("pole").pose.xyz[:2])
    return "around_pole" if np.linalg.norm(np.asarray(obj.pose.xyz[:2]) - pole) < 0.2 \
        else "table"


def _in_container(scene: Scene, obj: SceneObject) -> str:
    bottom = scene.object("container_bottom")
    lo = np.asarray(bottom.pose.xyz[:2]) - np.asarray(bottom.shape.size[:2]) / 2
    hi = lo + np.asarray(bottom.shape.size[:2])
    xy = np.asarray(obj.pose.xyz[:2])
    return "in_container" if np.all((lo < xy) & (xy < hi)) else "beside"


def _shelf_level(scene: Scene, obj: SceneObject) -> str:
    """level_k: the object stands on board_k (the highest board whose top is at or below the
    object's bottom)."""
    bottom = obj.pose.xyz[2] - obj.shape.half_extents[2]
    tops = {o.name: o.pose.xyz[2] + o.shape.size[2] / 2 for o in scene.objects
            if o.name.startswith("board_")}
    board = max((t, name) for name, t in tops.items() if t <= bottom + 1e-6)[1]
    return board.replace("board_", "level_")


def _prefix(scene: Scene, obj: SceneObject) -> str:
    return obj.name.split("_")[0]


# scene -> (region of a graspable object, regions that must hold a reachable pre-grasp: all
# of them (a set) or at least this many (an int))
REGIONS: dict[str, tuple[Callable[[Scene, SceneObject], str], set[str] | int]] = {
    "tabletop_pole": (_around_pole, {"around_pole", "table"}),
    "tabletop_container": (_in_container, {"in_container", "beside"}),
    "shelf_boxes": (_shelf_level, 4),
    "kitchen": (_prefix, 3),   # of counter, sink, fridge, cabinet (the handles: none)
    "panda_table_shelf": (lambda s, o: o.name.split("_")[0] if o.name != "can" else "open",
                          {"under", "on", "open"}),
    "panda_cage": (_prefix, {"inside", "beside"}),
}


def reachable_pregrasps(world: World) -> list[tuple[str, str]]:
    """(object name, pre-grasp label) of every pre-grasp with a checked IK solution."""
    out = []
    for obj in world.scene.objects:
        for label, T in obj.pregrasp_poses():
            goal = Goal.pose(T)
            for n in (1, 4):   # a second look when the exact checker rejects the first
                found = world.goal_ik.resolve(goal, n=n,
                                              deadline=time.perf_counter() + IK_TIME_S)
                ok = [q for q in found.Q if _meets(world, goal, q)]
                if ok or len(found) == 0:
                    break
            if ok:
                out.append((obj.name, label))
    return out


def _meets(world: World, goal: Goal, q: np.ndarray) -> bool:
    assert goal.T_world_ee is not None
    T = world.robot.compute_ee_pose(q)
    return (bool(world.robot.within_limits(q)[0]) and world.exact.is_valid(q)
            and float(np.linalg.norm(T[:3, 3] - goal.T_world_ee[:3, 3]))
            <= goal.position_tolerance
            and rotation_angle(T[:3, :3], goal.T_world_ee[:3, :3])
            <= goal.orientation_tolerance)


@pytest.mark.parametrize("name", sorted(REGIONS))
def test_scene_has_reachable_pregrasps_in_its_regions(world_of, name):
    world = world_of(name)
    region_of, wanted = REGIONS[name]
    reached = reachable_pregrasps(world)
    assert len(reached) >= MIN_PREGRASPS, (name, reached)
    per_region = Counter(region_of(world.scene, world.scene.object(o)) for o, _ in reached)
    if isinstance(wanted, set):
        assert wanted <= set(per_region), (name, dict(per_region))
    else:
        assert len(per_region) >= wanted, (name, dict(per_region))
    if name == "kitchen":
        assert set(per_region) <= {"counter", "sink", "fridge", "cabinet"}, dict(per_region)


def test_builtin_scenes_all_have_a_region_rule():
    from chekhov.scene.io import builtin_scenes

    assert sorted(REGIONS) == builtin_scenes()
