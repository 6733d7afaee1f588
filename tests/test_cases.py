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


def test_solvability_pass_with_the_default_planner(world, cases):
    rep = solvability_pass(world, cases.head(2), time_limit_s=1.0)
    assert rep.planners == ("RRTConnect",) and len(rep.cases) == 2


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
    assert main(["cases", "info", str(out), "--scene", "kitchen"]) == 2
    assert "not for scene 'kitchen'" in capsys.readouterr().err
