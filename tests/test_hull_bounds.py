"""Hull bounds for large meshes (collision/hull_bounds.py): on a Kinova Jaco, whose collision
meshes are its visual ones (1,500-45,000 triangles a link), the hulls' distance never exceeds
coal's distance between the meshes, and the exact checker's answers that use it agree with
coal's mesh distances; the Panda's small meshes get no hulls."""

import numpy as np
import pinocchio as pin

from chekhov import Robot, World, load_scene
from chekhov.collision.hull_bounds import TRUSTED_BOUND_M
from chekhov.robot.description import example_robot_data_dir

SHARE = example_robot_data_dir()
KINOVA = SHARE / "robots/kinova_description"


def _jaco_world() -> World:
    robot = Robot.from_urdf(KINOVA / "robots/kinova.urdf", srdf=KINOVA / "srdf/kinova.srdf",
                            joints=[f"j2s6s200_joint_{i}" for i in range(1, 7)],
                            ee_frame="j2s6s200_end_effector", package_dirs=[SHARE.parent])
    scene = load_scene("tabletop_pole")
    return World(scene, robot)


def _mesh_distances(exact, q):
    """coal's distance of every collision pair at q, on the URDF's meshes."""
    gd = pin.GeometryData(exact.geom_model)
    pin.updateGeometryPlacements(exact.model, exact.model.createData(), exact.geom_model, gd, q)
    return np.array([pin.computeDistance(exact.geom_model, gd, k).min_distance
                     for k in range(len(exact.collision_pairs))])


def test_hull_bounds_are_lower_bounds_and_decisions_stay_the_meshes():
    world = _jaco_world()
    exact = world.exact
    hulls = exact._hulls
    assert len(hulls.hulls) >= 8       # every Jaco link mesh has ≥ 1,500 triangles
    covered = exact._hull_pairs
    assert covered.all()
    margins = np.full(len(covered), 0.05)
    qs = world.robot.sample_uniform(np.random.default_rng(3), 5)
    seen_close = seen_far = 0
    for q in qs:
        d = _mesh_distances(exact, q)
        gd = exact._place(q)
        lb = hulls.lower_bounds(exact.geom_model, gd, exact.collision_pairs)
        assert np.all(lb <= d + 1e-9)
        got = exact.pair_distances(q, np.arange(len(d)))
        assert np.all(got <= d + 1e-9)
        exact_where = got < TRUSTED_BOUND_M
        assert np.allclose(got[exact_where], d[exact_where], atol=1e-9)
        close = set(exact.pairs_within(q, margins).tolist())
        assert {k for k in range(len(d)) if d[k] < 0.05 - 1e-6} <= close
        assert close <= {k for k in range(len(d)) if d[k] < 0.05 + 1e-6}
        seen_close += len(close)
        seen_far += int((lb >= 0.05).sum())
    assert seen_close > 0 and seen_far > 0   # both branches were taken


def test_small_meshes_get_no_hulls():
    world = World.load("panda_table_shelf")
    assert not world.exact._hulls
