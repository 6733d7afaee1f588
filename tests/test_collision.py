"""The fast checker against the exact one, and the checkers' behaviour."""

import time

import numpy as np
import pinocchio as pin
import pytest

from chekhov import Shape
from chekhov.collision.codes import OBSTACLE
from chekhov.collision.exact import densify
from chekhov.collision.fast import pinocchio_joint_placements

SCENES = ["tabletop_pole", "tabletop_container", "kitchen", "shelf_boxes"]
PANDA_SCENES = ["panda_table_shelf", "panda_cage"]


@pytest.mark.parametrize("scene", ["kitchen", "panda_cage"])
def test_numba_fk_matches_pinocchio(world_of, rng, scene):
    w = world_of(scene)
    for q in w.robot.sample_uniform(rng, 10):
        R, p = w.fast.joint_placements(q)
        for k, M in enumerate(pinocchio_joint_placements(w.robot, q)):
            assert np.allclose(R[k], M.rotation, atol=1e-12)
            assert np.allclose(p[k], M.translation, atol=1e-12)


@pytest.mark.parametrize("scene", SCENES + PANDA_SCENES)
def test_fast_never_says_free_where_exact_says_collision(world_of, scene):
    """100 000 random configurations per scene, for both robots: every one the fast checker
    calls free is free for the exact checker."""
    w = world_of(scene)
    Q = w.robot.sample_uniform(np.random.default_rng(sum(map(ord, scene))), 100_000)
    free = w.fast.valid(Q)
    exact_free = w.exact.valid(Q[free])
    missed = int(np.sum(~exact_free))
    assert missed == 0, f"{scene}: fast said free, exact said collision for {missed} configs"
    assert 0.2 < free.mean() < 0.9


def test_batched_equals_looped(world_of, rng):
    w = world_of("shelf_boxes")
    Q = w.robot.sample_uniform(rng, 300)
    batch = w.fast.valid(Q)
    assert np.array_equal(batch, np.array([w.fast.is_valid(q) for q in Q]))


def test_min_distance_agrees_with_validity(world_of, rng):
    w = world_of("tabletop_pole")
    Q = w.robot.sample_uniform(rng, 2000)
    d = w.fast.min_distance(Q)
    v = w.fast.valid(Q)
    # spheres apart prove the configuration free; sphere overlaps are confirmed on the
    # covered geometry, so an overlap may still be free
    assert np.all(v[d > 1e-6])
    assert np.all(d[~v] < 1e-6)
    assert np.any(v & (d < -1e-6))


def test_contacts_normals_match_finite_differences(world_of, rng):
    w = world_of("tabletop_pole")
    fast = w.fast
    q = None
    for cand in w.robot.sample_uniform(rng, 500):
        c = fast.contacts(cand, 0.05)
        if len(c) and np.any(c.source == OBSTACLE):
            q = cand
            break
    assert q is not None
    c = fast.contacts(q, 0.05)
    centers = fast.sphere_centers(q)
    from chekhov.collision import kernels

    env = fast.packed.obstacles
    for i in np.flatnonzero(c.source == OBSTACLE)[:10]:
        s, o = c.sphere[i], c.other[i]
        x = centers[s]
        eps = 1e-6
        grad = np.array([(kernels.signed_distance(env.kind[o], env.R[o], env.p[o], env.size[o],
                                                  x + eps * e)
                          - kernels.signed_distance(env.kind[o], env.R[o], env.p[o], env.size[o],
                                                    x - eps * e)) / (2 * eps)
                         for e in np.eye(3)])
        assert np.allclose(grad, c.normal[i], atol=1e-4)
        assert np.allclose(c.point[i], x - fast.spheres.radii[s] * c.normal[i])


def test_motion_validity_matches_dense_sampling(world_of, rng):
    """FastChecker.motions_valid (bisection order, early exit) decides each motion as checking
    every interior step k / n with valid() does."""
    w = world_of("tabletop_container")
    Q0 = w.robot.sample_uniform(rng, 200)
    Q1 = np.clip(Q0 + rng.normal(scale=0.3, size=Q0.shape), w.robot.lower, w.robot.upper)
    res = 0.02
    ok = w.fast.motions_valid(Q0, Q1, res)
    for i in range(200):
        n = int(np.ceil(np.linalg.norm(Q1[i] - Q0[i]) / res))
        interior = Q0[i] + (np.arange(1, n) / n)[:, None] * (Q1[i] - Q0[i])
        assert ok[i] == bool(w.fast.valid(interior).all() if len(interior) else True)
    assert 0 < ok.mean() < 1


