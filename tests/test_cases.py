"""Test cases of the evaluation: generation, files, solvability pass, CLI."""

import json

import numpy as np
import pytest

from chekhov.bench import CaseSet, cached_cases, generate_cases, solvability_pass
from chekhov.cases import sample_case
from chekhov.cli import main
from chekhov.errors import ChekhovError
from chekhov.planners.base import PlanResult


@pytest.fixture(scope="module")
def world(world_of):
    return world_of("tabletop_pole")


@pytest.fixture(scope="module")
def cases(world):
    return generate_cases(world, 6, seed=7)


def test_cases_are_free_within_limits_and_record_poses(world, cases):
    assert len(cases) == 6 and cases.scene == "tabletop_pole" and cases.seed == 7
    assert cases.scene_hash == world.scene.content_hash() and cases.replaced == 0
    for Q, T in ((cases.q_start, cases.T_world_ee_start), (cases.q_goal, cases.T_world_ee_goal)):
        assert world.robot.within_limits(Q).all()
        assert world.fast.valid(Q).all() and world.exact.valid(Q).all()
        np.testing.assert_allclose(T, world.robot.compute_ee_poses(Q), atol=1e-12)
    goal = cases.goal(2)
    assert goal.is_pose and np.array_equal(goal.T_world_ee, cases.T_world_ee_goal[2])


def test_deterministic_for_a_seed_and_independent_of_n(world, cases):
    assert generate_cases(world, 6, seed=7).same_as(cases)
    assert generate_cases(world, 3, seed=7).same_as(cases.head(3))
    other = generate_cases(world, 3, seed=8)
    assert not np.allclose(other.q_start, cases.q_start[:3])


def test_save_load_identical(world, cases, tmp_path):
    path = cases.save(tmp_path / "sub" / "c.npz")
    back = CaseSet.load(path, world)
    assert back.same_as(cases)
    assert back.joint_names == world.robot.joint_names
    assert [p.name for p in (tmp_path / "sub").iterdir()] == ["c.npz"]  # no temporaries left


def test_load_against_another_scene_says_which(world_of, cases, tmp_path):
    path = cases.save(tmp_path / "c.npz")
    with pytest.raises(ChekhovError) as e:
        CaseSet.load(path, world_of("kitchen"))
    msg = str(e.value)
    assert str(path) in msg and "tabletop_pole" in msg and "kitchen" in msg
    assert cases.scene_hash[:12] in msg


def test_load_rejects_other_versions_and_files(cases, tmp_path):
    path = cases.save(tmp_path / "c.npz")
    with np.load(path) as z:
        data = {k: z[k] for k in z.files}
    meta = json.loads(str(data["meta"]))
    meta["version"] = 99
    data["meta"] = np.array(json.dumps(meta))
    np.savez(tmp_path / "v99.npz", **data)
    with pytest.raises(ChekhovError, match=r"v99\.npz: case file format version 99"):
        CaseSet.load(tmp_path / "v99.npz")
    (tmp_path / "junk.npz").write_text("not a zip")
    with pytest.raises(ChekhovError, match=r"junk\.npz: not a chekhov case file"):
        CaseSet.load(tmp_path / "junk.npz")
    with pytest.raises(ChekhovError, match="no such case file"):
        CaseSet.load(tmp_path / "missing.npz")


class _FailsOn:
    """A stub planner that fails on given start configurations and solves everything else."""

    name = "stub"

    def __init__(self, starts):
        self.starts = [np.asarray(q) for q in starts]

    def plan(self, q_start, goal, time_limit_s=1.0):
        ok = not any(np.array_equal(q_start, q) for q in self.starts)
        return PlanResult(ok, np.vstack([q_start, q_start]) if ok else None,
                          "solved" if ok else "timeout", 0.0)


