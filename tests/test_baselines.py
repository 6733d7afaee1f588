"""Baseline planners: OMPL's RRTConnect, RRT, RRT*, PRM* and our LazyPRM."""

from types import SimpleNamespace

import numpy as np
import pytest

from chekhov.bench import generate_cases
from chekhov.errors import ChekhovError
from chekhov.planners.lazy_prm import (
    INVALID,
    VALID,
    LazyPRM,
    LazyPRMConfig,
    lazy_shortest_path,
)
from chekhov.planners.ompl_planner import OmplPlanner
from chekhov.robot.goal import Goal


@pytest.fixture(scope="module")
def world(world_of):
    return world_of("tabletop_pole")


@pytest.fixture(scope="module")
def case(world):
    cases = generate_cases(world, 3, seed=0)
    return cases.q_start[2], cases.goal(2), cases.T_world_ee_goal[2]


def _check_path(world, result, q_start, T_goal):
    assert result.success and result.status == "solved", result
    P = result.path
    assert P.ndim == 2 and P.shape[1] == world.robot.dof and len(P) >= 2
    np.testing.assert_allclose(P[0], q_start, atol=1e-12)
    np.testing.assert_allclose(world.robot.compute_ee_pose(P[-1]), T_goal, atol=1e-3)
    assert world.robot.within_limits(P).all()
    assert world.fast.path_valid(P, resolution=0.02)
    assert result.timing_s["ik"] > 0 and result.time_s >= sum(result.timing_s.values()) - 1e-6
    assert result.path_length > 0


@pytest.mark.parametrize("name", ["RRTConnect", "RRT", "RRT*", "PRM*"])
def test_ompl_planner_solves_a_tabletop_case(world, case, name):
    q_start, goal, T_goal = case
    planner = OmplPlanner(world, name, resolution=0.02, seed=0)
    limit = 1.0
    result = planner.plan(q_start, goal, time_limit_s=limit)
    _check_path(world, result, q_start, T_goal)
    assert result.info["motion_checks"] > 0
    if name in ("RRT*", "PRM*"):       # optimal planners use their whole limit
        assert result.time_s >= 0.9 * limit
    else:
        assert result.time_s < limit + 0.2


def test_ompl_simplify_and_errors(world, case):
    q_start, goal, T_goal = case
    planner = OmplPlanner(world, "RRTConnect", simplify=True, seed=1)
    assert planner.name == "RRTConnect+simplify"
    result = planner.plan(q_start, goal, 1.0)
    _check_path(world, result, q_start, T_goal)
    assert "simplify" in result.timing_s
    with pytest.raises(ChekhovError, match="unknown OMPL planner"):
        OmplPlanner(world, "FMT")
    far = np.eye(4)
    far[:3, 3] = [9.0, 0.0, 1.0]               # 9 m away: beyond the arm's reach
    bad = planner.plan(q_start, Goal.pose(far), 0.5)
    assert not bad.success and bad.status == "no_ik" and bad.path is None


def _simplify_with(planner, simplifier, monkeypatch):
    """``planner`` (RRTConnect) with ``simplifier`` in place of OMPL's PathSimplifier."""
    monkeypatch.setattr(planner, "_og", SimpleNamespace(PathSimplifier=simplifier,
                                                        RRTConnect=planner._og.RRTConnect))


def test_ompl_simplify_keeps_its_time_budget(world, case, monkeypatch):
    """OMPL's simplifier checks its budget only between its steps, and asked for at least one
    whole pass (its default) it went through all of one whatever the budget: under a 5 ms
    limit in panda_cage answers came after 5-21 ms. It is now started without that pass, with
    its budget (``simplify_time_s`` or the time left) less one step (``SIMPLIFY_STEP_S``),
    and not at all when that leaves nothing: recorded here on a stand-in simplifier."""
    calls = []

    class Recorder:
        def __init__(self, si, goal):
            pass

        def simplify(self, path, budget, at_least_once=True):
            calls.append((budget, at_least_once))

    q_start, goal, T_goal = case
    for simplify_time_s, runs in ((1e-6, 0), (1.0, 1)):
        planner = OmplPlanner(world, "RRTConnect", simplify=True,
                              simplify_time_s=simplify_time_s, seed=3)
        _simplify_with(planner, Recorder, monkeypatch)
        calls.clear()
        result = planner.plan(q_start, goal, 1.0)
        _check_path(world, result, q_start, T_goal)
        assert len(calls) == runs
        for budget, at_least_once in calls:
            assert 0 < budget <= simplify_time_s and at_least_once is False