@pytest.mark.parametrize("scene", ["panda_cage", "shelf_boxes"])
def test_clearance_world_keeps_every_link_that_far_from_everything(world_of, scene):
    """FastChecker.clearance_world(c): every configuration it calls free has each of the
    exact checker's collision pairs at least c apart by coal's distance; it calls free a
    subset of what the plain checker does, and its motion checks pass a subset of the plain
    ones, each motion as checking its interior steps in that world does."""
    w = world_of(scene)
    c = 0.01
    rng = np.random.default_rng(23)
    Q = w.robot.sample_uniform(rng, 1500)
    world_c = w.fast.clearance_world(c)
    free_c, free = w.fast.valid_in(world_c, Q), w.fast.valid(Q)
    assert not np.any(free_c & ~free)
    assert 0.2 * free.sum() < free_c.sum() < free.sum()
    ex = w.exact
    gd = pin.GeometryData(ex.geom_model)
    for q in Q[free_c]:
        pin.computeDistances(ex.model, ex.data, ex.geom_model, gd, q)
        assert min(r.min_distance for r in gd.distanceResults) >= c - 1e-6
    Q0 = Q[free_c][:150]
    Q1 = np.clip(Q0 + rng.normal(scale=0.3, size=Q0.shape), w.robot.lower, w.robot.upper)
    ok_c = w.fast.motions_valid(Q0, Q1, 0.02, clearance_m=c)
    ok = w.fast.motions_valid(Q0, Q1, 0.02)
    assert not np.any(ok_c & ~ok) and ok_c.sum() < ok.sum()
    for i in range(len(Q0)):
        n = int(np.ceil(np.linalg.norm(Q1[i] - Q0[i]) / 0.02))
        interior = Q0[i] + (np.arange(1, n) / n)[:, None] * (Q1[i] - Q0[i])
        assert ok_c[i] == bool(w.fast.valid_in(world_c, interior).all() if n > 1 else True)


def test_dynamic_obstacles_add_move_remove(world_of):
    w = world_of("tabletop_pole")
    q = np.array([0.0, -0.3, 0.0, 0.8, 0.0, 0.8, 0.0])
    assert w.fast.is_valid(q) and w.exact.is_valid(q)
    ee = w.robot.compute_ee_pose(q)[:3, 3]
    T = np.eye(4)
    T[:3, 3] = ee
    ball = Shape("sphere", (0.08,))
    w.add_obstacle("ball", ball, T)
    try:
        assert not w.fast.is_valid(q) and not w.exact.is_valid(q)
        T2 = T.copy()
        T2[2, 3] += 1.5
        w.move_obstacle("ball", T2)
        assert w.fast.is_valid(q) and w.exact.is_valid(q)
        w.move_obstacle("ball", T)
        assert not w.fast.is_valid(q)
    finally:
        w.remove_obstacle("ball")
    assert w.fast.is_valid(q) and w.exact.is_valid(q)
    with pytest.raises(KeyError):
        w.fast.move_obstacle("tabletop", T)


def test_exact_path_check_finds_collision_between_waypoints(world_of):
    w = world_of("tabletop_pole")
    # two free configurations either side of the pole, the straight line sweeps through it
    pole = w.scene.object("pole").pose.xyz
    Q = w.robot.sample_uniform(np.random.default_rng(7), 20000)
    ee = w.robot.compute_ee_poses(Q)[:, :3, 3]
    free = w.fast.valid(Q)
    near = free & (np.abs(ee[:, 2] - 1.0) < 0.1) & (np.abs(ee[:, 0] - pole[0]) < 0.05)
    left = np.flatnonzero(near & (ee[:, 1] > pole[1] + 0.12))
    right = np.flatnonzero(near & (ee[:, 1] < pole[1] - 0.12))
    found = False
    for a in left[:20]:
        for b in right[:20]:
            path = np.vstack([Q[a], Q[b]])
            if not w.exact.path_valid(path, substeps=100):
                assert not w.fast.path_valid(path)
                found = True
                break
        if found:
            break
    assert found


def test_densify_shape_and_endpoints():
    P = np.arange(21, dtype=float).reshape(3, 7)
    D = densify(P, 100)
    assert D.shape == (2 * 101 + 1, 7)
    assert np.allclose(D[0], P[0]) and np.allclose(D[101], P[1]) and np.allclose(D[-1], P[2])


