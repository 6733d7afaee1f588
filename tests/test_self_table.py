"""Self-collision tables (``collision/self_table.py``): the gap bound a table holds for a cell
never exceeds the distance between the two link meshes anywhere in the cell (measured by
coal on the meshes, not by the GJK bound the table was built from), nor falls far below the
distance between the covered geometries (coal on their hulls and boxes), and the fast checker
with the tables gives the answers it gives without them, except where it now proves a pair
apart that the exact checker also calls free."""

import coal
import numpy as np
import pinocchio as pin
import pytest

from chekhov import Robot, World
from chekhov.collision.codes import BOX, HULL
from chekhov.collision.self_table import QUANTUM_M, no_tables, table_gap
from chekhov.collision.validity import valid_batch
from chekhov.robot.chain_kinematics import chain_fk
from chekhov.scene.io import scene_from_dict

FINGERS = {"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04}


@pytest.fixture(scope="module", params=["panda", "baxter_left"])
def world(request):
    if request.param == "panda":
        robot = Robot.load("panda", locked=FINGERS)
    else:
        robot = Robot.load("baxter_left")
    scene = scene_from_dict({"format": 1, "name": "empty", "robot": request.param,
                             "objects": []})
    return World(scene, robot)


def _pair_distances(w, q, pairs):
    """Coal's distance (m) between the meshes of each (geometry, geometry) pair at q."""
    robot = w.robot
    gm, gd = robot.collision_model, pin.GeometryData(robot.collision_model)
    data = robot.model.createData()
    pin.updateGeometryPlacements(robot.model, data, gm, gd, q)
    out = []
    for a, b in pairs:
        req, res = coal.DistanceRequest(), coal.DistanceResult()
        coal.distance(gm.geometryObjects[a].geometry, gd.oMg[a],
                      gm.geometryObjects[b].geometry, gd.oMg[b], req, res)
        out.append(res.min_distance)
    return np.array(out)


def _tabled(w):
    p = w.fast.packed
    geoms = list(dict.fromkeys(w.fast.spheres.geometries.tolist()))
    idx = np.flatnonzero(p.self_tables.pair >= 0)
    pairs = [(geoms[a], geoms[b]) for a, b in p.groups.self_pairs[idx]]
    return p, idx, pairs


def test_tables_cover_the_wrist_pairs(world):
    p, idx, _ = _tabled(world)
    assert len(idx) >= 1, "a wrist pair one or two joints apart gets a table"
    st = p.self_tables
    used = [st.gap[t] if st.joint[t, 1] >= 0 else st.gap[t, :, :1] for t in range(len(st.gap))]
    assert np.mean([(g > 0).mean() for g in used]) > 0.5, "most cells are proved apart"


def test_table_bound_below_mesh_distance(world):
    p, idx, pairs = _tabled(world)
    st = p.self_tables
    rng = np.random.default_rng(3)
    Q = world.robot.sample_uniform(rng, 400)
    close = 0
    for q in Q:
        d = _pair_distances(world, q, pairs)
        for k, i in enumerate(idx):
            g = table_gap(q, i, st.pair, st.joint, st.lo, st.inv_w, st.gap)
            assert g >= 0.0
            # the bound holds for the meshes (contained in the hulls the table measured);
            # 0 proves nothing (confirmation margins are positive)
            assert g == 0.0 or g <= d[k] + 1e-9, (q, i, g, d[k])
            close += int(d[k] < 0.05)
    if world.robot.name == "panda":     # Baxter's tabled pairs are never this close
        assert close >= 20, "the sample reaches near-contact cells"


def test_tables_change_only_proved_answers(world):
    p, _, _ = _tabled(world)
    bare = p._replace(self_tables=no_tables(len(p.self_tables.pair),
                                               len(p.self_tables.group)))
    rng = np.random.default_rng(5)
    Q = world.robot.sample_uniform(rng, 3000)
    with_t, without = valid_batch(Q, p), valid_batch(Q, bare)
    assert not np.any(~with_t & without), "a table only ever proves a pair apart"
    changed = with_t & ~without
    assert world.exact.valid(Q[changed]).all()


def _covered_shapes(p, g):
    """Coal shapes of group g's covered parts, each with its pose in the group's geometry
    frame (hulls as convex shapes of their support points, boxes as boxes)."""
    geo = p.geometry
    if geo.kind[g] == BOX:
        return [coal.Box(*(2 * geo.size[g]))]
    assert geo.kind[g] == HULL
    out = []
    for k in range(geo.part_start[g], geo.part_start[g + 1]):
        points = coal.StdVec_Vec3s()
        points.extend(list(geo.verts[geo.vert_start[k]:geo.vert_start[k + 1]]))
        out.append(coal.Convex.convexHull(points, False, ""))
    return out


@pytest.fixture(scope="module")
def panda_world():
    scene = scene_from_dict({"format": 1, "name": "empty", "robot": "panda", "objects": []})
    return World(scene, Robot.load("panda", locked=FINGERS))


def test_table_proves_apart_what_is_apart_by_more_than_a_cell(panda_world):
    """Where the Panda's link 5 and fingers are apart by more than the two motion bounds of
    a cell (about 1 cm each) and a quantum, by coal on the geometries the table was built
    from, the table proves them apart, and never further than they are (until 2026-12-02
    GJK stopped at its first point of A − B near the origin, and near cells held 0 where the
    parts were 2-6 cm apart)."""
    world = panda_world      # Baxter's tabled pairs are never this near
    p, idx, _ = _tabled(world)
    st, geo = p.self_tables, p.geometry
    robot = world.robot
    chain_R, chain_p = np.empty((robot.dof, 3, 3)), np.empty((robot.dof, 3))
    shapes = {int(g): _covered_shapes(p, g) for i in idx for g in p.groups.self_pairs[i]}
    rng = np.random.default_rng(8)
    near = 0
    for q in robot.sample_uniform(rng, 150):
        chain_fk(q, p.chain, chain_R, chain_p)
        for i in idx:
            a, b = p.groups.self_pairs[i]
            poses = []
            for g in (a, b):
                j = p.groups.joint[g]
                poses.append(coal.Transform3s(chain_R[j] @ geo.R[g],
                                              chain_R[j] @ geo.p[g] + chain_p[j]))
            d = min(_coal_distance(sa, poses[0], sb, poses[1])
                    for sa in shapes[int(a)] for sb in shapes[int(b)])
            g = table_gap(q, i, st.pair, st.joint, st.lo, st.inv_w, st.gap)
            assert g <= max(d, 0.0) + 1e-6, (q, i, g, d)
            if 0.024 + QUANTUM_M < d < 0.2:
                near += 1
                assert g > 0.0, (q, i, d)
    assert near >= 100


def _coal_distance(a, Ta, b, Tb):
    req, res = coal.DistanceRequest(), coal.DistanceResult()
    coal.distance(a, Ta, b, Tb, req, res)
    return res.min_distance


def test_a_fixed_parts_table_bound_is_below_the_mesh_distances(world):
    """A group that one or two joints move gets a table against the fixed parts it is
    checked with (Baxter's shoulder links beside its torso and head; none on the Panda, whose
    SRDF leaves its first links unchecked against its base): its bound at q never exceeds
    coal's distance between the link's mesh and any of those parts' meshes, and it proves
    most configurations apart."""
    p = world.fast.packed
    st, robot = p.self_tables, world.robot
    tabled = np.flatnonzero(st.group >= 0)
    if robot.name == "panda":
        assert len(tabled) == 0
        return
    assert len(tabled) >= 2
    geoms = list(dict.fromkeys(world.fast.spheres.geometries.tolist()))
    moving = set(robot.moving_geometries)
    against = {int(g): [f for a, b in robot.self_collision_pairs for f in (a, b)
                        if geoms[g] in (a, b) and f != geoms[g] and f not in moving]
               for g in tabled}
    assert all(against.values())
    proved = 0
    for q in robot.sample_uniform(np.random.default_rng(4), 300):
        for g in tabled:
            bound = table_gap(q, g, st.group, st.joint, st.lo, st.inv_w, st.gap)
            d = _pair_distances(world, q, [(geoms[g], f) for f in against[int(g)]]).min()
            assert bound == 0.0 or bound <= d + 1e-9, (q, g, bound, d)
            proved += bound > 0.0
    assert proved >= 0.5 * 300 * len(tabled)
