"""Any arm from its URDF: Robot.from_urdf agrees with the built-in description, resolves meshes
through package_dirs, keys caches on its content (locked joints included), refuses groups that
are not chains of 1-DOF joints, plans continuous joints as bounded revolute ones, leaves
adjacent links out of self-collision, loads joints and links that share a name; the numbered
example plans; arms written elsewhere (a UR5, an SO-100, a Z1) plan: TrajOpt past overlapping
wrist spheres, ends the fast checker rejects but coal accepts."""

import itertools
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest
import yaml

from chekhov import (
    Goal,
    OmplPlanner,
    PlanStatus,
    RoadmapConfig,
    RoadmapTrajOpt,
    Robot,
    RobotError,
    SceneError,
    TrajOptPlanner,
    World,
    build_roadmap,
    load_scene,
)
from chekhov.cli import main
from chekhov.collision.exits import EXIT_RADII_RAD, exact_exit
from chekhov.robot.description import example_robot_data_dir

SHARE = example_robot_data_dir()
PANDA = SHARE / "robots/panda_description"
JOINTS = [f"panda_joint{i}" for i in range(1, 8)]


def _panda(**kw):
    kw.setdefault("package_dirs", [SHARE.parent])
    kw.setdefault("joints", JOINTS)
    return Robot.from_urdf(PANDA / "urdf/panda.urdf", ee_frame="panda_hand_tcp",
                           srdf=PANDA / "srdf/panda.srdf", **kw)


def test_from_urdf_matches_the_builtin_description():
    builtin = Robot.load("panda")
    robot = _panda(locked=dict(builtin.description.fixed_joints))
    assert robot.dof == 7 and robot.joint_names == tuple(JOINTS)
    assert np.allclose(robot.lower, builtin.lower) and np.allclose(robot.upper, builtin.upper)
    Q = robot.sample_uniform(np.random.default_rng(0), 20)
    assert np.allclose(robot.compute_ee_poses(Q), builtin.compute_ee_poses(Q), atol=1e-12)
    assert robot.self_collision_pairs == builtin.self_collision_pairs