@pytest.mark.parametrize("scene", SCENES)
def test_exact_path_check_equals_checking_every_configuration(world_of, scene):
    """The distance-certified path check finds the same first colliding configuration as
    checking every densified configuration one by one, on free and colliding paths."""
    w = world_of(scene)
    rng = np.random.default_rng(sum(map(ord, scene)))
    Q = w.robot.sample_uniform(rng, 2000)
    free = Q[w.fast.valid(Q)]
    found = {True: 0, False: 0}
    for n in range(90):   # at least 30 paths, more until both kinds are seen 5 times
        if n >= 30 and min(found.values()) >= 5:
            break
        q0 = free[rng.integers(len(free))]
        steps = rng.normal(scale=(0.05, 0.2, 0.5)[n % 3], size=(int(rng.integers(1, 5)), 7))
        P = np.clip(np.vstack([q0, q0 + np.cumsum(steps, axis=0)]), w.robot.lower,
                    w.robot.upper)
        substeps = (0, 5, 20)[n % 3]
        brute = w.exact.first_collision_brute(densify(P, substeps))
        assert w.exact.first_collision(P, substeps) == brute, (scene, n)
        assert w.exact.path_valid(P, substeps) == (brute is None)
        found[brute is None] += 1
    assert found[True] >= 5 and found[False] >= 5, found


def test_primitive_confirmation_never_misses_a_coal_collision():
    """The fast checker's exact primitive test (GJK with a support-value certificate) says
    'collision' whenever coal finds the two primitives closer than the padding."""
    import coal
    from scipy.spatial.transform import Rotation

    from chekhov.collision.gjk import primitives_collide

    rng = np.random.default_rng(5)
    shapes = [lambda s: coal.Sphere(s[0]), lambda s: coal.Box(*(2 * s)),
              lambda s: coal.Cylinder(s[0], 2 * s[1])]
    pad, free_found = 0.001, 0
    for i in range(3000):
        ka, kb = rng.integers(0, 3, 2)
        sa, sb = rng.uniform(0.005, 0.2, 3), rng.uniform(0.005, 0.2, 3)
        Ra, Rb = Rotation.random(2, random_state=i).as_matrix()
        pa, pb = rng.normal(scale=0.2, size=3), rng.normal(scale=0.2, size=3)
        d = coal.distance(shapes[ka](sa), coal.Transform3s(Ra, pa), shapes[kb](sb),
                          coal.Transform3s(Rb, pb), coal.DistanceRequest(),
                          coal.DistanceResult())
        hit = primitives_collide(ka, Ra, pa, sa, kb, Rb, pb, sb, pad)
        if d < pad - 1e-7:
            assert hit, (i, d)
        elif d > pad + 1e-4:
            free_found += 1
            assert not hit, (i, d)
    assert free_found > 1000


@pytest.mark.parametrize("scene", ["shelf_boxes", "kitchen", "panda_cage"])
def test_dense_path_check_equals_checking_every_configuration(world_of, scene):
    """Certified skipping (bounding-sphere and per-sphere certificates) gives the same first
    colliding index as checking all of densify(path, 100) with the fast checker, on free and
    colliding paths, without and with a dynamic obstacle beside the arm."""
    from chekhov.collision.exact import densify

    w = world_of(scene)
    rng = np.random.default_rng(5)
    Q = w.robot.sample_uniform(rng, 2000)
    Q = Q[w.fast.valid(Q)]
    T = np.eye(4)
    T[:3, 3] = w.robot.compute_ee_pose(Q[0])[:3, 3] + np.array([0.0, 0.0, 0.12])
    kinds = set()
    for dynamic in (False, True):
        if dynamic:
            w.add_obstacle("probe", Shape("sphere", (0.06,)), T)
        try:
            for i in range(0, 40, 2):
                scale = 1.0 if i % 4 == 0 else 0.3
                P = np.linspace(Q[i], Q[i] + scale * (Q[i + 1] - Q[i]), 12)
                v = w.fast.valid(densify(P, 100))
                ref = None if v.all() else int(np.flatnonzero(~v)[0])
                assert w.fast.first_dense_collision(P, 100) == ref, (dynamic, i)
                kinds.add(ref is None)
        finally:
            if dynamic:
                w.remove_obstacle("probe")
    assert kinds == {True, False}


