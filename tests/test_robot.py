import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from chekhov import IKError, Robot, RobotError, build_sphere_model, solve_ik
from chekhov.robot.spheres import cover_box, cover_cylinder


@pytest.fixture(scope="module")
def baxter() -> Robot:
    return Robot.load("baxter_left")


@pytest.fixture(scope="module", params=["baxter_left", "panda"])
def robot(request) -> Robot:
    """Each built-in robot: kinematics, Jacobians and IK are checked on both."""
    return Robot.load(request.param)


def test_group_limits_and_fixed_joints(baxter):
    assert baxter.dof == 7
    assert baxter.joint_names[0] == "left_s0" and baxter.joint_names[-1] == "left_w2"
    assert baxter.lower[3] == pytest.approx(-0.05) and baxter.upper[3] == pytest.approx(2.618)
    # the right arm is locked: its geometry is fixed in the world
    names = [g.name for g in baxter.collision_model.geometryObjects]
    right = names.index("right_wrist_0")
    assert baxter.collision_model.geometryObjects[right].parentJoint == 0


def test_base_pose_moves_everything(baxter):
    T = np.eye(4)
    T[:3, 3] = [1.0, 2.0, 0.5]
    moved = Robot.load("baxter_left", T_world_base=T @ baxter.T_world_base)
    q = np.linspace(-0.3, 0.4, 7)
    assert np.allclose(moved.compute_ee_pose(q), T @ baxter.compute_ee_pose(q))


def test_batched_fk_equals_looped(robot, rng):
    Q = robot.sample_uniform(rng, 20)
    batch = robot.compute_ee_poses(Q)
    assert np.allclose(batch, np.stack([robot.compute_ee_pose(q) for q in Q]))


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.floats(-20.0, 20.0), st.floats(-2e5, 2e5),
                 # the quadrants' edges, where the reduction changes k
                 st.builds(lambda k, e: k * np.pi / 4 + e, st.integers(-2000, 2000),
                           st.floats(-1e-9, 1e-9)),
                 st.sampled_from([0.0, -0.0, np.nan, np.inf, -np.inf, 1e300])))
def test_compiled_sincos_agrees_with_numpy(x):
    """The forward kinematics' own sine and cosine (a polynomial after reducing by pi/2) are
    numpy's to within 2 ulp of 1 over the whole range, and NaN where numpy's are."""
    from chekhov.robot.chain_kinematics import sincos

    s, c = sincos(x)
    with np.errstate(invalid="ignore"):
        wants = np.sin(x), np.cos(x)
    for got, want in zip((s, c), wants, strict=True):
        if np.isnan(want):
            assert np.isnan(got)
        else:
            assert abs(got - want) <= 2 * np.spacing(1.0), (x, got, want)


def test_compiled_fk_matches_pinocchio(robot, rng):
    """The compiled chain's end-effector poses (what the collision kernels, IK and TrajOpt's
    terms build on) are pinocchio's, at random configurations and at angles several turns
    out (a continuous joint's)."""
    from chekhov.robot.chain_kinematics import ChainKinematics

    kin = ChainKinematics.from_robot(robot)
    Q = robot.sample_uniform(rng, 200)
    Q[100:] += 2 * np.pi * rng.integers(-5, 6, size=(100, robot.dof))
    R, p = kin.ee_poses(Q)
    T = robot.compute_ee_poses(Q)
    np.testing.assert_allclose(R, T[:, :3, :3], atol=1e-12)
    np.testing.assert_allclose(p, T[:, :3, 3], atol=1e-12)


def test_frame_jacobian_matches_finite_differences(robot, rng):
    q = robot.sample_uniform(rng, 1)[0]
    J = robot.compute_frame_jacobian(q)
    eps = 1e-6
    T0 = robot.compute_ee_pose(q)
    for k in range(robot.dof):
        dq = np.zeros(robot.dof)
        dq[k] = eps
        T1 = robot.compute_ee_pose(q + dq)
        v_lin = (T1[:3, 3] - T0[:3, 3]) / eps
        w = pin.log3(T1[:3, :3] @ T0[:3, :3].T) / eps
        assert np.allclose(J[:3, k], v_lin, atol=1e-5)
        assert np.allclose(J[3:, k], w, atol=1e-5)


def test_wrong_joint_count_is_a_clear_error(baxter):
    with pytest.raises(RobotError, match="expected 7 joint values"):
        baxter.check_configuration(np.zeros(6))


def test_second_robot_through_the_same_path():
    panda = Robot.load("panda")
    assert panda.dof == 7
    spheres = build_sphere_model(panda)
    assert len(spheres) > 20 and set(spheres.joints.tolist()) <= set(range(7))


