"""The reproducible RRT-Connect (seeded, node-bounded) and the solvability pass it decides:
same query, same answer; a path's edges refused by the stricter test are cut and the search
goes on; the budget ends a hopeless search."""

from itertools import pairwise

import numpy as np
import pytest
from hypothesis import event, given
from hypothesis import strategies as st

from chekhov.bench.solvability import solvability_pass
from chekhov.cases import generate_cases
from chekhov.errors import ChekhovError
from chekhov.planners.rrt_connect import DeterministicRRTConnect, DeterministicRRTConnectConfig
from chekhov.roadmap.trees import Tree, rrt_connect
from chekhov.robot.goal import Goal

# A 2-D square [-1, 1]²: a wall x = 0 with a gap at y > 0.6. ``free`` only looks at the
# motion's end (it misses the wall); ``crosses`` is the truth.
LO, HI = np.array([-1.0, -1.0]), np.array([1.0, 1.0])


def crosses(q0, q1):
    """The segment q0 → q1 crosses x = 0 below the gap."""
    if (q0[0] < 0) == (q1[0] < 0):
        return False
    t = q0[0] / (q0[0] - q1[0])
    return q0[1] + t * (q1[1] - q0[1]) <= 0.6


def search(certify, seed=0, max_nodes=5000):
    rng = np.random.default_rng(seed)
    return rrt_connect(np.array([-0.8, -0.8]), np.array([[0.8, -0.8]]), lambda a, b: True,
                       lambda: rng.uniform(LO, HI), step=0.3, max_nodes=max_nodes,
                       certify=certify)


def test_refused_edges_are_cut_and_the_search_goes_on():
    blind = search(None)
    assert blind.status == "solved" and any(crosses(a, b) for a, b in
                                            zip(blind.path[:-1], blind.path[1:], strict=True))
    for seed in range(5):
        r = search(lambda a, b: not crosses(a, b), seed)
        assert r.status == "solved", seed
        assert not any(crosses(a, b) for a, b in zip(r.path[:-1], r.path[1:], strict=True))
        assert r.path[:, 1].max() > 0.6        # through the gap
        np.testing.assert_array_equal(r.path[0], [-0.8, -0.8])
        np.testing.assert_array_equal(r.path[-1], [0.8, -0.8])


def _hits_box(q0, q1, box):
    """Whether the segment q0 → q1 meets the axis-aligned box (lo, hi) (slab test)."""
    lo, hi = box
    t0, t1 = 0.0, 1.0
    d = q1 - q0
    for k in range(2):
        if abs(d[k]) < 1e-15:
            if not lo[k] <= q0[k] <= hi[k]:
                return False
            continue
        a, b = (lo[k] - q0[k]) / d[k], (hi[k] - q0[k]) / d[k]
        t0, t1 = max(t0, min(a, b)), min(t1, max(a, b))
    return t0 <= t1


boxes = st.lists(st.tuples(st.floats(-0.9, 0.7), st.floats(-0.9, 0.7), st.floats(0.02, 0.3),
                           st.floats(0.02, 0.3)), min_size=1, max_size=6)


@given(boxes, st.integers(0, 2**32 - 1))
def test_any_path_found_is_certified_edge_by_edge(spec, seed):
    """Random boxes in the square; ``free`` sees only a motion's end, ``certify`` the whole
    segment. Whatever is found starts at the start, ends at a goal root, steps at most
    ``step``, and every edge passes ``certify``; the same seed finds the same path."""
    B = [(np.array([x, y]), np.array([x + w, y + h])) for x, y, w, h in spec]
    start, goals = np.array([-0.95, -0.95]), np.array([[0.95, 0.95], [0.95, -0.95]])

    def inside(q):
        return any((lo <= q).all() and (q <= hi).all() for lo, hi in B)

    if inside(start) or all(inside(g) for g in goals):
        event("an end inside a box")
        return
    goals = goals[[not inside(g) for g in goals]]

    def run():
        rng = np.random.default_rng(seed)
        return rrt_connect(start, goals, lambda a, b: not inside(b), lambda: rng.uniform(LO, HI),
                           step=0.25, max_nodes=1500,
                           certify=lambda a, b: not any(_hits_box(a, b, x) for x in B))

    r = run()
    event(r.status)
    if r.path is None:
        assert r.status == "exhausted" and r.n_nodes >= 1500
        return
    P = r.path
    np.testing.assert_array_equal(P[0], start)
    assert any(np.array_equal(P[-1], g) for g in goals)
    assert (np.linalg.norm(np.diff(P, axis=0), axis=1) <= 0.25 + 1e-12).all()
    assert not any(_hits_box(a, b, x) for a, b in pairwise(P) for x in B)
    np.testing.assert_array_equal(run().path, P)


def test_the_node_budget_ends_a_hopeless_search():
    r = search(lambda a, b: (a[0] < 0) == (b[0] < 0), max_nodes=300)   # a closed wall
    assert r.status == "exhausted" and r.path is None and r.n_nodes >= 300


def test_prune_removes_the_subtree():
    t = Tree(np.zeros((1, 2)))
    a = t.add(np.array([1.0, 0.0]), 0)
    b = t.add(np.array([2.0, 0.0]), a)
    c = t.add(np.array([0.0, 1.0]), 0)
    t.add(np.array([3.0, 0.0]), b)
    t.prune(a)
    assert t.nearest(np.array([3.0, 0.0])) in (0, c)
    assert np.isfinite(t.X[[0, c]]).all() and not np.isfinite(t.X[[a, b, 4]]).any()


@pytest.mark.parametrize("field,value", [("max_nodes", 0), ("n_ik", 1.5),
                                         ("range_fraction", 0.0), ("resolution", -0.01)])
def test_config_errors_name_the_field(field, value):
    with pytest.raises(ChekhovError, match=f"DeterministicRRTConnectConfig.{field}"):
        DeterministicRRTConnectConfig(**{field: value})


@pytest.fixture(scope="module")
def world(world_of):
    return world_of("tabletop_pole")


def test_same_query_same_answer_and_certified(world):
    """Two planners, the same query: identical paths; each checked here by coal at 400
    substeps per segment and the joint limits. The answer carries the proof its edges'
    checks made (and that proof covers the path the final check saw)."""
    cases = generate_cases(world, 4, seed=3)
    a, b = DeterministicRRTConnect(world), DeterministicRRTConnect(world)
    solved = 0
    for i in range(len(cases)):
        goal = Goal.pose(cases.T_world_ee_goal[i])
        ra = a.plan(cases.q_start[i], goal, float("inf"))
        rb = b.plan(cases.q_start[i], goal, float("inf"))
        assert ra.status == rb.status
        if ra.success:
            solved += 1
            np.testing.assert_array_equal(ra.path, rb.path)
            assert ra.certificate is not None
            assert ra.certificate.covers_resampled(ra.path, 100, world.fast)
            assert world.exact.path_valid(ra.path, substeps=400)
            assert world.robot.within_limits(ra.path).all()
    assert solved >= 3


def test_the_solvability_pass_is_reproducible(world):
    """The default pass, twice on the same cases: the same cases out (no clock decides)."""
    cases = generate_cases(world, 6, seed=8)
    one = solvability_pass(world, cases)
    two = solvability_pass(world, cases)
    assert one.planners == ("RRTConnect(deterministic)",) and one.time_limit_s == float("inf")
    assert one.cases.same_as(two.cases) and one.replaced_indices == two.replaced_indices