def test_budgeted_motion_checks_resumed_decide_the_same(world_of):
    """The motion kernel cut into calls of a few configurations each (as near a deadline),
    each resumed at the motion and step where the last stopped, decides every motion as one
    unbudgeted call does; FastChecker.motions_valid with a deadline already passed decides
    the motions its one call reaches and calls the rest blocked."""
    from chekhov.collision import validity

    w = world_of("panda_cage")
    Q = w.robot.sample_uniform(np.random.default_rng(12), 2000)
    Q = Q[w.fast.valid(Q)]
    A, B = Q[:120], Q[120:240]
    ref = w.fast.motions_valid(A, B, 0.02)
    assert 0 < ref.mean() < 1
    out, done, resume, calls = np.zeros(len(A), dtype=bool), 0, 0, 0
    while done < len(A):
        part, done, resume = validity.motions_valid(A, B, 0.02, done, resume, 5, False,
                                                    w.fast.packed)
        out |= part
        calls += 1
    np.testing.assert_array_equal(out, ref)
    assert calls > len(A)   # motions were cut and resumed
    late = w.fast.motions_valid(A, B, 0.02, deadline=0.0)
    assert not (late & ~ref).any() and late.sum() < ref.sum()
    # the first free motion, from every place in the list and when none is left
    free = np.flatnonzero(ref)
    for k in range(0, len(A), 7):
        later = free[free >= k]
        want = int(later[0] - k) if len(later) else None
        assert w.fast.first_free_motion(A[k:], B[k:], 0.02) == want
    assert w.fast.first_free_motion(A[~ref], B[~ref], 0.02) is None
    # a motion with no interior step is free, and ends the search there
    k = int(np.flatnonzero(~ref)[0])
    stay = np.vstack([A[~ref][:3], A[k:k + 1], A[~ref][3:6]])
    to = np.vstack([B[~ref][:3], A[k:k + 1], B[~ref][3:6]])
    assert w.fast.first_free_motion(stay, to, 0.02) == 3


def test_group_order_and_coarse_grids_do_not_change_decisions(world_of, rng):
    """The fast checker visits the most often blocked groups first and screens groups on
    coarse grids (one lookup in the static and fixed-part grids combined first); with the
    plain order and the fine grids only it decides the same."""
    from chekhov.collision import validity

    fast = world_of("shelf_boxes").fast
    Q = fast._as_batch(fast.robot.sample_uniform(rng, 20000))
    g = fast.packed.grids
    assert sorted(g.order.tolist()) == list(range(len(g.fixed)))
    n = (len(g.coarse) - 1) // 2   # the coarse stack: static, n fixed-part sets, n combined
    fine = g.fine[:1 + n]
    plain = fast.packed._replace(grids=g._replace(
        coarse_h=g.h, inv_coarse_h=g.inv_h,
        coarse=np.concatenate([fine, np.minimum(fine[:1], fine[1:])]),
        order=np.arange(len(g.fixed), dtype=np.int64)))
    np.testing.assert_array_equal(validity.valid_batch(Q, plain), fast.valid(Q))


def test_packed_world_dynamic_updates_repack_only_the_obstacles(world_of):
    """Adding, moving and removing a dynamic obstacle replaces the packed world's obstacle
    fields only (grids, spheres, fixed parts are the same objects) and changes the answers."""
    from chekhov.collision.fast import FastChecker
    from chekhov.collision.packed import GridCache
    from chekhov.robot.chain_kinematics import ChainKinematics

    w = world_of("tabletop_pole")
    fast = FastChecker(w.robot, w.scene, grid_cache=GridCache())
    before = fast.packed
    Q = w.robot.sample_uniform(np.random.default_rng(3), 2000)
    free0 = fast.valid(Q)
    np.testing.assert_array_equal(free0, w.fast.valid(Q))
    x = fast.sphere_centers(Q[np.flatnonzero(free0)[0]])[-1]
    fast.add_obstacle("probe", Shape("sphere", (0.05,)), np.block(
        [[np.eye(3), x[:, None]], [np.zeros((1, 3)), np.ones((1, 1))]]))
    after = fast.packed
    assert after.grids is before.grids and after.fixed is before.fixed
    assert after.spheres is before.spheres and after.chain is before.chain
    assert len(after.dynamic.kind) == len(before.dynamic.kind) + 1
    assert len(after.obstacles.kind) == len(fast.obstacle_names)
    assert (~fast.valid(Q) & free0).any()
    fast.remove_obstacle("probe")
    np.testing.assert_array_equal(fast.valid(Q), free0)
    # one FK: the IK chain and the collision chain are the same arrays
    kin = ChainKinematics.from_robot(w.robot)
    for a, b in zip(kin.chain, fast.packed.chain, strict=True):
        np.testing.assert_array_equal(a, b)


