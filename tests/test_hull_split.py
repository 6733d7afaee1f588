"""A mesh part whose hull is a poor fit is cut into convex pieces (``hull_split.split_part``):
the pieces' hulls together still hold every triangle and the solid they bound, and are
tighter — checked by point-in-hull tests and by coal's distances to the mesh itself."""

import itertools

import coal
import numpy as np
import pinocchio as pin
from scipy.spatial import ConvexHull

from chekhov import Robot
from chekhov.collision.codes import BOX, CYLINDER, HULL
from chekhov.collision.gjk import convex_collide
from chekhov.collision.hull_split import split_part
from chekhov.collision.packed import pack_world
from chekhov.collision.primitives import hull_parts, support_points
from chekhov.robot.description import example_robot_data_dir

MM = 1e-3
# the UR5 upper arm's shape: a tube of radius 50.5 mm between 57 mm flanges, 290 mm long
FLANGED_TUBE = [(0.0, 0.0), (57.0, 0.0), (57.0, 5.0), (50.5, 5.0), (50.5, 285.0),
                (57.0, 285.0), (57.0, 290.0), (0.0, 290.0)]


def _revolve(profile, sides=24):
    """A closed mesh (vertices (V, 3) m, triangles (F, 3)) turning the (r, z) mm profile about
    z; long thin triangles join consecutive rings, as in the UR5's own mesh."""
    ang = 2 * np.pi * np.arange(sides) / sides
    verts, rings = [], []
    for r, z in profile:
        if r == 0.0:
            rings.append([len(verts)] * sides)
            verts.append((0.0, 0.0, z * MM))
        else:
            rings.append(list(range(len(verts), len(verts) + sides)))
            verts += [(r * MM * np.cos(a), r * MM * np.sin(a), z * MM) for a in ang]
    tris = []
    for lo, hi in itertools.pairwise(rings):
        for i in range(sides):
            j = (i + 1) % sides
            tris += [(lo[i], lo[j], hi[j]), (lo[i], hi[j], hi[i])]
    tris = [t for t in tris if len(set(t)) == 3]
    return np.array(verts), np.array(tris, dtype=np.int64)


def _inside_any(pieces, X, tol=1e-9):
    inside = np.zeros(len(X), dtype=bool)
    for pts in pieces:
        eq = ConvexHull(pts).equations
        inside |= np.max(X @ eq[:, :3].T + eq[:, 3], axis=1) <= tol
    return inside


def _on_triangles(V, T, rng, per=20):
    A, B, C = (np.repeat(V[T[:, i]], per, axis=0) for i in range(3))
    u = rng.random((len(A), 2))
    flip = u.sum(axis=1) > 1
    u[flip] = 1 - u[flip]
    return A + u[:, :1] * (B - A) + u[:, 1:] * (C - A)


def test_a_flanged_tube_is_cut_at_its_flanges_and_the_pieces_hold_it():
    V, T = _revolve(FLANGED_TUBE)
    pieces = split_part(V, T)
    assert len(pieces) >= 3
    whole = ConvexHull(V).volume
    solid = np.pi * (57.0 ** 2 * 10 + 50.5 ** 2 * 280) * MM ** 3
    total = sum(ConvexHull(p).volume for p in pieces)
    assert whole > 1.2 * solid                       # one hull: 57 mm all along
    assert total < 1.03 * solid, total / solid
    rng = np.random.default_rng(0)
    assert _inside_any(pieces, _on_triangles(V, T, rng)).all()
    # the solid too (the pieces' cut faces close it): points inside the tube and flanges
    r = 50.0 * MM * np.sqrt(rng.random(4000))
    a = 2 * np.pi * rng.random(4000)
    z = 290.0 * MM * rng.random(4000)
    X = np.column_stack([r * np.cos(a), r * np.sin(a), z])
    assert _inside_any(pieces, X).all()


