"""Sphere hits on mesh links are confirmed on the convex hulls of the mesh's parts
(``primitives.hull_parts``, ``gjk.convex_collide``), so the fast checker is conservative and
tight for a robot made of meshes (the Panda): it never says free where the exact checker
(coal on the meshes) says collision, also just past contact, and rarely says collision where
the exact checker says free, also just short of contact."""

import numpy as np
import pinocchio as pin
import pytest

from chekhov import Robot, World
from chekhov.collision.codes import HULL
from chekhov.collision.gjk import _hull_argmax, convex_collide
from chekhov.collision.primitives import hull_parts, support_points
from chekhov.scene.io import scene_from_dict

FINGERS = {"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04}


@pytest.fixture(scope="module")
def panda_world():
    """A Panda at a table with a shelf board, a post and a box: obstacles on every side."""
    def obj(name, shape, size, xyz):
        return {"name": name, "shape": shape, "size": size, "pose": {"xyz": xyz}}

    objects = [obj("table", "box", [0.8, 1.2, 0.04], [0.6, 0, -0.05]),
               obj("board", "box", [0.4, 0.8, 0.02], [0.6, 0, 0.45]),
               obj("post", "cylinder", [0.04, 1.0], [0.35, -0.35, 0.4]),
               obj("crate", "box", [0.15, 0.2, 0.15], [0.5, 0.35, 0.05])]
    scene = scene_from_dict({"format": 1, "name": "panda_probe", "robot": "panda",
                             "objects": objects})
    return World(scene, Robot.load("panda", locked=FINGERS))


def _distance(w, gd, q):
    i = pin.computeDistances(w.exact.model, w.exact.data, w.exact.geom_model, gd, q)
    return float(gd.distanceResults[i].min_distance)


def _near_contact(w, rng, n):
    """(free (n', K), past (n', K)): pairs on random joint-space rays from exactly free
    configurations, bisected to within 1e-4 rad of the first exact collision."""
    free, past = [], []
    for _ in range(40 * n):
        if len(free) == n:
            break
        q0 = w.robot.sample_uniform(rng, 1)[0]
        if not w.exact.is_valid(q0):
            continue
        v = rng.normal(size=w.robot.dof)
        v *= 0.1 / np.linalg.norm(v)
        a = b = None
        for k in range(1, 40):
            q = q0 + k * v
            if not w.robot.within_limits(q)[0]:
                break
            if not w.exact.is_valid(q):
                a, b = q - v, q
                break
        if a is None:
            continue
        while np.linalg.norm(b - a) > 1e-4:
            m = 0.5 * (a + b)
            a, b = (m, b) if w.exact.is_valid(m) else (a, m)
        free.append(a)
        past.append(b)
    return np.array(free), np.array(past)


def test_support_points_keep_the_support_function():
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(500, 3)) * (0.05, 0.02, 0.1)
    keep = support_points(pts)
    assert len(keep) < len(pts)
    U = rng.normal(size=(2000, 3))
    assert np.allclose((pts @ U.T).max(axis=0), (keep @ U.T).max(axis=0), atol=1e-12)


def test_hull_support_scan_finds_the_first_largest_point():
    """The hull's support point (four running maxima) is numpy's argmax of V·l: the first of
    the largest, for any length (not only multiples of four), with tied points, and on a
    range that does not start at 0."""
    rng = np.random.default_rng(11)
    for n in (1, 2, 3, 4, 5, 7, 8, 13, 152):
        V = rng.integers(-3, 4, size=(n + 3, 3)).astype(float)  # small integers: exact ties
        for _ in range(200):
            u = rng.integers(-2, 3, size=3).astype(float)
            d = V[3:, 0] * u[0] + V[3:, 1] * u[1] + V[3:, 2] * u[2]
            assert _hull_argmax(V, 3, n + 3, u[0], u[1], u[2]) == 3 + int(np.argmax(d))


def test_hull_gjk_agrees_with_coal_on_a_panda_link():
    """convex_collide(hull of a link mesh, box) says "apart" only when coal's distance between
    the mesh and the box is positive; and it says so for most boxes coal puts > 2 mm away."""
    import coal

    robot = Robot.load("panda")
    go = next(g for g in robot.collision_model.geometryObjects if g.name == "panda_link5_0")
    parts = hull_parts(go.geometry)
    rng = np.random.default_rng(5)
    box = coal.Box(0.04, 0.06, 0.02)
    half = np.array([0.02, 0.03, 0.01])
    eye, zero = np.eye(3), np.zeros(3)
    apart_by_coal = proved = 0
    for _ in range(400):
        R = pin.exp3(rng.normal(size=3))
        p = rng.uniform(-0.2, 0.2, size=3)
        req, res = coal.DistanceRequest(), coal.DistanceResult()
        d = coal.distance(go.geometry, coal.Transform3s(), box, coal.Transform3s(R, p), req, res)
        hit = any(convex_collide(HULL, eye, zero, zero, V, 0, len(V), V.mean(axis=0),
                                 1, R, p, half, np.zeros((0, 3)), 0, 0, p, 1e-4)
                  for V in parts)
        if not hit:
            assert d > 0, (R, p, d)          # never "apart" when coal says touching
        if d > 2e-3:
            apart_by_coal += 1
            proved += not hit
    assert apart_by_coal >= 100
    # the hull contains the (non-convex) mesh, so some boxes in its concavities stay "hit"
    assert proved >= 0.8 * apart_by_coal, (proved, apart_by_coal)