def _covered(points, centers, radii):
    d = np.linalg.norm(points[:, None, :] - centers[None], axis=2)
    return np.all((d <= radii[None] + 1e-12).any(axis=1))


def test_cylinder_and_box_covers_contain_their_surface(rng):
    for r, h in [(0.06, 0.136), (0.06, 0.05), (0.029, 0.05)]:
        c, rad = cover_cylinder(r, h, 0.15)
        a = rng.uniform(0, 2 * np.pi, 4000)
        z = rng.uniform(-h, h, 4000)
        pts = np.column_stack([r * np.cos(a), r * np.sin(a), z])
        caps = np.column_stack([np.sqrt(rng.uniform(0, 1, 1000)) * r * np.cos(a[:1000]),
                                np.sqrt(rng.uniform(0, 1, 1000)) * r * np.sin(a[:1000]),
                                np.where(rng.random(1000) < 0.5, -h, h)])
        assert _covered(np.vstack([pts, caps]), c, rad)
    half = np.array([0.005, 0.025, 0.0085])
    c, rad = cover_box(half, 0.15)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half
    assert _covered(np.vstack([corners, rng.uniform(-1, 1, (2000, 3)) * half]), c, rad)


@settings(max_examples=80, deadline=None)
@given(points=arrays(np.float64, st.tuples(st.integers(1, 60), st.just(3)),
                     elements=st.floats(-0.3, 0.3, allow_nan=False)))
def test_a_mesh_clusters_ball_contains_it_and_is_no_larger_than_the_box_centres(points):
    """enclosing_ball (each mesh cluster's sphere): every point inside it (checked by
    distance), its radius no larger than the ball about the bounding box's centre (the cover
    before 2026-11-29), and no smaller than half the points' largest pairwise distance (no ball
    holding them can be)."""
    from scipy.spatial.distance import pdist

    from chekhov.robot.spheres import enclosing_ball

    centre, radius = enclosing_ball(points)
    assert np.linalg.norm(points - centre, axis=1).max() <= radius + 1e-12
    mid = 0.5 * (points.min(axis=0) + points.max(axis=0))
    assert radius <= np.linalg.norm(points - mid, axis=1).max() + 1e-12
    if len(points) > 1:
        assert radius >= 0.5 * pdist(points).max() - 1e-12


def test_mesh_covers_are_tighter_than_the_box_centres():
    """The Panda's mesh spheres: 96 clusters, radii summing 5.9% below their bounding box
    centres' balls (measured; at least 3% asked), each cluster still covered (the covering
    tests above and below check that on the surfaces)."""
    from scipy.cluster.vq import kmeans2

    from chekhov.robot.spheres import cover_triangles, mesh_triangles

    robot = Robot.load("panda")
    before = after = 0.0
    for gi in robot.moving_geometries:
        geo = robot.collision_model.geometryObjects[gi].geometry
        if not hasattr(geo, "num_tris"):
            continue
        tri = mesh_triangles(geo)
        k = min(robot.description.spheres.mesh_spheres, len(tri))
        _, labels = kmeans2(tri.mean(axis=1), k, seed=0, minit="++")
        for c in range(k):
            pts = tri[labels == c].reshape(-1, 3)
            if len(pts):
                mid = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
                before += float(np.linalg.norm(pts - mid, axis=1).max())
        after += float(cover_triangles(tri, robot.description.spheres.mesh_spheres)[1].sum())
    assert after <= 0.97 * before, (after, before)


def test_split_triangles_keep_the_surface_in_short_triangles():
    """Every piece lies in its triangle (barycentric coordinates in [0, 1]), the pieces' area
    is the triangles', and no edge is longer than asked; 0 leaves the triangles alone."""
    from chekhov.robot.spheres import split_triangles

    rng = np.random.default_rng(3)
    tri = rng.uniform(-0.2, 0.2, (40, 3, 3))
    tri[0] = [[0, 0, 0], [0.5, 0, 0], [0, 0.001, 0]]        # a long sliver
    pieces = split_triangles(tri, 0.03)
    assert len(pieces) > 10 * len(tri)
    assert np.linalg.norm(pieces - np.roll(pieces, -1, axis=1), axis=2).max() <= 0.03

    def area(T):
        return 0.5 * np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1)

    assert abs(area(pieces).sum() - area(tri).sum()) <= 1e-9 * area(tri).sum()
    # each piece's corners, in barycentric coordinates of the one triangle that holds them
    for P in pieces[rng.choice(len(pieces), 300, replace=False)]:
        held = False
        for T in tri:
            M = np.stack([T[1] - T[0], T[2] - T[0]], axis=1)
            uv, *_ = np.linalg.lstsq(M, (P - T[0]).T, rcond=None)
            inside = (np.abs(M @ uv - (P - T[0]).T).max() < 1e-12 and (uv >= -1e-9).all()
                      and (uv.sum(axis=0) <= 1 + 1e-9).all())
            held = held or inside
        assert held
    assert np.array_equal(split_triangles(tri, 0.0), tri)


