"""The certification proves the motion between its samples free, not only the samples.

A small sphere is placed next to a corner of the Baxter's finger-tip box so that the corner
sweeps through it between two of the certification's samples while both samples are clear:
a boolean check of the samples (what certification did before) passes such a path. The
truth comes from another mechanism: the exact checker on 20 times as many configurations
(one of which is the midpoint between the two samples).
"""

import numpy as np
import pinocchio as pin
import pytest

from chekhov import Goal, Shape
from chekhov.collision import path_check
from chekhov.collision.exact import densify
from chekhov.planners.certify import MAX_SEGMENT_RAD, SUBSTEPS, check_path
from chekhov.planners.query import make_query
from chekhov.planners.status import PlanStatus

SCENE = "tabletop_pole"
FINGER = "l_gripper_r_finger_tip_0"
N = SUBSTEPS + 1           # steps per segment at the certification's substeps
K = 50                     # the two samples K / N and (K + 1) / N straddle the obstacle
DENSE = 20 * N - 1         # 20 times the steps: the midpoint (K + 0.5) / N is a sample


def _box_at(world, q, gi):
    """World rotation, position and half sizes of geometry gi (a box) at q."""
    ex = world.exact
    gd = pin.GeometryData(ex.geom_model)
    pin.updateGeometryPlacements(ex.model, ex.model.createData(), ex.geom_model, gd, q)
    M = gd.oMg[gi]
    return M.rotation.copy(), M.translation.copy(), np.asarray(
        ex.geom_model.geometryObjects[gi].geometry.halfSide, dtype=float)


def _point_box_distance(c, box):
    R, p, h = box
    local = R.T @ (c - p)
    return float(np.linalg.norm(np.maximum(np.abs(local) - h, 0.0)))


def _corner_pass(world, P, t_near, around, gap, rho, dip=0.0):
    """(centre, radius) of a sphere that a corner of the finger-tip box passes at ``gap`` m
    (< 0: overlapping by as much) at fraction ``t_near`` of segment P (2, K), its closest
    approach: the centre ``rho + gap`` m from the corner, square to the corner's velocity and
    outside the box. Some corner must be the box's point nearest to it, and the sphere at
    least ``dip`` m farther from the box at the fractions ``around`` (the samples either
    side); None when none is."""
    gi = world.exact.geom_model.getGeometryId(FINGER)
    at = [_box_at(world, P[0] + t * (P[1] - P[0]), gi) for t in (around[0], t_near, around[1])]
    for s in np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).T.reshape(-1, 3):
        x = [R @ (s * h) + p for R, p, h in at]
        v = (x[2] - x[0]) / np.linalg.norm(x[2] - x[0])
        d0 = at[1][0] @ (s / np.sqrt(3.0))            # the corner's outward diagonal
        n = d0 - (d0 @ v) * v
        c = x[1] + (rho + gap) * n / np.linalg.norm(n)
        d = [_point_box_distance(c, b) for b in at]
        if abs(d[1] - (rho + gap)) < 1e-9 and min(d[0], d[2]) - d[1] > dip:
            return c, rho
    return None


def _place(world, c, r):
    T = np.eye(4)
    T[:3, 3] = c
    world.set_obstacles({"graze": (Shape("sphere", (r,)), T)})


def _segments(world, rng, n):
    """Up to n free straight segments (2, K), MAX_SEGMENT_RAD long less a little, whose
    finger tip is in open space (its 100-substep samples clear by the exact checker)."""
    robot = world.robot
    out = []
    for _ in range(400):
        q0 = robot.sample_uniform(rng, 1)[0]
        u = rng.normal(size=robot.dof)
        q1 = q0 + 0.99 * MAX_SEGMENT_RAD * u / np.linalg.norm(u)
        P = np.vstack([q0, q1])
        if robot.within_limits(P).all() and world.exact.valid(densify(P, 10)).all():
            out.append(P)
            if len(out) == n:
                break
    return out


@pytest.fixture(scope="module")
def world(world_of):
    w = world_of(SCENE)
    yield w
    w.set_obstacles({})


def _query(world, P):
    return make_query(world.robot, P[0], Goal.configuration(P[-1]), float("inf"))


def _grazing_case(world, rng):
    """A segment whose 100-substep samples are all free while the
    motion between samples K and K + 1 collides with the sphere (checked)."""
    for P in _segments(world, rng, 40):
        # 20 µm inside at the midpoint, the samples either side more than 0.1 mm farther
        found = _corner_pass(world, P, (K + 0.5) / N, (K / N, (K + 1) / N), -2e-5, 5e-4, 1e-4)
        if found is None:
            continue
        c, r = found
        _place(world, c, r)
        if world.exact.valid(densify(P, SUBSTEPS)).all() and \
                not world.exact.valid(densify(P, DENSE)).all():
            return P
        world.set_obstacles({})
    pytest.fail("no grazing case found")


def test_a_path_that_grazes_between_samples_is_rejected(world):
    rng = np.random.default_rng(3)
    P = _grazing_case(world, rng)
    try:
        # every configuration the certification samples is free: a boolean check passes it
        assert world.exact.valid(densify(P, SUBSTEPS)).all()
        assert not world.exact.valid(densify(P, DENSE)).all()
        valid, cert = path_check.exact_path_decision(world.fast, world.exact, P, SUBSTEPS)
        assert valid is False and cert is None
        why = check_path(world, _query(world, P), P)[0]
        assert why is not None and why[0] == PlanStatus.COLLISION
    finally:
        world.set_obstacles({})


