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