def test_solvability_pass_replaces_unsolved_cases_deterministically(world, cases):
    rep = solvability_pass(world, cases, [_FailsOn([cases.q_start[1]])], time_limit_s=0.1)
    assert rep.replaced == 1 and rep.replaced_indices == (1,) and rep.unsolved_indices == ()
    assert rep.cases.replaced == 1 and rep.planners == ("stub",)
    q0, q1 = sample_case(world, cases.seed, 1, attempt=1)
    assert np.array_equal(rep.cases.q_start[1], q0) and np.array_equal(rep.cases.q_goal[1], q1)
    np.testing.assert_allclose(rep.cases.T_world_ee_goal[1], world.robot.compute_ee_pose(q1))
    keep = [0, 2, 3, 4, 5]
    assert np.array_equal(rep.cases.q_start[keep], cases.q_start[keep])
    assert world.exact.valid(rep.cases.q_start[1:2]).all()


def test_solvability_pass_with_the_default_planner(world, cases, tmp_path):
    """The default pass, recorded in the cases (and their file): which planner, what limit."""
    rep = solvability_pass(world, cases.head(2))
    assert rep.planners == ("RRTConnect(deterministic)",) and len(rep.cases) == 2
    assert rep.cases.solvability == "RRTConnect(deterministic), no time limit"
    again = solvability_pass(world, rep.cases, [_FailsOn([])], time_limit_s=0.1).cases
    assert again.solvability == ("RRTConnect(deterministic), no time limit; stub, 0.1 s each")
    loaded = CaseSet.load(again.save(tmp_path / "c.npz"), world)
    assert loaded.solvability == again.solvability and loaded.same_as(again)


def test_cached_cases_generate_once(world, tmp_path):
    a = cached_cases(world, 3, seed=5, cache_dir=tmp_path)
    files = list(tmp_path.iterdir())
    assert len(files) == 1 and files[0].name.startswith("tabletop_pole-")
    assert cached_cases(world, 2, seed=5, cache_dir=tmp_path).same_as(a.head(2))
    assert len(list(tmp_path.iterdir())) == 1


def test_cli_generate_takes_registry_planners(tmp_path, capsys):
    """The solvability pass's planners come from the registry (names, aliases, +TrajOpt)."""
    out = tmp_path / "cases.npz"
    assert main(["cases", "generate", "tabletop_pole", "--n", "2", "--out", str(out),
                 "--planners", "lazyprm", "TrajOpt", "--solvability-limit", "0.5"]) == 0
    assert "solvability pass (LazyPRM, TrajOpt, 0.5 s each)" in capsys.readouterr().out


def test_cli_generate_and_info(tmp_path, capsys):
    out = tmp_path / "cases.npz"
    assert main(["cases", "generate", "tabletop_pole", "--n", "3", "--seed", "2",
                 "--out", str(out), "--solvability-limit", "1"]) == 0
    text = capsys.readouterr().out
    assert "generated 3 cases" in text and "solvability pass (RRTConnect" in text
    cases = CaseSet.load(out)
    assert len(cases) == 3 and cases.seed == 2
    assert main(["cases", "info", str(out), "--scene", "tabletop_pole"]) == 0
    text = capsys.readouterr().out
    assert "tabletop_pole" in text and "3 (seed 2" in text and "matches" in text
    assert "solvability RRTConnect(deterministic), 1 s each" in text
    assert main(["cases", "info", str(out), "--scene", "kitchen"]) == 2
    assert "not for scene 'kitchen'" in capsys.readouterr().err


# --- the task family (issue 17) ------------------------------------------------------------
def _meets(world, T_goal, q, pos_tol=0.005, rot_tol=0.05):
    from chekhov.transforms import rotation_angle

    T = world.robot.compute_ee_pose(q)
    return (float(np.linalg.norm(T[:3, 3] - T_goal[:3, 3])) <= pos_tol
            and rotation_angle(T[:3, :3], T_goal[:3, :3]) <= rot_tol)


@pytest.fixture(scope="module")
def tasks(world):
    return generate_cases(world, 8, seed=3, family="tasks")


def test_task_cases_are_deterministic_per_seed(world, tasks):
    assert tasks.family == "tasks" and len(tasks) == 8 and tasks.seed == 3
    assert generate_cases(world, 8, seed=3, family="tasks").same_as(tasks)
    assert generate_cases(world, 3, seed=3, family="tasks").same_as(tasks.head(3))
    other = generate_cases(world, 3, seed=4, family="tasks")
    assert not np.allclose(other.q_start, tasks.q_start[:3])
    # the random family is untouched: the same cases as before the families
    assert generate_cases(world, 6, seed=7, family="random").same_as(
        generate_cases(world, 6, seed=7))