def test_a_convex_part_stays_whole():
    V, T = _revolve([(0.0, 0.0), (40.0, 0.0), (40.0, 120.0), (0.0, 120.0)])
    pieces = split_part(V, T)
    assert len(pieces) == 1
    assert np.array_equal(np.sort(support_points(pieces[0]), axis=0),
                          np.sort(support_points(V), axis=0))


def test_the_ur5_upper_arm_pieces_agree_with_coal_and_prove_more_than_one_hull():
    """convex_collide over the pieces says "apart" only where coal's distance between the
    mesh and the box is positive, and proves more of the boxes coal puts > 1 mm away than the
    hulls of the mesh's connected parts alone did."""
    share = example_robot_data_dir()
    path = str(share / "robots/ur_description/meshes/ur5/collision/upperarm.stl")
    geometry = coal.MeshLoader().load(path, np.ones(3))
    pieces = hull_parts(geometry)
    whole = hull_parts(geometry, max_pieces=1)   # the connected parts, as before the pieces
    verts = np.asarray(geometry.vertices(), dtype=float)
    assert len(pieces) > len(whole)
    rng = np.random.default_rng(7)
    half = np.array([0.05, 0.05, 0.01])
    box = coal.Box(*(2 * half))
    eye, zero = np.eye(3), np.zeros(3)
    lo, hi = verts.min(axis=0) - 0.06, verts.max(axis=0) + 0.06

    def hit(parts, R, p):
        return any(convex_collide(HULL, eye, zero, zero, P, 0, len(P), P.mean(axis=0),
                                  BOX, R, p, half, np.zeros((0, 3)), 0, 0, p, 1e-4)
                   for P in parts)

    apart = proved_pieces = proved_whole = 0
    for _ in range(1500):
        R = pin.exp3(rng.normal(size=3) * 0.3)
        p = rng.uniform(lo, hi)
        d = coal.distance(geometry, coal.Transform3s(), box, coal.Transform3s(R, p),
                          coal.DistanceRequest(), coal.DistanceResult())
        h = hit(pieces, R, p)
        if not h:
            assert d > 0, (R, p, d)                 # never "apart" when coal says touching
        if d > 1e-3:
            apart += 1
            proved_pieces += not h
            proved_whole += not hit(whole, R, p)
    assert apart >= 300, apart
    # measured: 584 and 536 of 590
    assert proved_pieces >= proved_whole + 0.04 * apart, (proved_pieces, proved_whole, apart)


def test_every_part_lies_inside_its_bounding_ball():
    """The confirmations skip a part whose ball (``GroupGeometry.part_radius`` about its
    centre) clears the other shape: every support point of a mesh part, and every corner of a
    box or cylinder group, must lie inside it (UR5: cut parts; Baxter: primitives)."""
    share = example_robot_data_dir()
    ur5 = Robot.from_urdf(share / "robots/ur_description/urdf/ur5_joint_limited_robot.urdf",
                          joints=["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
                                  "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"],
                          ee_frame="tool0", package_dirs=[share.parent])
    checked = 0
    for robot in (ur5, Robot.load("baxter_left")):
        geo = pack_world(robot, None).geometry
        for g, kind in enumerate(geo.kind):
            for k in range(geo.part_start[g], geo.part_start[g + 1]):
                pts = geo.verts[geo.vert_start[k]:geo.vert_start[k + 1]]
                if kind == BOX:
                    pts = np.array(list(itertools.product(*[(-h, h) for h in geo.size[g]])))
                elif kind == CYLINDER:
                    r, h = geo.size[g][:2]
                    a = np.linspace(0, 2 * np.pi, 64)
                    pts = np.array([(r * np.cos(t), r * np.sin(t), z) for t in a for z in (-h, h)])
                if len(pts):
                    d = np.linalg.norm(pts - geo.part_centre[k], axis=1)
                    assert d.max() <= geo.part_radius[k], (g, k, d.max(), geo.part_radius[k])
                    checked += 1
    assert checked >= 20, checked
