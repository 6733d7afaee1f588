import numpy as np
import pytest
import yaml

from chekhov import SceneError, builtin_scenes, load_scene, save_scene, scene_from_dict

MINIMAL = {"name": "t", "objects": [{"name": "b", "shape": "box", "size": [0.1, 0.2, 0.3],
                                     "pose": {"xyz": [1, 0, 0.5]}}]}


def test_builtin_scenes_four_for_baxter_two_for_the_panda():
    assert builtin_scenes() == ["kitchen", "panda_cage", "panda_table_shelf", "shelf_boxes",
                                "tabletop_container", "tabletop_pole"]
    assert {load_scene(n).robot for n in builtin_scenes()} == {"baxter_left", "panda"}
    for name in ("panda_cage", "panda_table_shelf"):
        scene = load_scene(name)
        assert dict(scene.locked_joints) == {"panda_finger_joint1": 0.04,
                                             "panda_finger_joint2": 0.04}
        assert sum(len(o.grasps) for o in scene.objects) >= 6


def test_kitchen_keeps_every_box_of_the_trajopt_file():
    k = load_scene("kitchen")
    furniture = [o for o in k.objects if not o.grasps or "handle" in o.name]
    assert len(furniture) == 50   # the things to pick (issue 17) come on top
    assert len(k.objects) > 50 and all(o.cls in ("object", "box") for o in k.objects[50:])
    sink = k.object("sink_bottom")  # extents 0.3 0.3 0.01 at 0.30 1.60 0.50 in the XML
    assert sink.shape.size == pytest.approx((0.6, 0.6, 0.02))
    assert sink.pose.xyz == pytest.approx((0.30, 1.60, 0.50))
    assert k.base_pose is not None


def test_shelf_has_seven_levels_with_boxes():
    s = load_scene("shelf_boxes")
    boards = [o for o in s.objects if o.name.startswith("board_")]
    assert len(boards) == 7
    for k in range(7):
        assert any(o.name.startswith(f"box_{k}_") for o in s.objects)
    assert len(s.regions) == 7


@pytest.mark.parametrize("name", ["kitchen", "shelf_boxes", "tabletop_container",
                                  "tabletop_pole"])
def test_saved_scene_loads_back_identical(tmp_path, name):
    s = load_scene(name)
    path = tmp_path / f"{name}.yaml"
    save_scene(s, path)
    back = load_scene(path)
    assert back == s
    assert back.content_hash() == s.content_hash()


def test_generated_grasps_and_articulation_states():
    pole = load_scene("tabletop_pole")
    box = pole.object("box_left")
    poses = dict(box.pregrasp_poses())
    top = poses["box_left/top"]
    assert top[:3, 2] == pytest.approx([0, 0, -1])  # approach straight down
    assert top[2, 3] > box.pose.xyz[2] + box.shape.size[2] / 2  # above the box
    kitchen = load_scene("kitchen")
    door = kitchen.object("dishwasher_door")
    closed = door.T_world_obj("closed")
    assert closed[:3, 3] == pytest.approx([0.60, 2.16, 0.46], abs=1e-6)
    labels = [lab for lab, _ in kitchen.object("dishwasher_handle").pregrasp_poses()]
    assert any("@open" in lab for lab in labels) and any("@closed" in lab for lab in labels)


@pytest.mark.parametrize("mutate, match", [
    (lambda d: d["objects"][0].update(size=[0.1, -1, 0.3]), r"object 'b': field 'size'"),
    (lambda d: d["objects"][0].update(shape="cone"), r"object 'b': field 'shape'"),
    (lambda d: d["objects"][0].update(pose={"xyz": [1, 2]}), r"object 'b': field 'pose.xyz'"),
    (lambda d: d["objects"][0].update(colour="red"), r"object 'b': field 'colour'"),
    (lambda d: d["objects"][0].update(motion="flying"), r"object 'b': field 'motion'"),
    (lambda d: d["objects"][0].update(pose={"xyz": [0, 0, 0], "quat": [0, 0, 0, 2]}),
     r"field 'pose.quat'"),
    (lambda d: d["objects"].append(dict(d["objects"][0])), r"duplicate object names"),
    (lambda d: d["objects"][0].update(articulation={"type": "hinge", "axis": [0, 0, 1],
                                                    "states": {"open": 1}, "state": "shut"}),
     r"field 'articulation.state'"),
])
def test_validation_names_file_object_and_field(tmp_path, mutate, match):
    import copy

    d = copy.deepcopy(MINIMAL)
    mutate(d)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(d))
    with pytest.raises(SceneError, match=match) as e:
        load_scene(path)
    assert "bad.yaml" in str(e.value)


def test_unknown_scene_and_bad_yaml(tmp_path):
    with pytest.raises(SceneError, match="no built-in scene"):
        load_scene("moon_base")
    p = tmp_path / "x.yaml"
    p.write_text("objects: [")
    with pytest.raises(SceneError, match="not valid YAML"):
        load_scene(p)


def test_minimal_scene_defaults():
    s = scene_from_dict(MINIMAL)
    assert s.objects[0].cls == "object" and not s.objects[0].dynamic
    assert np.allclose(s.objects[0].T_world_obj()[:3, 3], [1, 0, 0.5])