def test_task_starts_are_free_pregrasps_and_goals_other_objects_pregrasps(world, tasks):
    from chekhov.cases import task_targets

    pregrasps = {label: T for o in world.scene.objects for label, T in o.pregrasp_poses()}
    assert task_targets(world).ready is None   # Baxter's SRDF names no ready configuration
    places = 0
    for i in range(len(tasks)):
        start, goal = tasks.start_labels[i], tasks.goal_labels[i]
        q0, q1 = tasks.q_start[i], tasks.q_goal[i]
        # the start: a pre-grasp configuration, free by both checkers, within the limits
        assert world.robot.within_limits(q0)[0] and world.exact.is_valid(q0)
        assert world.fast.valid(q0[None])[0]
        assert _meets(world, pregrasps[start], q0), start
        np.testing.assert_allclose(tasks.T_world_ee_start[i], world.robot.compute_ee_pose(q0))
        # the goal: another object's pre-grasp pose (or a place pose), with a free solution
        assert world.robot.within_limits(q1)[0] and world.exact.is_valid(q1)
        assert _meets(world, tasks.T_world_ee_goal[i], q1), goal
        if goal.startswith("place:"):
            places += 1
            if start != "ready":   # the picked object, set down elsewhere
                assert goal.split("/")[1] == start.split("/")[0]
        else:
            assert goal.split("/")[0] != start.split("/")[0], (start, goal)
            np.testing.assert_array_equal(tasks.T_world_ee_goal[i], pregrasps[goal])
        assert tasks.goal(i).is_pose
    assert places < len(tasks)


def test_place_pose_sets_the_object_down_on_a_free_spot(world):
    from chekhov.cases import place_pose

    scene = world.scene
    obj = next(o for o in scene.objects if o.grasps and o.articulation is None)
    region = scene.regions[0]
    lo = np.asarray(region.center) - np.asarray(region.size) / 2
    hi = lo + np.asarray(region.size)
    found = 0
    for u in np.random.default_rng(0).random((20, 2)):
        T = place_pose(scene, obj, obj.grasps[0], region, u)
        if T is None:
            continue
        found += 1
        T_obj = T @ np.linalg.inv(obj.grasps[0].T_obj_pregrasp)
        np.testing.assert_allclose(T_obj[:3, :3], obj.T_world_obj()[:3, :3], atol=1e-12)
        assert np.all(lo[:2] < T_obj[:2, 3]) and np.all(T_obj[:2, 3] < hi[:2])
        assert lo[2] < T_obj[2, 3] - obj.shape.half_extents[2] < hi[2]
    assert found >= 5


def test_task_file_round_trip_keeps_family_and_labels(world, tasks, tmp_path):
    path = tasks.save(tmp_path / "t.npz")
    back = CaseSet.load(path, world)
    assert back.same_as(tasks) and back.family == "tasks"
    assert back.start_labels == tasks.start_labels and back.goal_labels == tasks.goal_labels
    with np.load(path) as z:
        assert json.loads(str(z["meta"]))["family"] == "tasks"
        assert z["goal_label"].shape == (len(tasks),)


def _rewrite_case_file(src, dst, edit=None, drop=()):
    with np.load(src) as z:
        data = {k: z[k] for k in z.files if k not in drop}
    meta = json.loads(str(data["meta"]))
    if edit is not None:
        edit(meta)
    data["meta"] = np.array(json.dumps(meta))
    np.savez(dst, **data)
    return dst


