import numpy as np
import pinocchio as pin
import pytest

from chekhov import IKError, Robot, RobotError, build_sphere_model, solve_ik
from chekhov.robot.spheres import cover_box, cover_cylinder


@pytest.fixture(scope="module")
def baxter() -> Robot:
    return Robot.load("baxter_left")


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


def test_batched_fk_equals_looped(baxter, rng):
    Q = baxter.sample_uniform(rng, 20)
    batch = baxter.compute_ee_poses(Q)
    assert np.allclose(batch, np.stack([baxter.compute_ee_pose(q) for q in Q]))


def test_frame_jacobian_matches_finite_differences(baxter, rng):
    q = baxter.sample_uniform(rng, 1)[0]
    J = baxter.compute_frame_jacobian(q)
    eps = 1e-6
    T0 = baxter.compute_ee_pose(q)
    for k in range(7):
        dq = np.zeros(7)
        dq[k] = eps
        T1 = baxter.compute_ee_pose(q + dq)
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


def test_sphere_model_covers_robot_geometry(baxter, rng):
    """Points on every moving collision cylinder / box lie inside that geometry's spheres."""
    import coal

    sm = build_sphere_model(baxter)
    for gi in baxter.moving_geometries:
        g = baxter.collision_model.geometryObjects[gi]
        geo = g.geometry
        if isinstance(geo, coal.Cylinder):
            a = rng.uniform(0, 2 * np.pi, 500)
            local = np.column_stack([geo.radius * np.cos(a), geo.radius * np.sin(a),
                                     rng.choice([-1, 1], 500) * geo.halfLength])
        elif isinstance(geo, coal.Box):
            local = rng.choice([-1, 1], (500, 3)) * np.asarray(geo.halfSide)
        else:
            continue
        pts = local @ g.placement.rotation.T + g.placement.translation
        mine = sm.geometries == gi
        assert _covered(pts, sm.centers[mine], sm.radii[mine]), g.name


def test_ik_reaches_pose_and_gives_distinct_solutions(baxter, rng):
    q = np.array([0.2, -0.4, 0.1, 1.0, 0.2, 0.6, -0.3])
    T = baxter.compute_ee_pose(q)
    sols = solve_ik(baxter, T, 3, rng=rng)
    assert 1 <= len(sols) <= 3
    for s in sols:
        assert baxter.within_limits(s)[0]
        Ts = baxter.compute_ee_pose(s)
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