def test_convex_gap_is_a_lower_bound_on_the_distance_that_converges():
    """gjk.convex_gap never exceeds the true distance (spheres and boxes at known gaps), comes
    within a micrometre of it when asked for more than the distance, stops early once it
    proves the target, and finds no positive gap between overlapping shapes."""
    from chekhov.collision.codes import BOX, SPHERE
    from chekhov.collision.gjk import convex_gap

    V = np.empty((0, 3))
    rng = np.random.default_rng(11)
    for _ in range(50):
        pa = rng.normal(size=3)
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        gap = rng.uniform(-0.05, 0.2)
        ra, rb = rng.uniform(0.02, 0.2, size=2)
        pb = pa + (ra + rb + gap) * u
        sa, sb = np.array([ra, 0.0, 0.0]), np.array([rb, 0.0, 0.0])
        eye = np.eye(3)
        got = convex_gap(SPHERE, eye, pa, sa, V, 0, 0, pa, SPHERE, eye, pb, sb, V, 0, 0, pb, 1.0,
                         1.0)
        if gap <= 0:
            assert got <= 1e-9
        else:
            assert gap - 1e-6 <= got <= gap + 1e-12
            early = convex_gap(SPHERE, eye, pa, sa, V, 0, 0, pa, SPHERE, eye, pb, sb, V, 0, 0,
                               pb, 0.5 * gap, 0.5 * gap)
            assert 0.5 * gap < early <= gap + 1e-12
    # two unit-half-extent boxes, faces 3 cm apart, the second turned about the gap's axis
    c, s = np.cos(0.4), np.sin(0.4)
    Rz = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    half = np.full(3, 0.5)
    pa, pb = np.zeros(3), np.array([1.03, 0.0, 0.0])
    got = convex_gap(BOX, np.eye(3), pa, half, V, 0, 0, pa, BOX, Rz, pb, half, V, 0, 0, pb, 1.0,
                     1.0)
    assert 0.03 - 1e-6 <= got <= 0.03 + 1e-12
    # a cube 10 cm beside a long bar's side, off its centre's direction: stopped at the first
    # point of A − B within 1 m, GJK gives the bound along that direction only; converged
    # (near < 0), the distance
    bar, cube = np.array([0.5, 0.05, 0.05]), np.full(3, 0.05)
    pb = np.array([0.45, 0.2, 0.0])
    eye = np.eye(3)
    first = convex_gap(BOX, eye, pa, bar, V, 0, 0, pa, BOX, eye, pb, cube, V, 0, 0, pb, 1.0, 1.0)
    full = convex_gap(BOX, eye, pa, bar, V, 0, 0, pa, BOX, eye, pb, cube, V, 0, 0, pb, 1.0, -1.0)
    assert first <= full + 1e-12 and 0.1 - 1e-6 <= full <= 0.1 + 1e-12


@pytest.mark.parametrize("scene", ["panda_cage", "tabletop_pole"])
def test_dense_path_check_near_contact_equals_every_configuration(world_of, scene):
    """Paths that graze the scene, millimetres from contact all along (where a group's
    spheres touch and its certificate comes from GJK on the covered geometry), with and
    without the certification's margins: the dense walk's first colliding index is the one
    checking every configuration of densify(path, substeps) gives — also when the walk is cut
    into calls of a few configurations, each resumed where the last stopped. Every other
    path is an arc of short uneven segments at 6 substeps, as a timed trajectory's knots,
    which the walk takes in runs of several segments (``walk_runs.run_end``), its
    certificates held across the knots."""
    from chekhov.collision import dense_path, validity, walk_runs
    from chekhov.collision.exact import densify

    w = world_of(scene)
    fast = w.fast
    rng = np.random.default_rng(11)
    G = len(fast.packed.groups.radius)
    margins = [(np.zeros(0), np.zeros(0)), (np.full(G, 0.002), np.full(G, 0.001))]
    seen: dict[bool, int] = {True: 0, False: 0}
    paths = resumed = joined = 0
    span = np.empty(w.robot.dof)
    while paths < 30:
        q0 = w.robot.sample_uniform(rng, 1)[0]
        v = rng.normal(size=w.robot.dof)
        v *= 0.05 / np.linalg.norm(v)
        steps = q0 + np.arange(1, 40)[:, None] * v
        ok = fast.valid(steps)
        if not fast.is_valid(q0) or ok.all():
            continue
        k = int(np.argmin(ok))
        lo, hi = (q0 if k == 0 else steps[k - 1]), steps[k]
        for _ in range(12):              # bisect to just short of contact
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if fast.is_valid(mid) else (lo, mid)
        side = rng.normal(size=w.robot.dof)
        side -= side @ v / (v @ v) * v   # along the surface, roughly
        side *= 0.08 / np.linalg.norm(side)
        if paths % 2:   # an arc: 12 knots 0.8-1.2 apart in u, bent off the chord by ~1 cm
            u = np.cumsum(np.r_[0.0, rng.uniform(0.8, 1.2, 11)])
            u /= u[-1]
            bend = rng.normal(size=w.robot.dof)
            bend *= 0.02 / np.linalg.norm(bend)
            P = lo + u[:, None] * side + (4.0 * u * (1.0 - u))[:, None] * bend
            substeps = 6
            joined += walk_runs.run_end(P, 0, len(P) - 1, substeps + 1, span) > 1
        else:
            P = lo + np.linspace(0.0, 1.0, 6)[:, None] * side
            substeps = 100
        paths += 1
        for pad, grow in margins:
            packed = fast.packed if len(pad) == 0 else dense_path.with_margin(
                fast.packed, pad, grow)
            v_all = ~validity.valid_batch(densify(P, substeps), packed)
            ref = int(np.flatnonzero(v_all)[0]) if v_all.any() else -1
            got, resume = dense_path.first_dense_collision(P, substeps, 0, dense_path.NO_BUDGET,
                                                           pad, grow, fast.packed)
            assert got == ref and resume == -1, (paths, len(pad))
            resume, calls = 0, 0
            while resume >= 0:
                got, resume = dense_path.first_dense_collision(P, substeps, resume, 3, pad,
                                                               grow, fast.packed)
                calls += 1
            assert got == ref, (paths, len(pad), calls)
            resumed += calls > 1
            seen[ref < 0] += 1
    assert seen[True] >= 5 and seen[False] >= 5, seen
    assert resumed >= 10, resumed
    assert joined >= 10, joined