def test_split_triangles_stop_at_their_bound(monkeypatch):
    """A limit far below the triangles' size stops at ``SPLIT_MAX_TRIANGLES``: the triangles
    still too long are kept whole, the surface (area) the same."""
    import chekhov.robot.spheres as spheres

    monkeypatch.setattr(spheres, "SPLIT_MAX_TRIANGLES", 1000)
    tri = np.array([[[0, 0, 0], [1.0, 0, 0], [0, 1.0, 0]]])
    pieces = spheres.split_triangles(tri, 1e-9)
    assert 500 <= len(pieces) <= 1000
    area = 0.5 * np.linalg.norm(np.cross(pieces[:, 1] - pieces[:, 0],
                                         pieces[:, 2] - pieces[:, 0]), axis=1).sum()
    assert abs(area - 0.5) < 1e-12


@pytest.mark.parametrize("spheres, says", [
    ({"mesh_split": "abc"}, "'mesh_split' must be a finite number >= 0"),
    ({"mesh_split": -0.1}, "'mesh_split' must be a finite number >= 0"),
    ({"max_excess": 0}, "'max_excess' must be a finite number > 0"),
    ({"mesh_spheres": 2.5}, "'mesh_spheres' must be an integer >= 1"),
    ({"bogus": 1}, r"unknown key\(s\) \['bogus'\]"),
    ([1], "expected a mapping"),
])
def test_bad_sphere_settings_are_located_errors(spheres, says):
    from chekhov.robot.description import RobotDescription

    d = {"name": "x", "urdf": "u.urdf", "group_joints": ["a"], "ee_frame": "e",
         "spheres": spheres}
    with pytest.raises(RobotError, match="robot.yaml: field 'spheres': " + says):
        RobotDescription.from_dict(d, "robot.yaml")
    d["spheres"] = {"mesh_split": 0.05, "mesh_spheres": 8}
    assert RobotDescription.from_dict(d, "robot.yaml").spheres.mesh_split == 0.05


def test_split_mesh_covers_are_tighter():
    """The Panda's mesh spheres from split triangles: radii summing at least 20% below those
    of the whole triangles' clusters (measured 27%: 5.95 → 4.34 m over its 8 meshes; a
    cluster holding a long triangle needs a ball as long as it). Both cover the surface (the
    covering test below)."""
    from chekhov.robot.spheres import cover_geometry

    robot = Robot.load("panda")
    s = robot.description.spheres
    whole = split = 0.0
    for gi in robot.moving_geometries:
        geo = robot.collision_model.geometryObjects[gi].geometry
        if hasattr(geo, "num_tris"):
            whole += float(cover_geometry(geo, s.max_excess, s.mesh_spheres,
                                          mesh_split=0.0)[1].sum())
            split += float(cover_geometry(geo, s.max_excess, s.mesh_spheres)[1].sum())
    assert split <= 0.8 * whole, (split, whole)


def _surface_points(geo, rng, n=600):
    """Points on a coal shape's surface (its own frame): cylinder rims, caps and side; box
    corners, edges and faces; sphere and capsule surfaces; for a mesh every vertex and 4
    random (barycentric) points on every triangle."""
    import coal

    from chekhov.robot.spheres import mesh_arrays, mesh_triangles

    if isinstance(geo, coal.Cylinder):
        a = rng.uniform(0, 2 * np.pi, n)
        r = np.where(rng.random(n) < 0.5, geo.radius, geo.radius * np.sqrt(rng.random(n)))
        z = np.where(r == geo.radius, rng.uniform(-1, 1, n), rng.choice([-1, 1], n))
        return np.column_stack([r * np.cos(a), r * np.sin(a), z * geo.halfLength])
    if isinstance(geo, coal.Box):
        u = rng.uniform(-1, 1, (n, 3))
        face = rng.integers(0, 3, n)
        u[np.arange(n), face] = rng.choice([-1, 1], n)
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        return np.vstack([corners, u]) * np.asarray(geo.halfSide)
    if isinstance(geo, coal.Sphere):
        v = rng.normal(size=(n, 3))
        return geo.radius * v / np.linalg.norm(v, axis=1, keepdims=True)
    if isinstance(geo, coal.Capsule):
        v = rng.normal(size=(n, 3))
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        a = rng.uniform(0, 2 * np.pi, n)
        side = np.column_stack([geo.radius * np.cos(a), geo.radius * np.sin(a),
                                rng.uniform(-geo.halfLength, geo.halfLength, n)])
        ends = geo.radius * v + np.where(v[:, 2:] > 0, 1, -1) * [0, 0, geo.halfLength]
        return np.vstack([side, ends])
    verts, _ = mesh_arrays(geo)                             # every vertex, (V, 3)
    tris = mesh_triangles(geo)                              # (F, 3, 3)
    w = rng.dirichlet(np.ones(3), size=(len(tris), 4))      # 4 points on every triangle
    return np.vstack([verts, np.einsum("fkc,fcx->fkx", w, tris).reshape(-1, 3)])