def test_old_version_files_are_read_as_random_and_unclear_ones_refused(world, cases, tasks,
                                                                      tmp_path):
    from chekhov.cases import CASE_FORMAT_VERSION
    from chekhov.errors import CaseFileError

    assert CASE_FORMAT_VERSION == 2
    path = cases.save(tmp_path / "c.npz")

    def v1(meta):   # a file written before the families: version 1, no 'family'
        meta["version"] = 1
        del meta["family"]

    old = CaseSet.load(_rewrite_case_file(path, tmp_path / "v1.npz", v1), world)
    assert old.family == "random" and old.same_as(cases)

    def before_solvability_field(meta):   # version 2 as written before session 38
        del meta["solvability"]

    older = _rewrite_case_file(path, tmp_path / "v2old.npz", before_solvability_field)
    assert CaseSet.load(older, world).solvability == ""

    def bad_solvability(meta):
        meta["solvability"] = 3

    with pytest.raises(CaseFileError, match=r"badsolv\.npz: meta field 'solvability' must be"):
        CaseSet.load(_rewrite_case_file(path, tmp_path / "badsolv.npz", bad_solvability))

    def no_family(meta):
        del meta["family"]

    with pytest.raises(CaseFileError, match=r"nofamily\.npz: .*meta field 'family'"):
        CaseSet.load(_rewrite_case_file(path, tmp_path / "nofamily.npz", no_family))

    def other_family(meta):
        meta["family"] = "chores"

    with pytest.raises(CaseFileError, match=r"chores\.npz: meta field 'family' must be"):
        CaseSet.load(_rewrite_case_file(path, tmp_path / "chores.npz", other_family))
    tpath = tasks.save(tmp_path / "t.npz")
    with pytest.raises(CaseFileError, match=r"nolabel\.npz: .*lacks the array 'goal_label'"):
        CaseSet.load(_rewrite_case_file(tpath, tmp_path / "nolabel.npz", drop=["goal_label"]))


def test_solvability_pass_replaces_task_cases_by_task_cases(world, tasks):
    from chekhov.cases import draw_case

    cases = tasks.head(3)
    rep = solvability_pass(world, cases, [_FailsOn([cases.q_start[1]])], time_limit_s=0.1)
    assert rep.replaced == 1 and rep.replaced_indices == (1,)
    d = draw_case(world, "tasks", cases.seed, 1, attempt=1)
    out = rep.cases
    assert out.family == "tasks"
    assert np.array_equal(out.q_start[1], d.q_start) and np.array_equal(out.q_goal[1], d.q_goal)
    assert np.array_equal(out.T_world_ee_goal[1], d.T_goal)
    assert (out.start_labels[1], out.goal_labels[1]) == (d.start_label, d.goal_label)
    assert out.start_labels[::2] == cases.start_labels[::2]


def test_cached_cases_are_keyed_by_family(world, tasks, tmp_path):
    t = cached_cases(world, 2, seed=3, cache_dir=tmp_path, family="tasks")
    r = cached_cases(world, 2, seed=3, cache_dir=tmp_path)
    assert t.same_as(tasks.head(2)) and r.family == "random"
    names = sorted(p.name for p in tmp_path.iterdir())
    assert len(names) == 2 and "-random-s3-n2" in names[0] and "-tasks-s3-n2" in names[1]
    assert cached_cases(world, 2, seed=3, cache_dir=tmp_path, family="tasks").same_as(t)
    assert len(list(tmp_path.iterdir())) == 2


def test_ready_configuration_comes_from_the_srdf(world_of):
    from chekhov.cases import ready_configuration

    q = ready_configuration(world_of("panda_cage"))   # the Panda SRDF's "default" state
    np.testing.assert_allclose(q, [0, -0.785398, 0, -2.35619, 0, 1.5707, 0.785398])


def test_cli_generate_and_info_of_the_task_family(tmp_path, capsys, monkeypatch):
    from chekhov.cases import FAMILIES
    from chekhov.cli.checks import CASE_FAMILIES

    assert CASE_FAMILIES == FAMILIES
    monkeypatch.chdir(tmp_path)
    assert main(["cases", "generate", "tabletop_pole", "--family", "tasks", "--n", "2",
                 "--seed", "3", "--no-solvability"]) == 0
    assert "generated 2 cases of family tasks" in capsys.readouterr().out
    out = tmp_path / "tabletop_pole-tasks-s3-n2.npz"    # the default name says the family
    assert CaseSet.load(out).family == "tasks"
    assert main(["cases", "info", str(out), "--scene", "tabletop_pole"]) == 0
    text = capsys.readouterr().out
    assert "family     tasks" in text and "2 at pre-grasps" in text