def test_repacked_obstacles_equal_packing_them_afresh(world_of):
    """The packed obstacle arrays, which reuse the rows the obstacle list shares with the
    last packing, equal packing the whole list again, through a random series of sets,
    moves and removals (the scene's static obstacles first)."""
    from chekhov.collision.primitives import pack_primitives

    w = world_of("kitchen")
    fast, rng = w.fast, np.random.default_rng(4)
    shapes = [Shape("sphere", (0.05,)), Shape("box", (0.1, 0.2, 0.1)),
              Shape("capsule", (0.04, 0.3))]

    def pose():
        T = np.eye(4)
        T[:3, 3] = rng.uniform(-1, 1, 3)
        return T

    try:
        for _ in range(40):
            op = rng.integers(3)
            names = fast.dynamic_obstacles
            if op == 0 or not names:
                fast.set_obstacles({f"o{i}": (shapes[rng.integers(3)], pose())
                                    for i in rng.permutation(5)[:rng.integers(0, 5)]})
            elif op == 1:
                fast.move_obstacle(names[rng.integers(len(names))], pose())
            else:
                fast.remove_obstacle(names[rng.integers(len(names))])
            prims = fast._obstacles
            want_all = pack_primitives(prims.values())
            want_dyn = pack_primitives(p for n, p in prims.items() if n in fast._dynamic)
            for got, want in ((fast.packed.obstacles, want_all), (fast.packed.dynamic, want_dyn)):
                for a, b in zip(got, want, strict=True):
                    assert a.dtype == b.dtype and a.flags.c_contiguous
                    assert np.array_equal(a, b)
    finally:
        fast.set_obstacles({})


def test_moving_obstacles_keeps_compiled_entries_and_answers_with_the_new_pose(world_of):
    """Changing the dynamic obstacles repacks them without typing the packed world again
    (the compiled entry points are kept), and the kept entries read the new obstacles."""
    w = world_of("tabletop_pole")
    fast = w.fast
    Q = w.robot.sample_uniform(np.random.default_rng(2), 200)
    q = Q[fast.valid(Q)][0]
    T = np.eye(4)
    T[:3, 3] = w.robot.compute_ee_pose(q)[:3, 3]
    far = np.eye(4)
    far[:3, 3] = (5.0, 5.0, 5.0)
    fast.add_obstacle("probe", Shape("sphere", (0.05,)), T)
    try:
        assert not fast.is_valid(q)
        kept = dict(fast._entries)
        assert kept
        fast.move_obstacle("probe", far)
        assert fast.is_valid(q)
        fast.set_obstacles({"probe": (Shape("sphere", (0.05,)), T),
                            "other": (Shape("box", (0.1, 0.1, 0.1)), far)})
        assert not fast.is_valid(q)
        assert fast._entries == kept
        # two of one kind: their arrays are only C-contiguous where one row was also
        # Fortran-contiguous — the same numba type, so the entries stay
        fast.set_obstacles({"probe": (Shape("sphere", (0.05,)), far),
                            "other": (Shape("sphere", (0.05,)), T)})
        assert fast._entries == kept       # before any check could have typed them again
        assert not fast.is_valid(q)
    finally:
        fast.set_obstacles({})
    assert fast._entries == kept
    assert fast.is_valid(q)