def test_locked_joints_change_the_geometry_and_the_content_hash():
    a = Robot.load("panda", locked={"panda_finger_joint1": 0.01, "panda_finger_joint2": 0.01})
    b = Robot.load("panda", locked={"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04})
    assert a.content_hash() != b.content_hash()
    assert a.content_hash() == Robot.load("panda", locked={"panda_finger_joint1": 0.01,
                                                           "panda_finger_joint2": 0.01}
                                          ).content_hash()
    fingers = [i for i in range(a.collision_model.ngeoms)
               if "finger" in a.collision_model.geometryObjects[i].name]
    assert fingers
    q = np.zeros(7)
    da, db = a.collision_model.createData(), b.collision_model.createData()
    pin.updateGeometryPlacements(a.model, a.data, a.collision_model, da, q)
    pin.updateGeometryPlacements(b.model, b.data, b.collision_model, db, q)
    gap = [np.linalg.norm(da.oMg[i].translation - db.oMg[i].translation) for i in fingers]
    assert max(gap) > 0.02   # the fingers moved by about 3 cm


def test_locking_a_planned_joint_or_a_bad_value_is_an_error():
    with pytest.raises(RobotError, match="planned joints"):
        Robot.load("panda", locked={"panda_joint1": 0.0})
    with pytest.raises(RobotError, match="finite number"):
        Robot.load("panda", locked={"panda_finger_joint1": float("nan")})
    with pytest.raises(RobotError, match="not in"):
        Robot.load("panda", locked={"no_such_joint": 0.0})


def test_a_group_that_is_not_a_joint_chain_is_refused():
    with pytest.raises(RobotError, match="not in"):
        _panda(joints=["panda_joint1", "nope"])
    with pytest.raises(RobotError, match="kinematic order"):
        _panda(joints=list(reversed(JOINTS)))
    with pytest.raises(RobotError, match="end-effector frame"):
        Robot.from_urdf(PANDA / "urdf/panda.urdf", joints=JOINTS, ee_frame="nope",
                        package_dirs=[SHARE.parent])


def test_meshes_resolve_through_package_dirs(tmp_path):
    """A copy of the Panda outside example-robot-data, its mesh URIs renamed to a package of
    its own: it loads only when that package's folder is given."""
    pkg = tmp_path / "pkgs" / "my_panda"
    shutil.copytree(PANDA / "meshes", pkg / "meshes")
    text = (PANDA / "urdf/panda.urdf").read_text()
    text = re.sub(r"package://example-robot-data/robots/panda_description/", "package://my_panda/",
                  text)
    (pkg / "panda.urdf").write_text(text)
    robot = Robot.from_urdf(pkg / "panda.urdf", joints=JOINTS, ee_frame="panda_hand_tcp",
                            package_dirs=[tmp_path / "pkgs"])
    assert robot.collision_model.ngeoms > 0 and robot.name == "panda"
    with pytest.raises(RobotError):
        Robot.from_urdf(pkg / "panda.urdf", joints=JOINTS, ee_frame="panda_hand_tcp")


def test_visual_meshes_load_only_when_asked():
    robot = _panda()
    assert "visual_model" not in robot.__dict__
    assert robot.visual_model.ngeoms > 0


def test_the_custom_urdf_example_plans():
    example = Path(__file__).parents[1] / "examples" / "01_custom_urdf.py"
    out = subprocess.run([sys.executable, str(example)], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("solved certified"), out.stdout


KINOVA = SHARE / "robots/kinova_description"
KINOVA_JOINTS = [f"j2s6s200_joint_{i}" for i in range(1, 7)]


def _kinova():
    """A Kinova Jaco 2 (6 DOF; joints 1, 4 and 6 continuous, its SRDF disables no pair)."""
    return Robot.from_urdf(KINOVA / "robots/kinova.urdf", srdf=KINOVA / "srdf/kinova.srdf",
                           joints=KINOVA_JOINTS, ee_frame="j2s6s200_end_effector",
                           package_dirs=[SHARE.parent])


def test_continuous_joints_are_planned_as_bounded_revolute_ones():
    """The Jaco's continuous joints (pinocchio: two coordinates, cos and sin) become revolute
    ones over the range their <limit> gives (±2π), and the kinematics are the URDF's: the
    end-effector pose equals pinocchio's on the unchanged file, with (cos θ, sin θ)."""
    robot = _kinova()
    assert robot.dof == 6
    assert np.allclose(robot.lower[[0, 3, 5]], -2 * np.pi)
    assert np.allclose(robot.upper[[0, 3, 5]], 2 * np.pi)
    assert np.all(np.isfinite(robot.velocity_limit)) and np.all(robot.velocity_limit > 0)
    raw = pin.buildModelFromUrdf(str(KINOVA / "robots/kinova.urdf"))
    data, ee = raw.createData(), raw.getFrameId("j2s6s200_end_effector")
    for q in robot.sample_uniform(np.random.default_rng(1), 10):
        q_raw = pin.neutral(raw)
        for k, name in enumerate(KINOVA_JOINTS):
            j = raw.joints[raw.getJointId(name)]
            q_raw[j.idx_q:j.idx_q + j.nq] = [np.cos(q[k]), np.sin(q[k])] if j.nq == 2 else q[k]
        pin.framesForwardKinematics(raw, data, q_raw)
        assert np.allclose(robot.compute_ee_pose(q), data.oMf[ee].homogeneous, atol=1e-10)


def test_a_continuous_joint_without_limits_gets_a_turn_either_way(tmp_path):
    urdf = tmp_path / "two.urdf"
    urdf.write_text(
        '<robot name="two"><link name="base"/><link name="a"><collision><geometry><box '
        'size="0.1 0.1 0.1"/></geometry></collision></link><link name="b"/>'
        '<joint name="j1" type="continuous"><parent link="base"/><child link="a"/>'
        '<axis xyz="0 0 1"/></joint><joint name="j2" type="continuous"><parent link="a"/>'
        '<child link="b"/><axis xyz="0 1 0"/><limit effort="3" velocity="2"/></joint></robot>')
    robot = Robot.from_urdf(urdf, joints=["j1", "j2"], ee_frame="b")
    assert np.allclose(robot.lower, -np.pi) and np.allclose(robot.upper, np.pi)
    assert robot.velocity_limit[0] == np.inf and robot.velocity_limit[1] == 2.0


def test_adjacent_links_are_not_checked_for_self_collision():
    """Without SRDF entries a Jaco's neighbouring links, whose meshes meet at their joint,
    collided in every configuration; they are now left out (as MoveIt's "Adjacent"), the
    other pairs stay, and most random configurations are free."""
    robot = _kinova()
    pairs = {frozenset((robot.geometry_link(i), robot.geometry_link(j)))
             for i, j in robot.self_collision_pairs}
    links = ["j2s6s200_link_base"] + [f"j2s6s200_link_{i}" for i in range(1, 7)]
    assert not any(frozenset(p) in pairs for p in itertools.pairwise(links))
    assert frozenset(("j2s6s200_link_base", "j2s6s200_link_5")) in pairs
    assert frozenset(("j2s6s200_link_2", "j2s6s200_link_6")) in pairs
    world = World(load_scene("tabletop_pole"), robot)
    free = [world.exact.is_valid(q) for q in robot.sample_uniform(np.random.default_rng(2), 100)]
    assert sum(free) >= 50


def test_links_whose_meshes_always_overlap_are_not_checked_and_the_rest_are(caplog):
    """TIAGo (no SRDF): its first arm link lies inside the torso column's mesh, and its wrist
    sensor inside the sixth arm link's, in every configuration, so every configuration
    collided and no roadmap could be built. Those two pairs are left out (MoveIt's
    "Always"), with a warning naming them; a pair that collides only sometimes (the forearm
    against the base) stays checked, and about half of the random configurations beside the
    table are free by coal."""
    T = np.eye(4)
    T[:3, 3] = (0.1, 0.25, 0.0)
    with caplog.at_level("WARNING", logger="chekhov.robot.robot"):
        robot = Robot.from_urdf(SHARE / "robots/tiago_description/robots/tiago.urdf",
                                joints=[f"arm_{i}_joint" for i in range(1, 8)],
                                ee_frame="arm_tool_link", package_dirs=[SHARE.parent],
                                T_world_base=T)
        always = {frozenset((robot.geometry_link(i), robot.geometry_link(j)))
                  for i, j in robot.always_colliding_pairs}
    assert always == {frozenset(("arm_1_link", "torso_fixed_column_link")),
                      frozenset(("arm_6_link", "wrist_ft_link"))}
    assert "arm_6_link" in caplog.text and "wrist_ft_link" in caplog.text
    checked = {frozenset((robot.geometry_link(i), robot.geometry_link(j)))
               for i, j in robot.self_collision_pairs}
    assert not always & checked
    assert frozenset(("arm_4_link", "base_link")) in checked
    # they still overlap at other configurations (coal on the two shapes, another seed):
    # only the checks leave them out
    model, geoms = robot.model, robot.collision_model
    data, gdata = model.createData(), pin.GeometryData(geoms)
    Q = robot.sample_uniform(np.random.default_rng(11), 200)
    for q in Q[:20]:
        pin.updateGeometryPlacements(model, data, geoms, gdata, q)
        for i, j in robot.always_colliding_pairs:
            out = coal.CollisionResult()
            coal.collide(geoms.geometryObjects[i].geometry, gdata.oMg[i],
                         geoms.geometryObjects[j].geometry, gdata.oMg[j],
                         coal.CollisionRequest(), out)
            assert out.isCollision()
    exact = World(load_scene("tabletop_pole"), robot).exact
    free = exact.valid(Q)
    assert 60 <= free.sum() <= 160
    assert any(frozenset(("arm_4_link_0", "base_link_0")) in n
               for n in (set(map(frozenset, exact.colliding_pairs(q))) for q in Q[~free]))


def test_a_scene_file_names_a_robot_file(tmp_path):
    """``robot:`` a description file, relative to the scene file; its URDF relative to its own
    folder (copied there), its SRDF from example-robot-data; the scene's base pose applies,
    and the command line plans in it like in a built-in scene."""
    arm = tmp_path / "arm"
    arm.mkdir()
    shutil.copy(PANDA / "urdf/panda.urdf", arm / "panda.urdf")
    (arm / "my_panda.yaml").write_text(yaml.safe_dump({
        "name": "my_panda", "urdf": "panda.urdf",
        "srdf": "robots/panda_description/srdf/panda.srdf", "group_joints": JOINTS,
        "ee_frame": "panda_hand_tcp", "proximal_joints": 7}))
    scene = {"format": 1, "name": "my_bench", "robot": "arm/my_panda.yaml",
             "base_pose": {"xyz": [0.1, 0.2, 0.3]},
             "objects": [{"name": "b", "shape": "box", "size": [0.1, 0.1, 0.1],
                          "pose": {"xyz": [0.6, 0.0, 0.4]}}]}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(scene))
    world = World.load(tmp_path / "s.yaml")
    assert world.robot.name == "my_panda" and world.robot.dof == 7
    assert world.robot.description.urdf == str(arm / "panda.urdf")
    assert world.robot.self_collision_pairs == Robot.load("panda").self_collision_pairs
    assert np.allclose(world.robot.T_world_base[:3, 3], [0.1, 0.2, 0.3])
    assert main(["show", str(tmp_path / "s.yaml"), "--out", str(tmp_path / "s.png")]) == 0
    assert (tmp_path / "s.png").stat().st_size > 0
    for bad, match in (("arm/nope.yaml", "no robot description file"), (3, "got 3")):
        (tmp_path / "bad.yaml").write_text(yaml.safe_dump({**scene, "robot": bad}))
        with pytest.raises(SceneError, match=f"bad.yaml: field 'robot': .*{match}"):
            load_scene(tmp_path / "bad.yaml")


def test_show_draws_a_configuration_within_the_limits():
    """Without --q, ``chekhov show`` drew the zero configuration, outside the Jaco's joint
    limits (its joints 2 and 3 do not reach zero); now the SRDF's ready state, else zero moved
    into the limits."""
    from chekhov.cli.scene_commands import _default_q
    robot = _kinova()
    world = World(load_scene("tabletop_pole"), robot)
    assert not robot.within_limits(np.zeros(robot.dof)[None])[0]
    assert robot.within_limits(_default_q(world)[None])[0]
    panda = World.load("panda_table_shelf")
    assert np.allclose(_default_q(panda), [0, -0.785, 0, -2.356, 0, 1.571, 0.785], atol=1e-3)


UR5 = SHARE / "robots/ur_description"
UR5_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
              "wrist_2_joint", "wrist_3_joint"]


@pytest.fixture(scope="module")
def ur5_world():
    """A UR5 (written by nobody here) beside the pole's table, level with its top."""
    T = np.eye(4)
    T[:3, 3] = 0.35, 0.25, 0.75
    robot = Robot.from_urdf(UR5 / "urdf/ur5_joint_limited_robot.urdf", joints=UR5_JOINTS,
                            ee_frame="tool0", srdf=UR5 / "srdf/ur5.srdf",
                            package_dirs=[SHARE.parent], T_world_base=T)
    return World(load_scene("tabletop_pole"), robot)


def test_a_ur5s_overlapping_wrist_spheres_do_not_hold_trajopt_back(ur5_world):
    """The UR5's wrist 2 and tool-link spheres overlap by 14 mm in every configuration, the
    links never touch. That pair's TrajOpt term made every straight-line run "infeasible"
    (or at best "exact_clear") until the pair's tabled gap bound took its place; now most
    runs converge, and each success is certified (checked again here at 200 substeps)."""
    world, robot = ur5_world, ur5_world.robot
    Q = robot.sample_uniform(np.random.default_rng(5), 200)
    Q = Q[world.exact.valid(Q)][:40]
    planner = TrajOptPlanner(world)
    statuses = []
    for q0, q1 in zip(Q[0::2], Q[1::2], strict=True):
        r = planner.plan(q0, Goal.configuration(q1), 2.0)
        statuses.append(r.info.get("trajopt_status"))
        if r.success:
            assert world.exact.path_valid(r.path, substeps=200)
            assert np.allclose(r.path[-1], q1, atol=1e-6)
    assert statuses.count("converged") >= 6, statuses


def test_ends_the_fast_checker_rejects_but_coal_accepts_are_planned(ur5_world):
    """The UR5's hulls touch where its meshes do not (the forearm and the tool link within
    millimetres of each other; before the hulls were cut into pieces, ``hull_split.py``, also
    the upper arm's tube beside the tabletop): 14 of these 2000 configurations are exactly
    free and rejected by the fast checker (27 before). Roadmap + TrajOpt answered
    "invalid_goal" for such a goal (and could not start from such a start); now the route
    leaves through an exit (``collision.exits.exact_exit``: fast-free, within the limits,
    its straight motion exactly free — checked here by coal at 400 substeps) and the answer
    ends exactly at the goal, exactly free at 300 substeps. (Where no exit is found the
    seeder says "no_connection", and the planner's repair and straight-line fallback run.)
    OMPL's RRTConnect, whose validity test is the fast checker, plans between the exits too."""
    world, robot = ur5_world, ur5_world.robot
    Q = robot.sample_uniform(np.random.default_rng(5), 2000)
    fast_ok, exact_ok = world.fast.valid(Q), world.exact.valid(Q)
    exits = [(q, exact_exit(world.fast, world.exact, q, robot.lower, robot.upper))
             for q in Q[~fast_ok & exact_ok]]
    alarmed = [q for q, out in exits if out is not None]
    # measured: 6 of the 14 such configurations (19 of 27 before the pieces, when the others
    # had a link within 0.1-9 mm of another, where the hulls stay in contact)
    assert len(alarmed) >= 5, len(alarmed)
    for q, out in exits:
        if out is not None:
            assert world.fast.is_valid(out) and robot.within_limits(out[None])[0]
            assert np.linalg.norm(out - q) <= EXIT_RADII_RAD[-1] + 1e-9
            assert world.exact.path_valid(np.vstack([q, out]), substeps=400)
    free = Q[fast_ok & exact_ok][0]
    assert np.array_equal(exact_exit(world.fast, world.exact, free, robot.lower, robot.upper),
                          free)
    planner = RoadmapTrajOpt(world, build_roadmap(world, RoadmapConfig(n_nodes=200,
                                                                       n_region_nodes=0)))
    rrt = OmplPlanner(world, "RRTConnect", simplify=True)   # its validity: the fast checker
    rrt_solved = 0
    for q0, q1 in [(free, alarmed[0]), (free, alarmed[1]), (alarmed[2], free),
                   (alarmed[3], alarmed[0])]:
        r = planner.plan(q0, Goal.configuration(q1), 2.0)
        assert r.success, (r.status, [(s.stage, s.status) for s in r.stages])
        assert np.array_equal(r.path[0], q0) and np.array_equal(r.path[-1], q1)
        assert world.exact.path_valid(r.path, substeps=300)
        # OMPL's sampler is its own (unseeded) and its motions are checked at 0.02 rad
        # steps, so a rare answer fails the certification ("collision"): no refusal, though
        r = rrt.plan(q0, Goal.configuration(q1), 2.0)
        assert r.status in (PlanStatus.SOLVED, PlanStatus.COLLISION), r.status
        if r.success:
            rrt_solved += 1
            assert np.array_equal(r.path[0], q0) and np.array_equal(r.path[-1], q1)
            assert world.exact.path_valid(r.path, substeps=300)
    assert rrt_solved >= 2
    # the repair tree (used when obstacles cut the roadmap) leaves through the exits too
    r = planner.seeder.repair(alarmed[0], np.array([alarmed[1]]), time.perf_counter() + 1.0)
    assert r.path is not None, r.status
    assert np.array_equal(r.path[0], alarmed[0]) and np.array_equal(r.path[-1], alarmed[1])
    assert world.exact.path_valid(r.path, substeps=300)


def test_a_joint_and_a_link_of_one_name_load_and_the_link_is_the_frame():
    """Two arms nobody here wrote: the SO-100's joint "gripper" moves its link "gripper"
    (pinocchio refused to lock that joint: "several frames match"), and Unitree's Z1 has a
    fixed joint and a link both named "gripperStator" (the end-effector frame lookup
    refused). Both load; the end-effector pose is the link's, as pinocchio's own full model
    places its BODY frame; a straight-line plan of the Z1 is certified."""
    arms = [
        (SHARE / "robots/so_arm_description/urdf/so100.urdf", None,
         ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"],
         "gripper"),
        (SHARE / "robots/z1_description/urdf/z1.urdf",
         SHARE / "robots/z1_description/srdf/z1.srdf", [f"joint{i}" for i in range(1, 7)],
         "gripperStator"),
    ]
    for urdf, srdf, joints, ee in arms:
        robot = Robot.from_urdf(urdf, joints=joints, ee_frame=ee, srdf=srdf,
                                package_dirs=[SHARE.parent])
        full = pin.buildModelFromUrdf(str(urdf))
        data = full.createData()
        body = next(i for i, f in enumerate(full.frames)
                    if f.name == ee and f.type == pin.FrameType.BODY)
        for q in robot.sample_uniform(np.random.default_rng(3), 5):
            q_full = pin.neutral(full)
            for name, v in zip(joints, q, strict=True):
                q_full[full.joints[full.getJointId(name)].idx_q] = v
            pin.framesForwardKinematics(full, data, q_full)
            np.testing.assert_allclose(robot.compute_ee_pose(q),
                                       robot.T_world_base @ data.oMf[body].homogeneous,
                                       atol=1e-9)
    world = World(load_scene("tabletop_pole"), robot)   # the Z1, at the scene's base pose
    Q = robot.sample_uniform(np.random.default_rng(4), 60)
    Q = Q[world.fast.valid(Q)]
    r = TrajOptPlanner(world).plan(Q[0], Goal.configuration(Q[1]), 2.0)
    assert r.success and world.exact.path_valid(r.path, substeps=200)