def test_ompl_simplified_path_in_collision_gives_way_to_the_path_as_it_came(world, case,
                                                                             monkeypatch):
    """A simplified path that fails the certification (its motions are checked every 0.02
    rad, the certification's substeps are finer, and smoothing hugs obstacles: once in
    panda_cage RRTConnect + simplify answered ``collision``) is not the answer: the path as
    OMPL found it is, certified, and ``info["simplified_rejected"]`` says why. Here a
    stand-in simplifier moves an interior state into collision."""
    rng = np.random.default_rng(4)
    Q = world.robot.sample_uniform(rng, 400)
    q_bad = Q[~world.exact.valid(Q)][0]
    raw = []

    class Spoiler:
        def __init__(self, si, goal):
            pass

        def simplify(self, path, budget, at_least_once=True):
            raw.append(np.array([[path.getState(i)[j] for j in range(world.robot.dof)]
                                 for i in range(path.getStateCount())]))
            path.interpolate(max(3, path.getStateCount()))
            state = path.getState(1)
            for j, v in enumerate(q_bad):
                state[j] = float(v)

    q_start, goal, T_goal = case
    planner = OmplPlanner(world, "RRTConnect", simplify=True, seed=3)
    _simplify_with(planner, Spoiler, monkeypatch)
    result = planner.plan(q_start, goal, 1.0)
    _check_path(world, result, q_start, T_goal)
    assert len(raw) == 1 and np.array_equal(result.path, raw[0])
    assert result.info["simplified_rejected"].startswith("collision")
    assert result.timing_s["simplify_check"] > 0


# --- LazyPRM on a known graph ----------------------------------------------------------
#
#        3 (1, 1)
#       /        \            shortest 0-1-2 (length 2): node 1 is invalid
#  0 (0,0) - 1 (1,0) - 2 (2,0)  next 0-3-2 (2.83): edge 3-2 is invalid
#       \        /            then 0-4-2 (4.47): valid, must be returned
#        4 (1, -2)
X = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [1.0, 1.0], [1.0, -2.0]])
EDGES = np.array([[0, 1], [1, 2], [0, 3], [2, 3], [0, 4], [2, 4]])


def _injected(bad_nodes, bad_edges, log):
    bad_pts = {tuple(X[i]) for i in bad_nodes}
    bad_segs = {frozenset((tuple(X[a]), tuple(X[b]))) for a, b in bad_edges}

    def node_valid(Q):
        log.append(("nodes", [tuple(q) for q in Q]))
        return np.array([tuple(q) not in bad_pts for q in Q])

    def edge_valid(Q0, Q1, resolution):
        log.append(("edges", resolution, len(Q0)))
        return np.array([frozenset((tuple(a), tuple(b))) not in bad_segs
                         for a, b in zip(Q0, Q1, strict=True)])

    return node_valid, edge_valid


def test_lazy_shortest_path_on_a_known_graph():
    log = []
    node_valid, edge_valid = _injected([1], [(3, 2)], log)
    stats = {}
    path, ns, es = lazy_shortest_path(X, EDGES, 0, np.array([2]), node_valid, edge_valid,
                                      0.1, coarse_factor=4, stats=stats)
    assert path.tolist() == [0, 4, 2]
    assert ns[1] == INVALID and ns[[0, 2, 3, 4]].tolist() == [VALID] * 4
    assert es[3] == INVALID and es[4] == VALID and es[5] == VALID
    assert es[0] == 0 and es[1] == 0          # edges of an invalid node are never checked
    assert stats == {"searches": 3, "node_checks": 5, "edge_checks": 4}
    # nodes of each path are checked before its edges; edges coarse (0.4) before fine (0.1)
    kinds = [entry[0] for entry in log]
    assert kinds == ["nodes", "nodes", "edges", "nodes", "edges", "edges"]
    assert [e[1] for e in log if e[0] == "edges"] == [0.4, 0.4, 0.1]


def test_lazy_shortest_path_disconnected_and_multiple_goals():
    node_valid, edge_valid = _injected([1, 3, 4], [], [])
    path, ns, _ = lazy_shortest_path(X, EDGES, 0, np.array([2]), node_valid, edge_valid, 0.1)
    assert path is None and (ns[[1, 3, 4]] == INVALID).all()
    # two goals: the nearer one (3 via 0-3) wins once 1 is removed
    node_valid, edge_valid = _injected([1], [], [])
    path, _, _ = lazy_shortest_path(X, EDGES, 0, np.array([2, 3]), node_valid, edge_valid, 0.1)
    assert path.tolist() == [0, 3]


def test_lazy_prm_solves_a_tabletop_case(world, case):
    q_start, goal, T_goal = case
    planner = LazyPRM(world, LazyPRMConfig(resolution=0.02), seed=0)
    result = planner.plan(q_start, goal, time_limit_s=2.0)
    _check_path(world, result, q_start, T_goal)
    assert result.info["searches"] >= 1 and result.info["nodes"] >= 1000
    assert {"ik", "roadmap", "search", "check"} <= set(result.timing_s)


def test_lazy_prm_enhances_a_disconnected_roadmap(world, case):
    q_start, goal, T_goal = case
    planner = LazyPRM(world, LazyPRMConfig(n_init=5, n_enhance=300), seed=3)
    result = planner.plan(q_start, goal, time_limit_s=3.0)
    _check_path(world, result, q_start, T_goal)
    assert result.info["enhancements"] >= 1