@pytest.mark.parametrize("scene", ["panda_cage", "tabletop_pole"])
def test_screening_margins_set_for_the_asked_pairs_only(world_of, scene):
    """ExactChecker.pairs_within sets the security margins of the pairs it is asked about
    only: after a subset was asked with other margins, the answers for all pairs and for
    another subset are those of a checker that never saw the other margins."""
    from chekhov import World

    used, fresh = world_of(scene).exact, World.load(scene).exact
    n = len(used.collision_pairs)
    rng = np.random.default_rng(13)
    seen = 0
    for q in world_of(scene).robot.sample_uniform(rng, 30):
        m_a, m_b = rng.choice([0.0, 0.01, 0.05], n), rng.choice([0.0, 0.02, 0.08], n)
        used.pairs_within(q, m_a, rng.choice(n, n // 3, replace=False))
        ref = fresh.pairs_within(q, m_b)
        np.testing.assert_array_equal(used.pairs_within(q, m_b), ref)
        for size in (n // 10, n // 2):   # one pair at a time, and coal's all-pairs call
            sub = np.sort(rng.choice(n, size, replace=False))
            used.pairs_within(q, m_a, sub)
            np.testing.assert_array_equal(used.pairs_within(q, m_b, sub),
                                          np.intersect1d(ref, sub))
        seen += len(ref) > 0
    assert seen >= 5, seen


@pytest.mark.parametrize("scene", ["shelf_boxes", "panda_cage"])
def test_local_clearance_bound_holds_along_the_motion(world_of, scene):
    """The dense walk's certificate from this configuration's distances to the joint axes
    (motion_bounds.clear_for, the lever bound left out): along the straight motion, the group's
    centre — and, with the group's radius, each of its spheres' centres — moves less than d
    for as many substeps as it says (up to 300), by forward kinematics at half substeps. It
    is longer than the lever bound's in most cases (else it would not be worth having)."""
    from chekhov.collision import motion_bounds

    w = world_of(scene)
    pk = w.fast.packed
    chain, groups, spheres = pk.chain, pk.groups, pk.spheres
    rng = np.random.default_rng(21)
    K, G = w.robot.dof, len(groups.radius)
    n = 101
    curve = np.empty((G, 2))
    longer = checked = 0
    for _ in range(8):
        q0 = w.robot.sample_uniform(rng, 1)[0]
        u = rng.normal(size=K) * rng.uniform(0.0, 1.0, K)   # some joints barely move
        q1 = q0 + 0.16 * u / np.linalg.norm(u)
        dq = np.abs(q1 - q0) / n
        Rc, pc = (np.ascontiguousarray(a) for a in w.fast.joint_placements(q0))
        gwc = np.einsum("gab,gb->ga", Rc[groups.joint], groups.centre) + pc[groups.joint]
        for g in range(G):
            motion_bounds.curvature(g, dq, chain.parent, groups.joint, groups.radius,
                                  groups.lever, curve)
            members = np.arange(groups.start[g], groups.start[g + 1])
            moving = np.zeros(K, dtype=bool)   # the joints that move the group
            i = int(groups.joint[g])
            while i >= 0:
                moving[i], i = True, int(chain.parent[i])
            for which, r in ((0, 0.0), (1, float(groups.radius[g]))):
                d = float(rng.uniform(0.002, 0.1))
                s = motion_bounds.clear_for(d, g, r, curve[g, which], np.inf, dq, chain.parent,
                                          groups.joint, chain.axis, Rc, pc, gwc)
                lever_step = float((dq * (groups.lever[g] + r) * moving).sum())
                longer += s > d / max(lever_step, 1e-300)
                checked += 1
                for t in np.linspace(0.0, min(s, 300), 2 * min(s, 300) + 1):
                    R, p = w.fast.joint_placements(q0 + t * (q1 - q0) / n)
                    if which == 0:
                        c = R[groups.joint[g]] @ groups.centre[g] + p[groups.joint[g]]
                        assert np.linalg.norm(c - gwc[g]) < d, (g, t, s)
                    else:
                        j = spheres.joint[members]
                        now = np.einsum("sab,sb->sa", R[j], spheres.centre[members]) + p[j]
                        then = np.einsum("sab,sb->sa", Rc[j], spheres.centre[members]) + pc[j]
                        assert np.linalg.norm(now - then, axis=1).max() < d, (g, t, s)
    assert longer > 0.5 * checked, (longer, checked)


def test_decided_motions_are_remembered_until_the_obstacles_change(world_of):
    """``first_free_motion`` answers from the checker's memo of motions it decided before (the
    kernel's answer, in candidate lists mixing remembered and new motions); a motion cut by
    the deadline is not remembered; changing the obstacles forgets every decision;
    ``motions_valid`` neither reads nor fills the memo."""
    from chekhov.collision import validity

    w = world_of("tabletop_pole")
    fast = w.fast
    Q = w.robot.sample_uniform(np.random.default_rng(31), 1500)
    Q = Q[fast.valid(Q)]
    A, B = Q[:160], Q[160:320]

    def kernel(P0, P1):
        return validity.motions_valid(P0, P1, 0.02, 0, 0, validity.NO_BUDGET, False,
                                      fast.packed)[0]

    def expect(free):
        return int(np.argmax(free)) if free.any() else None

    want = kernel(A, B)
    assert 10 <= want.sum() <= len(A) - 10
    hits = fast._motion_memo.hits
    np.testing.assert_array_equal(fast.motions_valid(A, B, 0.02), want)
    assert fast._motion_memo.hits == hits                      # not through the memo
    blocked, free = np.flatnonzero(~want)[:30], np.flatnonzero(want)[:1]
    pick = np.concatenate([blocked, free])                     # 30 blocked, then a free one
    assert fast.first_free_motion(A[pick], B[pick], 0.02) == 30
    assert fast.first_free_motion(A[pick], B[pick], 0.02) == 30
    assert fast._motion_memo.hits - hits == 31                 # all 31 remembered
    order = np.random.default_rng(5).permutation(len(A))       # remembered and new, mixed
    for k in range(0, 100, 3):
        assert fast.first_free_motion(A[order[k:]], B[order[k:]], 0.02) == \
            expect(want[order[k:]])
    C, D = Q[320:480], Q[480:640]
    cut = np.concatenate([np.flatnonzero(~kernel(C, D)), np.flatnonzero(kernel(C, D))])
    C, D = C[cut], D[cut]                                      # the blocked first
    # a deadline 0.1 ms away cuts the list after a few motions (budgeted calls of 16
    # configurations); those not decided count as blocked and are not remembered as such
    assert fast.first_free_motion(C, D, 0.02, deadline=time.perf_counter() + 1e-4) in (
        None, expect(kernel(C, D)))
    assert fast.first_free_motion(C, D, 0.02) == expect(kernel(C, D))
    # an obstacle on a free motion's path: the remembered "free" is forgotten
    i = int(free[0])
    n = int(np.ceil(np.linalg.norm(B[i] - A[i]) / 0.02))
    q_mid = A[i] + (n // 2) / n * (B[i] - A[i])
    T = np.eye(4)
    T[:3, 3] = fast.sphere_centers(q_mid)[-1]
    fast.add_obstacle("memo_probe", Shape("sphere", (0.05,)), T)
    try:
        assert fast.first_free_motion(A[i:i + 1], B[i:i + 1], 0.02) is None
    finally:
        fast.remove_obstacle("memo_probe")
    assert fast.first_free_motion(A[i:i + 1], B[i:i + 1], 0.02) == 0


def test_read_only_arrays_are_checked_by_the_writable_kernel_versions(world_of):
    """A read-only array (a timed trajectory's positions) gets the same answers as a writable
    one, and no kernel gets a version for read-only arrays: numba would load or compile it at
    its first call, mid-query (53 ms for the dense walk, measured)."""
    from chekhov.collision import dense_path, motion_bounds, validity
    from chekhov.collision.path_check import exact_path_decision

    w = world_of("tabletop_pole")
    rng = np.random.default_rng(31)
    Q = w.robot.sample_uniform(rng, 400)
    frozen = Q.copy()
    frozen.setflags(write=False)
    assert np.array_equal(w.fast.valid(frozen), w.fast.valid(Q))
    free = Q[w.fast.valid(Q)]
    assert len(free) >= 6
    blocked = Q[~w.fast.valid(Q) & ~w.exact.valid(Q)][0]
    answers = []
    for P in (free[0:3], free[3:6], np.vstack([free[0], blocked])):
        ro = P.copy()
        ro.setflags(write=False)
        answers.append(exact_path_decision(w.fast, w.exact, ro, 20).valid)
        assert answers[-1] == exact_path_decision(w.fast, w.exact, P, 20).valid
    assert answers[-1] is False
    for kernel in (validity.valid_batch, dense_path.first_dense_collision,
                   motion_bounds.decision_margins):
        assert not any("readonly" in str(t) for sig in kernel.signatures for t in sig), kernel
