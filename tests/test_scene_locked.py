"""Scenes may be empty (a roadmap built in the empty workspace) and set the robot's locked
joints (fingers, the other arm); both round-trip through YAML and reach the World's robot."""

import numpy as np
import pytest

from chekhov import SceneError, World
from chekhov.scene.io import load_scene, save_scene, scene_from_dict

FINGERS = {"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04}


def test_an_empty_scene_is_written_loaded_and_planned_in(tmp_path):
    scene = scene_from_dict({"format": 1, "name": "empty", "robot": "panda"})
    assert scene.objects == ()
    path = save_scene(scene, tmp_path / "empty.yaml") or tmp_path / "empty.yaml"
    assert load_scene(path) == scene
    world = World(scene)
    Q = world.robot.sample_uniform(np.random.default_rng(0), 200)
    exact = world.exact.valid(Q)
    assert not np.any(world.fast.valid(Q) & ~exact)   # conservative with no obstacles too


def test_locked_joints_reach_the_robot_and_the_content_hash(tmp_path):
    scene = scene_from_dict({"format": 1, "name": "t", "robot": "panda",
                             "locked_joints": FINGERS})
    assert dict(scene.locked_joints) == FINGERS
    save_scene(scene, tmp_path / "t.yaml")
    back = load_scene(tmp_path / "t.yaml")
    assert back == scene and back.content_hash() == scene.content_hash()
    assert dict(World(back).robot.description.fixed_joints) == FINGERS
    other = scene_from_dict({"format": 1, "name": "t", "robot": "panda",
                             "locked_joints": {**FINGERS, "panda_finger_joint1": 0.01}})
    assert other.content_hash() != scene.content_hash()
    assert World(other).robot.content_hash() != World(back).robot.content_hash()


@pytest.mark.parametrize("value, match", [
    ({"panda_finger_joint1": True}, "locked_joints.panda_finger_joint1"),
    ({"panda_finger_joint1": float("nan")}, "locked_joints.panda_finger_joint1"),
    ({"../x": 0.0}, "locked_joints"),
    ([0.04], "locked_joints"),
])
def test_bad_locked_joints_are_located_errors(value, match):
    with pytest.raises(SceneError, match=match):
        scene_from_dict({"format": 1, "name": "t", "robot": "panda", "locked_joints": value})


def test_a_cached_roadmap_is_rebuilt_when_a_locked_joint_changes(tmp_path):
    """The roadmap cache is keyed on the robot's content, not its name: a roadmap built with
    the fingers at 0.04 m is not reused with them at 0.01 m (same scene, same robot name)."""
    from chekhov import Robot
    from chekhov.roadmap.config import RoadmapConfig
    from chekhov.roadmap.io import load_or_build_roadmap

    scene = scene_from_dict({"format": 1, "name": "empty", "robot": "panda"})
    config = RoadmapConfig(n_nodes=40, semantic=False, n_wrist_nodes=0, k_paths=1)
    path = tmp_path / "empty.npz"
    said: list[str] = []
    first = World(scene, Robot.load("panda", locked=FINGERS))
    built = load_or_build_roadmap(first, config, path, said.append)
    assert built.meta.robot_hash == first.robot.content_hash()
    assert load_or_build_roadmap(first, config, path, said.append).meta.created == \
        built.meta.created                                      # same robot: reused
    assert not any("rebuilding" in s for s in said)
    other = World(scene, Robot.load("panda", locked={**FINGERS, "panda_finger_joint1": 0.01}))
    rebuilt = load_or_build_roadmap(other, config, path, said.append)
    assert any("rebuilding" in s and "content hash" in s for s in said), said
    assert rebuilt.meta.robot_hash == other.robot.content_hash() != built.meta.robot_hash