@pytest.mark.parametrize("name", ["baxter_left", "panda"])
def test_sphere_model_covers_robot_geometry(name, rng):
    """Every moving collision geometry — cylinders, boxes and meshes — lies inside the union of
    its spheres: every mesh vertex and points on every triangle, rims, corners and faces. The
    fast checker is conservative only because of this (a sphere miss is a certain miss)."""
    robot = Robot.load(name)
    sm = build_sphere_model(robot)
    # the spheres stand for exactly the moving geometries (the fixed ones, Baxter's locked
    # right arm and torso, are in the fast checker's distance grids instead)
    moving = set(robot.moving_geometries)
    assert set(sm.geometries.tolist()) == moving
    geoms = robot.collision_model.geometryObjects
    assert np.array_equal(sm.joints, [geoms[int(gi)].parentJoint - 1 for gi in sm.geometries])
    kinds = set()
    for gi in robot.moving_geometries:
        g = geoms[gi]
        kinds.add(type(g.geometry).__name__)
        pts = _surface_points(g.geometry, rng) @ g.placement.rotation.T + g.placement.translation
        mine = sm.geometries == gi
        d = np.linalg.norm(pts[:, None, :] - sm.centers[mine][None], axis=2) - sm.radii[mine]
        outside = d.min(axis=1)
        assert outside.max() <= 1e-9, (g.name, float(outside.max()))
    assert kinds >= ({"BVHModelOBBRSS"} if name == "panda" else {"Cylinder", "Box"}), kinds


@pytest.mark.parametrize("name", ["baxter_left", "panda"])
def test_every_collision_shape_is_covered_by_its_spheres(name, rng):
    """cover_geometry on every collision geometry of the robot, fixed ones included (Baxter's
    meshes and spheres are all fixed), and on a capsule, which neither robot has: every
    surface point (every mesh vertex, points on every triangle) lies in a sphere."""
    import coal

    from chekhov.robot.spheres import cover_geometry

    robot = Robot.load(name)
    shapes = [(g.name, g.geometry) for g in robot.collision_model.geometryObjects]
    shapes += [("capsule", coal.Capsule(0.05, 0.3)), ("short capsule", coal.Capsule(0.05, 0.01))]
    for label, geo in shapes:
        for max_excess, mesh_spheres in ((0.15, 10), (0.01, 3)):
            c, r = cover_geometry(geo, max_excess, mesh_spheres)
            pts = _surface_points(geo, rng)
            outside = (np.linalg.norm(pts[:, None, :] - c[None], axis=2) - r).min(axis=1)
            assert outside.max() <= 1e-9, (label, max_excess, float(outside.max()))


def test_ik_reaches_pose_and_gives_distinct_solutions(robot, rng):
    q = np.clip(np.array([0.2, -0.4, 0.1, 1.0, 0.2, 0.6, -0.3]), robot.lower + 0.1,
                robot.upper - 0.1)
    T = robot.compute_ee_pose(q)
    sols = solve_ik(robot, T, 3, rng=rng)
    assert 1 <= len(sols) <= 3
    for s in sols:
        assert robot.within_limits(s)[0]
        Ts = robot.compute_ee_pose(s)
        assert np.linalg.norm(Ts[:3, 3] - T[:3, 3]) < 2e-4
        assert np.linalg.norm(pin.log3(Ts[:3, :3].T @ T[:3, :3])) < 2e-3
    for i in range(len(sols)):
        for j in range(i):
            assert np.linalg.norm(sols[i] - sols[j]) >= 0.1


def test_ik_unreachable_pose_is_a_clear_error(baxter):
    T = np.eye(4)
    T[:3, 3] = [3.0, 0.0, 1.0]
    with pytest.raises(IKError, match="beyond the arm's reach"):
        solve_ik(baxter, T)


def test_ik_accept_filter_rejects(baxter, rng):
    T = baxter.compute_ee_pose(np.full(7, 0.3))
    with pytest.raises(IKError, match="rejected"):
        solve_ik(baxter, T, accept=lambda q: False, rng=rng)