def test_panda_fast_checker_is_conservative_and_tight_on_random_configurations(panda_world):
    w = panda_world
    Q = w.robot.sample_uniform(np.random.default_rng(11), 3000)
    fast, exact = w.fast.valid(Q), w.exact.valid(Q)
    assert exact.sum() >= 600 and (~exact).sum() >= 300     # both kinds are exercised
    assert not np.any(fast & ~exact), np.flatnonzero(fast & ~exact)[:5]
    false_alarm = np.mean(~fast[exact])
    assert false_alarm <= 0.05, false_alarm                  # was 0.44 before hull confirmation


def test_panda_fast_checker_near_contact(panda_world):
    """Just past contact (1e-4 rad beyond the first exact collision) the fast checker says
    collision every time; just short of it, with exact clearance over 2 mm, it says free for
    most."""
    w = panda_world
    free, past = _near_contact(w, np.random.default_rng(13), 60)
    assert len(free) >= 40
    assert not np.any(w.fast.valid(past))
    gd = pin.GeometryData(w.exact.geom_model)
    back = []
    for q_free, q_past in zip(free, past, strict=True):   # step back to 2-20 mm clearance
        d = q_free - q_past
        for k in range(1, 200):
            q = q_free + 0.002 * k * d / np.linalg.norm(d)
            if not w.robot.within_limits(q)[0] or _distance(w, gd, q) > 0.02:
                break
            if _distance(w, gd, q) > 0.002:
                back.append(q)
                break
    assert len(back) >= 30
    back = np.array(back)
    assert np.all(w.exact.valid(back))
    assert np.mean(~w.fast.valid(back)) <= 0.1


def test_panda_ready_pose_and_pregrasps_are_free_in_both_checkers():
    """The ready pose does not self-collide (more mesh spheres used to make it)."""
    w = World(scene_from_dict({"format": 1, "name": "empty", "robot": "panda"}),
              Robot.load("panda", locked=FINGERS))
    q_ready = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    assert w.exact.is_valid(q_ready)
    assert w.fast.valid(q_ready[None])[0]


@pytest.mark.parametrize("scene", ["panda_table_shelf", "panda_cage"])
def test_every_panda_pregrasp_has_a_solution_both_checkers_call_free(scene):
    """The Panda's sphere model used to reject every grasp goal: now each pre-grasp pose of
    the built-in Panda scenes has an IK solution that both checkers call free, and no solution
    is called free by the fast checker alone."""
    from chekhov import IKError, solve_ik

    w = World.load(scene)
    rng = np.random.default_rng(sum(map(ord, scene)))
    poses = [(obj.name, label, T) for obj in w.scene.objects
             for label, T in obj.pregrasp_poses()]
    assert len(poses) >= 6
    for name, label, T in poses:
        try:
            Q = solve_ik(w.robot, T, 8, rng=rng)
        except IKError as e:
            raise AssertionError(f"{scene}: {name}/{label} unreachable: {e}") from e
        fast, exact = w.fast.valid(Q), w.exact.valid(Q)
        assert not np.any(fast & ~exact), (name, label)
        assert np.any(fast & exact), (name, label, fast, exact)


def test_mesh_spheres_inner_balls_lie_inside_the_hull_and_change_no_decision(panda_world):
    """A mesh sphere's inner ball (``packed.exact_geometry``) lies inside the convex hull of one
    of the mesh's parts — checked by Delaunay point location, not by the facet planes that
    sized it — so a hit it proves is one the hull confirmation would prove: the fast checker
    decides the same with the balls as with them set to 0, on random and near-contact
    configurations."""
    from scipy.spatial import Delaunay

    from chekhov.collision import validity

    w = panda_world
    pk = w.fast.packed
    geo, sph, grp = pk.geometry, pk.spheres, pk.groups
    on_mesh = np.zeros(len(sph.radius), dtype=bool)
    rng = np.random.default_rng(17)
    for g in np.flatnonzero(geo.kind == HULL):
        on_mesh[grp.start[g]:grp.start[g + 1]] = True
        tri = [Delaunay(geo.verts[geo.vert_start[k]:geo.vert_start[k + 1]])
               for k in range(geo.part_start[g], geo.part_start[g + 1])]
        for s in range(grp.start[g], grp.start[g + 1]):
            u = rng.normal(size=(300, 3))
            ball = sph.centre[s] + sph.inner[s] * u / np.linalg.norm(u, axis=1)[:, None]
            x = (ball - geo.p[g]) @ geo.R[g]          # the mesh's frame
            assert any(np.all(t.find_simplex(x, tol=1e-9) >= 0) for t in tri), (g, s)
    assert on_mesh.sum() >= 60 and np.mean(sph.inner[on_mesh] > 0) >= 0.8
    without = pk._replace(spheres=sph._replace(inner=np.where(on_mesh, 0.0, sph.inner)))
    free, past = _near_contact(w, np.random.default_rng(19), 40)
    Q = np.vstack([w.robot.sample_uniform(rng, 3000), free, past])
    with_balls = validity.valid_batch(Q, pk)
    assert (~with_balls).sum() >= 300
    assert np.array_equal(with_balls, validity.valid_batch(Q, without))