@pytest.mark.parametrize("gap", [3e-3, 3e-4])
def test_a_path_passing_close_but_free_is_certified(world, monkeypatch, gap):
    """The corner passes ``gap`` m from the sphere (3 mm; 0.3 mm, less than the margin, so
    that the samples near it are refined) and the path is certified."""
    refined = []
    motion_free = path_check._motion_free
    monkeypatch.setattr(path_check, "_motion_free",
                        lambda *a: refined.append(1) or motion_free(*a))
    rng = np.random.default_rng(4)
    for P in _segments(world, rng, 40):
        found = _corner_pass(world, P, (K + 0.5) / N, (K / N, (K + 1) / N), gap, 2e-3)
        if found is None:
            continue
        c, r = found
        _place(world, c, r)
        try:
            if not world.exact.valid(densify(P, DENSE)).all():
                continue   # another part of the arm touches it
            why, cert = check_path(world, _query(world, P), P)
            assert why is None and cert is not None
            if gap < 1e-3:   # the samples near it are closer than their margin
                assert refined
            return
        finally:
            world.set_obstacles({})
    pytest.fail("no close-passing case found")


def test_no_coal_query_starts_after_the_deadline(world, monkeypatch):
    """The deadline is looked at before each coal distance query, not only between windows
    of samples (on a Jaco's 45,000-triangle meshes one window near contact took 400 ms):
    with a clock that passes the deadline during the first distance query, the decision is
    None and no other query follows."""
    now = [0.0]
    monkeypatch.setattr(path_check.time, "perf_counter", lambda: now[0])
    calls = []
    pair_distances = world.exact.pair_distances

    def timed(q, pairs):
        calls.append(now[0])
        now[0] = 10.0              # this query ran past the deadline
        return pair_distances(q, pairs)
    monkeypatch.setattr(world.exact, "pair_distances", timed)
    rng = np.random.default_rng(4)
    for P in _segments(world, rng, 40):
        found = _corner_pass(world, P, (K + 0.5) / N, (K / N, (K + 1) / N), 3e-4, 2e-3)
        if found is None:
            continue
        _place(world, *found)
        try:
            now[0], calls[:] = 0.0, []
            decision = path_check.exact_path_decision(world.fast, world.exact, P, SUBSTEPS,
                                                      deadline=1.0)
            if not calls:
                continue       # decided without a distance query
            assert decision.valid is None and decision.certificate is None
            assert calls == [0.0]
            return
        finally:
            world.set_obstacles({})
    pytest.fail("no case with a distance query found")


def test_a_start_in_contact_free_proximity_is_valid(world):
    """The path's first configuration 10 µm from an object (a grasp) keeps the boolean test:
    the path away from it is certified."""
    rng = np.random.default_rng(5)
    for P in _segments(world, rng, 40):
        found = _corner_pass(world, P, 0.0, (-1 / N, 1 / N), 1e-5, 2e-3)
        if found is None:
            continue
        c, r = found
        _place(world, c, r)
        try:
            if not world.exact.valid(densify(P, DENSE)).all():
                continue
            why, _ = check_path(world, _query(world, P), P)
            assert why is None
            return
        finally:
            world.set_obstacles({})
    pytest.fail("no start near an object found")


@pytest.mark.parametrize("given_steps", [False, True])
def test_decision_margins_are_the_pairs_bounds(world, given_steps):
    """The decision's margins, computed per motion-weight row in one compiled call, are what
    the module docstring states per collision pair: the pair's largest motion bound L_p of a
    step between samples, its margin mu_p >= L_p / 2 (a power of the grid, + the slack, within
    the grid's factor), and each sphere group's screen margin the largest mu_p of the pairs of
    its geometry — computed here pair by pair, with the exact checker's pairs."""
    rng = np.random.default_rng(11)
    fast, exact = world.fast, world.exact
    W, row = exact.motion_weights
    pairs = exact.collision_pairs
    geometry = fast.spheres.geometries[fast.packed.groups.start[:-1]]
    for _ in range(20):
        P = world.robot.sample_uniform(rng, int(rng.integers(2, 12))) * rng.uniform(0.01, 1.0)
        steps = rng.normal(0.0, 0.01, (4, world.robot.dof)) if given_steps else None
        substeps = int(rng.choice([0, 10, 100]))
        coal_ = path_check._Coal.make(fast, exact, P, substeps, steps)
        coal_._pair_arrays()
        moves = np.abs(steps) if given_steps else np.abs(np.diff(P, axis=0)) / (substeps + 1)
        L = np.array([max(float(m @ W[row[p]]) for m in moves) for p in range(len(pairs))])
        np.testing.assert_allclose(coal_.L, np.maximum(L, 1e-12), rtol=1e-12)
        half = 0.5 * coal_.L
        assert np.all(coal_.mu >= half + path_check.MARGIN_SLACK - 1e-18)
        assert np.all(coal_.mu <= half * 2 ** (1 / 8) * (1 + 1e-12) + path_check.MARGIN_SLACK)
        pad = [max((coal_.mu[p] for p in range(len(pairs)) if g in pairs[p]), default=0.0)
               for g in geometry]
        np.testing.assert_array_equal(coal_.pad, pad)
        np.testing.assert_array_equal(
            coal_.grow, np.maximum(coal_.pad - fast.robot.description.spheres.padding, 0.0))
