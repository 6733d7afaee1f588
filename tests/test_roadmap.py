"""The roadmap (issue 4): build, k shortest paths, save/load, queries, dynamic obstacles, CLI."""

from __future__ import annotations

import dataclasses
import itertools
import json

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from chekhov.cli import main
from chekhov.collision.fast import FastChecker
from chekhov.roadmap.build import build_roadmap
from chekhov.roadmap.config import RoadmapConfig
from chekhov.roadmap.errors import RoadmapError, RoadmapMismatchError
from chekhov.roadmap.io import load_or_build_roadmap, load_roadmap, save_roadmap
from chekhov.roadmap.kpaths import KShortestPaths
from chekhov.roadmap.search import csr_adjacency, yen_k_shortest
from chekhov.roadmap.seeder import RoadmapSeeder
from chekhov.robot.chain_kinematics import ChainKinematics
from chekhov.robot.goal import Goal
from chekhov.scene.model import Shape

SCENE = "tabletop_pole"
SMALL = RoadmapConfig(n_nodes=150, n_region_nodes=20, n_wrist_nodes=60, seed=3)


@pytest.fixture(scope="module")
def world(world_of):
    return world_of(SCENE)


@pytest.fixture(scope="module")
def roadmap(world):
    return build_roadmap(world, SMALL)


@pytest.fixture(scope="module")
def seeder(world, roadmap):
    return RoadmapSeeder(world, roadmap)


def _free_configurations(world, n, seed):
    rng = np.random.default_rng(seed)
    Q = world.robot.sample_uniform(rng, 20 * n)
    return Q[world.fast.valid(Q)][:n]


# --- k shortest paths ---------------------------------------------------------------------
def _all_simple_paths(adj, src, dst):
    out, stack = [], [(src, [src])]
    while stack:
        u, path = stack.pop()
        if u == dst:
            out.append(path)
            continue
        for v in adj[u]:
            if v not in path:
                stack.append((v, [*path, v]))
    return out


def test_yen_matches_brute_force_enumeration():
    rng = np.random.default_rng(0)
    N = 8
    pairs = [(a, b) for a, b in itertools.combinations(range(N), 2) if rng.random() < 0.5]
    edges = np.array(pairs, dtype=np.int64)
    w = rng.uniform(0.5, 2.0, len(edges)).round(3)  # distinct sums almost surely
    indptr, indices, weights, eid = csr_adjacency(N, edges, w)
    adj = {i: [] for i in range(N)}
    length = {}
    for (a, b), c in zip(pairs, w, strict=True):
        adj[a].append(b)
        adj[b].append(a)
        length[(a, b)] = length[(b, a)] = c
    for src, dst in [(0, N - 1), (1, 5), (2, 6)]:
        brute = sorted((sum(length[e] for e in itertools.pairwise(p)), p)
                       for p in _all_simple_paths(adj, src, dst))
        for k in (1, 3, 6):
            got = yen_k_shortest(indptr, indices, weights, eid, src, dst, k)
            assert len(got) == min(k, len(brute))
            for (c, p), (cb, pb) in zip(got, brute, strict=False):
                assert c == pytest.approx(cb)
                assert p.tolist() == pb


def test_k_shortest_on_roadmap_are_loopless_and_sorted(roadmap):
    kp = KShortestPaths(roadmap, k=3)
    a, b = 0, roadmap.n_nodes - 1
    paths = kp.paths(a, b)
    assert 1 <= len(paths) <= 3
    assert paths[0].tolist() == roadmap.shortest_path(a, b).tolist()
    costs = [np.linalg.norm(np.diff(roadmap.nodes[p], axis=0), axis=1).sum() for p in paths]
    assert costs == sorted(costs)
    assert all(len(set(p.tolist())) == len(p) for p in paths)
    assert kp.paths(b, a)[0].tolist() == paths[0][::-1].tolist()


# --- build --------------------------------------------------------------------------------
def test_build_every_node_and_edge_free_and_paths_match_scipy(world, roadmap):
    fast = FastChecker(world.robot, world.scene, static_only=True)
    rm = roadmap
    assert rm.meta.node_counts["uniform"] > 100 and rm.meta.node_counts["wrist"] > 0
    assert fast.valid(rm.nodes).all()
    e = rm.edges
    assert fast.motions_valid(rm.nodes[e[:, 0]], rm.nodes[e[:, 1]], SMALL.resolution).all()
    assert np.isfinite(rm.dist).all()  # pruned to one component
    uniform = rm.nodes_of_kind("uniform")
    P = world.robot.description.proximal_joints
    assert np.allclose(rm.nodes[uniform, P:], world.robot.description.roadmap_fixed)
    A = coo_matrix((rm.edge_length, (e[:, 0], e[:, 1])), shape=(rm.n_nodes,) * 2)
    rng = np.random.default_rng(1)
    for a, b in rng.integers(0, rm.n_nodes, size=(20, 2)):
        ref = dijkstra(A, directed=False, indices=int(a))[b]
        path = rm.shortest_path(int(a), int(b))
        assert path[0] == a and path[-1] == b
        length = np.linalg.norm(np.diff(rm.nodes[path], axis=0), axis=1).sum()
        assert length == pytest.approx(ref, rel=1e-9, abs=1e-9)
        assert rm.dist[a, b] == pytest.approx(ref, rel=1e-5)
    R, p = ChainKinematics.from_robot(world.robot).ee_poses(rm.nodes[:5])
    T = world.robot.compute_ee_poses(rm.nodes[:5])
    assert np.allclose(R, T[:, :3, :3]) and np.allclose(p, T[:, :3, 3])
    assert np.allclose(p, rm.ee_position[:5])


def test_numba_ik_reaches_the_pose(world):
    kin = ChainKinematics.from_robot(world.robot)
    Q = _free_configurations(world, 10, 5)
    T = world.robot.compute_ee_poses(Q)
    rng = np.random.default_rng(2)
    for q, Tq in zip(Q, T, strict=True):
        sol, ok = kin.solve(Tq, q + rng.normal(0, 0.2, len(q)))
        if ok[0]:
            Ts = world.robot.compute_ee_pose(sol[0])
            assert np.linalg.norm(Ts[:3, 3] - Tq[:3, 3]) < 2e-4
            assert world.robot.within_limits(sol)[0]


# --- files --------------------------------------------------------------------------------
def test_save_load_identical(tmp_path, world, roadmap):
    path = save_roadmap(roadmap, tmp_path / "rm.npz")
    back = load_roadmap(path, world)
    for f in dataclasses.fields(roadmap):
        if f.name != "meta":
            a, b = getattr(roadmap, f.name), getattr(back, f.name)
            assert a.dtype == b.dtype and np.array_equal(a, b), f.name
    assert back.meta == roadmap.meta
    assert not list(tmp_path.glob(".rm.npz.*"))  # no temporary left behind


def test_loading_for_another_scene_or_newer_version_raises(tmp_path, world, roadmap):
    path = save_roadmap(roadmap, tmp_path / "rm.npz")
    other_scene = dataclasses.replace(world.scene, name="moved", objects=world.scene.objects[1:])
    from chekhov.world import World
    other = World(other_scene, robot=world.robot)
    with pytest.raises(RoadmapMismatchError, match=r"rm\.npz.*scene 'tabletop_pole'"):
        load_roadmap(path, other)
    with pytest.raises(RoadmapMismatchError):
        RoadmapSeeder(other, roadmap)
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["meta_json"]))
    meta["format_version"] = 99
    arrays["meta_json"] = np.array(json.dumps(meta))
    np.savez(tmp_path / "new.npz", **arrays)
    with pytest.raises(RoadmapMismatchError, match=r"new\.npz.*version 99"):
        load_roadmap(tmp_path / "new.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(RoadmapError, match=r"junk\.npz"):
        load_roadmap(tmp_path / "junk.npz")


def test_edges_pass_the_certification_of_an_answer(world, roadmap):
    """Every edge passes the check an answer's segment faces (built with ``certify_edges``):
    here re-checked by coal alone on 40 edges, configuration by configuration, 0.0008 rad
    apart (half the certification's spacing). A file from before the field reads False, so
    its roadmap is rebuilt."""
    from chekhov.collision.exact import ExactChecker
    from chekhov.paths import resample_path
    assert SMALL.certify_edges and "edges_failing_certification" in roadmap.meta.notes
    exact = ExactChecker(world.robot, world.scene)
    rng = np.random.default_rng(5)
    for e in rng.choice(len(roadmap.edges), 40, replace=False):
        a, b = roadmap.nodes[roadmap.edges[e]]
        D = resample_path(np.stack([a, b]), 0.0008)
        assert exact.valid(D).all(), f"edge {e}"
    old = {k: v for k, v in SMALL.to_dict().items() if k != "certify_edges"}
    assert RoadmapConfig.from_dict(old).certify_edges is False


def test_load_or_build_reuses_a_matching_file(tmp_path, world):
    cfg = RoadmapConfig(n_nodes=40, semantic=False, n_wrist_nodes=0, seed=1)
    a = load_or_build_roadmap(world, cfg, tmp_path / "x.npz")
    b = load_or_build_roadmap(world, cfg, tmp_path / "x.npz")
    assert b.meta.created == a.meta.created and np.array_equal(a.nodes, b.nodes)
    c = load_or_build_roadmap(world, dataclasses.replace(cfg, seed=2), tmp_path / "x.npz")
    assert not np.array_equal(c.nodes, a.nodes)


def test_another_robot_in_a_scene_keeps_its_own_default_roadmap(tmp_path, world, monkeypatch):
    """The default file is the scene's for its own robot and the scene's and robot's for
    another, so two arms in one scene do not rebuild over each other's roadmap."""
    from chekhov import Robot, World
    from chekhov.roadmap.io import world_roadmap_path

    monkeypatch.setenv("CHEKHOV_CACHE_DIR", str(tmp_path))
    panda = World(world.scene, Robot.load("panda"))
    own, other = world_roadmap_path(world), world_roadmap_path(panda)
    assert own == tmp_path / "roadmaps" / f"{world.scene.name}.npz"
    assert other == tmp_path / "roadmaps" / f"{world.scene.name}@panda.npz"
    cfg = RoadmapConfig(n_nodes=30, semantic=False, n_wrist_nodes=0, seed=1)
    a = load_or_build_roadmap(world, cfg)
    b = load_or_build_roadmap(panda, cfg)
    assert own.is_file() and other.is_file()
    assert load_or_build_roadmap(world, cfg).meta.created == a.meta.created   # not rebuilt
    assert b.meta.robot == "panda" and a.meta.robot == world.robot.name


def test_a_robot_with_every_joint_sampled_gets_no_wrist_copies(tmp_path, world):
    """Wrist nodes redraw the distal joints; with none (every joint sampled, as a URDF robot's
    default) they were duplicates of uniform nodes, whose self-loop edges the saved file's
    check refused on loading."""
    cfg = RoadmapConfig(n_nodes=60, semantic=False, n_wrist_nodes=50, proximal_joints=7,
                        distal_values=(), seed=1)
    roadmap = build_roadmap(world, cfg)
    assert roadmap.meta.node_counts.get("wrist", 0) == 0
    assert (roadmap.edges[:, 0] < roadmap.edges[:, 1]).all()
    back = load_roadmap(save_roadmap(roadmap, tmp_path / "all.npz"), world)
    assert np.array_equal(back.edges, roadmap.edges)


# --- queries ------------------------------------------------------------------------------
def test_query_seed_is_valid(world, seeder):
    Q = _free_configurations(world, 16, 7)
    solved = 0
    for q0, qg in zip(Q[:8], Q[8:], strict=True):
        T = world.robot.compute_ee_pose(qg)
        r = seeder.seed(q0, Goal.pose(T))
        assert r.status in ("solved", "no_connection", "no_ik")
        if not r.success:
            continue
        solved += 1
        assert np.array_equal(r.path[0], q0)
        assert world.fast.path_valid(r.path, seeder.resolution)
        T_end = world.robot.compute_ee_pose(r.path[-1])
        assert np.linalg.norm(T_end[:3, 3] - T[:3, 3]) < 1e-3
        assert set(r.timing_s) >= {"ik", "connect", "search", "validate", "total"}
    assert solved >= 6
    r = seeder.seed(Q[0], Goal.configuration(Q[1]))
    assert r.success and np.array_equal(r.path[-1], Q[1])


def test_seeds_route_to_distinct_goal_ik_solutions(world, seeder):
    Q = _free_configurations(world, 16, 11)
    several = 0
    for q0, qg in zip(Q[:8], Q[8:], strict=True):
        T = world.robot.compute_ee_pose(qg)
        found = seeder.seeds(q0, Goal.pose(T), 3)   # n_goal_ik: the same goal set as seed()
        first = seeder.seed(q0, Goal.pose(T))
        assert found[0].success == first.success
        if not first.success:
            continue
        assert np.array_equal(found[0].path, first.path)
        ends = np.array([s.path[-1] for s in found])
        assert len(found) <= 3
        assert all(np.linalg.norm(a - b) > 0.1 for i, a in enumerate(ends) for b in ends[:i])
        for s in found:
            assert np.array_equal(s.path[0], q0)
            assert world.fast.path_valid(s.path, seeder.resolution)
            assert np.linalg.norm(world.robot.compute_ee_pose(s.path[-1])[:3, 3]
                                  - T[:3, 3]) < 1e-3
        several += len(found) > 1
    assert several >= 2


def test_seeds_nearer_than_a_bound_are_the_unbounded_ones_whose_end_is_that_near(world,
                                                                                 seeder):
    """``shorter_than_rad`` keeps the routes whose end is nearer the start than the bound (a
    path there could beat it) and connects no other end: the bounded answer is the unbounded
    one's routes to those ends (distances measured here), and with no end that near the
    answer is a pruned "no_path", not a failure to connect."""
    Q = _free_configurations(world, 16, 21)
    compared = 0
    for q0, qg in zip(Q[:8], Q[8:], strict=True):
        goal = Goal.pose(world.robot.compute_ee_pose(qg))
        every = seeder.seeds(q0, goal, 6)
        if not every[0].success or len(every) < 2:
            continue
        lines = np.sort([np.linalg.norm(f.path[-1] - q0) for f in every])
        bound = 0.5 * (lines[0] + lines[-1])
        near = [f for f in every if np.linalg.norm(f.path[-1] - q0) < bound]
        some = seeder.seeds(q0, goal, 6, shorter_than_rad=bound)
        assert all(np.linalg.norm(f.path[-1] - q0) < bound for f in some)
        assert {f.path[-1].tobytes() for f in near} <= {f.path[-1].tobytes() for f in some}
        none = seeder.seeds(q0, goal, 6, shorter_than_rad=0.5 * lines[0])[0]
        assert not none.success and none.status == "no_path" and none.info["pruned"]
        compared += 1
    assert compared >= 3


def test_dynamic_obstacle_on_the_shortest_path_reroutes(world, roadmap, seeder):
    rm = roadmap
    rng = np.random.default_rng(4)
    for _ in range(40):
        a, b = (int(x) for x in rng.choice(rm.nodes_of_kind("uniform"), 2, replace=False))
        first = seeder.seed(rm.nodes[a], Goal.configuration(rm.nodes[b]))
        if not first.success or len(first.node_path) < 5:
            continue
        blocked = int(first.node_path[len(first.node_path) // 2])
        # a sphere around the elbow of the blocked node
        T = np.eye(4)
        T[:3, 3] = world.robot.compute_joint_placements(rm.nodes[blocked])[3][:3, 3]
        world.add_obstacle("probe", Shape("sphere", (0.06,)), T)
        try:
            if not (world.fast.is_valid(rm.nodes[a]) and world.fast.is_valid(rm.nodes[b])):
                continue
            second = seeder.seed(rm.nodes[a], Goal.configuration(rm.nodes[b]))
            if second.status == "no_path":
                continue
            assert second.success
            assert blocked not in second.node_path.tolist()
            assert not np.array_equal(second.path, first.path)
            assert world.fast.path_valid(second.path, seeder.resolution)
            assert second.info["path_rank"] != 0
            return
        finally:
            world.remove_obstacle("probe")
    pytest.fail("no query found whose path a probe obstacle blocks")


def test_a_first_answer_at_a_pregrasp_pose_needs_no_ik(world, roadmap, seeder, monkeypatch):
    """Asked for one route to a pose its roadmap nodes meet, with the goal nodes first, the
    seeder routes to a node without solving the IK, and the route is the one it gives when
    the nodes alone fail and it takes the whole goal set (nodes first, then IK solutions)."""
    ik_calls = []
    configurations = seeder.goals.configurations
    monkeypatch.setattr(seeder.goals, "configurations",
                        lambda *a, **k: ik_calls.append(1) or configurations(*a, **k))
    routes = seeder._routes

    def nodes_alone_fail(ask, q_from, Q_goal):
        if len(ik_calls) == 0:      # the call before any IK: the nodes alone
            return ask.fail("no_path", reason="stand-in: the nodes alone failed")
        return routes(ask, q_from, Q_goal)

    pregrasp = roadmap.nodes_of_kind("pregrasp")
    starts = _free_configurations(world, 6, 6)
    same = 0
    for k, n in enumerate(pregrasp[:6]):
        goal = Goal.pose(world.robot.compute_ee_pose(roadmap.nodes[n]))
        r = seeder.seeds(starts[k], goal, 1, goal_nodes_first=True)[0]
        if not r.success:
            continue
        assert ik_calls == [] and r.timing_s["ik"] == 0.0
        nodes = seeder.goal_nodes(goal)
        assert any(np.array_equal(r.path[-1], roadmap.nodes[m]) for m in nodes)
        monkeypatch.setattr(seeder, "_routes", nodes_alone_fail)
        whole = seeder.seeds(starts[k], goal, 1, goal_nodes_first=True)[0]
        monkeypatch.setattr(seeder, "_routes", routes)
        assert len(ik_calls) == 1 and whole.success
        same += np.array_equal(whole.path, r.path)
        ik_calls.clear()
    assert same >= 4


def test_a_pregrasp_pose_goal_ends_at_its_roadmap_node(world, roadmap, seeder):
    """A pose goal some roadmap nodes meet (a pre-grasp node for its pre-grasp pose): its goal
    nodes are exactly the nodes within the IK's tolerances by pinocchio's FK of every node
    (not the roadmap's stored poses), and a query asked for them first routes to one of them
    bit for bit (no goal connection); a node in a dynamic obstacle is not one, nor any node
    of a roadmap built for another version of the robot."""
    pregrasp = roadmap.nodes_of_kind("pregrasp")
    assert len(pregrasp) >= 4
    poses = [world.robot.compute_ee_pose(q) for q in roadmap.nodes]

    def meeting(T):
        out = set()
        for m, T_m in enumerate(poses):
            cos = (np.trace(T_m[:3, :3].T @ T[:3, :3]) - 1) / 2
            if np.linalg.norm(T_m[:3, 3] - T[:3, 3]) <= 1e-4 and \
                    np.arccos(np.clip(cos, -1, 1)) <= 1e-3:
                out.add(m)
        return out

    starts = _free_configurations(world, 6, 5)
    ended = empty = 0
    for k, n in enumerate(pregrasp[:6]):
        T = poses[n]
        nodes = seeder.goal_nodes(Goal.pose(T))
        assert int(n) in nodes.tolist() and set(nodes.tolist()) == meeting(T)
        r = seeder.seeds(starts[k], Goal.pose(T), 1, goal_nodes_first=True)[0]
        if r.success:
            ended += 1
            assert any(np.array_equal(r.path[-1], roadmap.nodes[m]) for m in nodes)
            assert world.fast.path_valid(r.path, seeder.resolution)
        off = T.copy()
        off[:3, 3] += 0.01 * np.array([np.cos(k), np.sin(k), 0.0])
        assert set(seeder.goal_nodes(Goal.pose(off)).tolist()) == meeting(off)
        empty += not meeting(off)
    assert ended >= 4 and empty >= 3
    other = dataclasses.replace(roadmap, meta=dataclasses.replace(roadmap.meta,
                                                                   robot_hash="another arm"))
    assert len(RoadmapSeeder(world, other).goal_nodes(Goal.pose(poses[pregrasp[0]]))) == 0
    n = int(pregrasp[0])
    T_wrist = world.robot.compute_joint_placements(roadmap.nodes[n])[-1]
    world.add_obstacle("probe", Shape("sphere", (0.06,)), T_wrist)
    try:
        assert not world.fast.is_valid(roadmap.nodes[n])
        assert n not in seeder.goal_nodes(Goal.pose(poses[n])).tolist()
    finally:
        world.remove_obstacle("probe")


# --- CLI ----------------------------------------------------------------------------------
def test_cli_build_and_info(tmp_path, capsys):
    out = tmp_path / "pole.npz"
    assert main(["roadmap", "build", SCENE, "--out", str(out), "--nodes", "60",
                 "--wrist-nodes", "20", "--quiet"]) == 0
    assert out.is_file() and "wrote" in capsys.readouterr().out
    assert main(["roadmap", "info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["scene"] == SCENE and info["nodes"] >= 50 and info["edges"] > 0
    assert main(["roadmap", "info", str(tmp_path / "missing.npz")]) == 2


def test_k_nearest_matches_a_kd_tree():
    from scipy.spatial import cKDTree

    from chekhov.roadmap.nearest import k_nearest

    rng = np.random.default_rng(1)
    P = rng.uniform(-2, 2, (500, 7))
    x = rng.uniform(-2, 2, 7)
    for k in (1, 10, 500, 800):
        d_ref, i_ref = cKDTree(P).query(x, k=min(k, len(P)))
        d, i = k_nearest(P, x, k)
        np.testing.assert_allclose(d, np.atleast_1d(d_ref))
        np.testing.assert_array_equal(i, np.atleast_1d(i_ref))
    assert len(k_nearest(P[:0], x, 3)[1]) == 0


def test_interrupted_save_or_build_leaves_no_corrupt_file(tmp_path, world, roadmap,
                                                          monkeypatch):
    import chekhov.roadmap.io as rio

    path = save_roadmap(roadmap, tmp_path / "rm.npz")
    before = path.read_bytes()

    def torn_savez(f, **arrays):  # writes part of the file, then the process is stopped
        f.write(b"PK\x03\x04 partial")
        raise KeyboardInterrupt

    monkeypatch.setattr(rio.np, "savez", torn_savez)
    with pytest.raises(KeyboardInterrupt):
        save_roadmap(roadmap, path)
    monkeypatch.undo()
    assert path.read_bytes() == before and not list(tmp_path.glob(".rm.npz.*"))
    assert load_roadmap(path, world).n_nodes == roadmap.n_nodes

    # a build stopped half-way writes nothing; the rerun builds and saves the roadmap
    fresh = tmp_path / "fresh.npz"

    def stop(msg: str) -> None:
        if "edges" in msg or "connect" in msg:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        load_or_build_roadmap(world, SMALL, fresh, progress=stop)
    assert not fresh.exists() and not list(tmp_path.glob(".fresh.npz.*"))
    again = load_or_build_roadmap(world, SMALL, fresh)
    assert fresh.is_file() and again.n_nodes == roadmap.n_nodes


def test_nearest_poses_match_numpy():
    from scipy.spatial.transform import Rotation

    from chekhov.roadmap.nearest import NearestNodes, nearest_poses

    rng = np.random.default_rng(2)
    P = rng.uniform(-1, 1, (300, 3))
    R = Rotation.random(300, random_state=3).as_matrix()
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.random(random_state=4).as_matrix(), rng.uniform(-1, 1, 3)
    d = np.linalg.norm(P - T[:3, 3], axis=1)
    near = np.argsort(d)[:24]
    angle = np.arccos(np.clip((np.einsum("nij,ij->n", R[near], T[:3, :3]) - 1) / 2, -1, 1))
    ref = near[np.argsort(d[near] + 0.2 * angle, kind="stable")[:6]]
    np.testing.assert_array_equal(nearest_poses(NearestNodes(P), R, T, 24, 6), ref)


def test_last_resorts_are_only_for_a_connection_the_query_needs(world, seeder, monkeypatch):
    con = seeder.connector
    called: list[str] = []
    monkeypatch.setattr(con, "direct", lambda *a, **k: [])
    for name in ("_via_wrist", "_via_proximal", "_via_random", "_via_tree", "_wide"):
        monkeypatch.setattr(con, name, lambda q, *_, name=name, **__: called.append(name) or [])
    q = _free_configurations(world, 1, 3)[0]
    assert con.connect(q, last_resorts=False) == []
    assert called == ["_via_wrist", "_via_proximal", "_via_random"]
    called.clear()
    assert con.connect(q) == []
    assert called == ["_via_wrist", "_via_proximal", "_via_random", "_via_tree", "_wide"]


def test_a_connection_is_kept_until_the_obstacles_change(world, seeder, monkeypatch):
    """Connector.connect(q) again in the same world: the same connections without a motion
    check; after an obstacle is added (and again after it is removed) they are worked out
    anew; an answer whose deadline had passed is not kept."""
    import time

    conn = seeder.connector
    checks: list[int] = []
    real = conn._motions
    monkeypatch.setattr(conn, "_motions",
                        lambda Q0, Q1, *a: checks.append(len(Q0)) or real(Q0, Q1, *a))

    def summary(found):
        return [(c.node, c.cost, c.kind, c.via.tobytes()) for c in found]

    Q = _free_configurations(world, 8, seed=11)
    for q in Q[:6]:
        checks.clear()
        first = conn.connect(q)
        n = len(checks)
        assert n >= 1 and summary(conn.connect(q)) == summary(first) and len(checks) == n
    before = summary(conn.connect(Q[0]))
    T = np.eye(4)
    T[:3, 3] = (0.0, 0.0, -5.0)   # far below the floor: the same connections
    for change in (lambda: world.add_obstacle("far", Shape("sphere", (0.01,)), T),
                   lambda: world.remove_obstacle("far")):
        change()
        checks.clear()
        assert summary(conn.connect(Q[0])) == before and len(checks) >= 1
    checks.clear()
    conn.connect(Q[7], deadline=time.perf_counter() - 1.0)   # late: its first batch only
    late = len(checks)
    conn.connect(Q[7])
    assert late >= 1 and len(checks) > late


def test_goal_configurations_are_kept_until_the_obstacles_change(world, seeder, monkeypatch):
    """The goal resolver's answers asked again in the same world come from memory, equal to
    what it computes (a fresh seeder asks it: a different mechanism); an obstacle added or
    removed makes it ask again; an answer whose deadline had passed is not kept; a kept
    answer cannot be changed in place."""
    import time

    asked: list[int] = []
    real = seeder.goal_ik.resolve
    monkeypatch.setattr(seeder.goal_ik, "resolve",
                        lambda *a, **k: asked.append(1) or real(*a, **k))
    seeder.goals.memo.clear()
    q0, q1 = _free_configurations(world, 2, seed=21)
    T = world.robot.compute_ee_pose(q1)
    Q, why = seeder.goal_configurations(T, near=q0)
    n = len(asked)
    assert n == 2 and len(Q) >= 1 and why == ""          # roadmap-seeded, and from near
    again, _ = seeder.goal_configurations(T, near=q0)
    assert len(asked) == n and np.array_equal(again, Q)
    fresh, _ = RoadmapSeeder(world, seeder.roadmap).goal_configurations(T, near=q0)
    assert np.array_equal(fresh, Q)
    seeded, _ = seeder.goal_configurations(T, near=q0, from_near=False)   # kept part
    assert len(asked) == n and not seeded.flags.writeable
    far = np.eye(4)
    far[:3, 3] = (0.0, 0.0, -5.0)
    for change in (lambda: world.add_obstacle("far", Shape("sphere", (0.01,)), far),
                   lambda: world.remove_obstacle("far")):
        change()
        asked.clear()
        assert np.array_equal(seeder.goal_configurations(T, near=q0)[0], Q) and len(asked) == 2
    T2 = world.robot.compute_ee_pose(q0)
    asked.clear()
    seeder.goal_configurations(T2, near=q1, deadline=time.perf_counter() - 1.0)
    seeder.goal_configurations(T2, near=q1)
    assert len(asked) == 4                                 # the late answers were not kept


def test_goal_last_resorts_wait_for_every_goals_cheap_connection(world, seeder, monkeypatch):
    """The goal configurations' cheap connections are all tried before any last resort (a
    tree of up to tree_time_s): a first answer takes the second goal that connects directly
    and never grows the first one's tree; more routes grow it (the goals nearer the start
    than the first that connected), and every goal gets it only when none connects cheaply."""
    q_start = _free_configurations(world, 1, seed=11)[0]
    Q_goal = _free_configurations(world, 3, seed=12)
    calls = []
    real = seeder.connector.connect

    def connect(q, last_resorts=True, deadline=float("inf")):
        i = next((i for i, g in enumerate(Q_goal) if np.array_equal(g, q)), None)
        calls.append((i, last_resorts))
        if i == 0 or (i is not None and cheap_fails):
            return real(q, last_resorts, deadline) if last_resorts and i == 0 else []
        return real(q, last_resorts, deadline)

    monkeypatch.setattr(seeder.connector, "connect", connect)
    cheap_fails = False
    starts, goals = seeder._connect_ends(q_start, Q_goal, 1, float("inf"))
    assert starts and [g[0][0] for g in goals] == [1]
    assert (0, True) not in calls and calls[1:] == [(0, False), (1, False)]
    calls.clear()
    starts, goals = seeder._connect_ends(q_start, Q_goal, 3, float("inf"))
    assert calls[1:] == [(0, False), (1, False), (2, False), (0, True)]
    calls.clear()
    cheap_fails = True
    starts, goals = seeder._connect_ends(q_start, Q_goal, 1, float("inf"))
    assert calls[1:4] == [(0, False), (1, False), (2, False)] and calls[4] == (0, True)
    # without last resorts (Roadmap + TrajOpt's more routes) no goal ever gets one, whether
    # a nearer goal failed its cheap connections or every goal did
    for fails in (False, True):
        calls.clear()
        cheap_fails = fails
        starts, goals = seeder._connect_ends(q_start, Q_goal, 3, float("inf"),
                                             last_resorts=False)
        assert calls[1:] == [(0, False), (1, False), (2, False)]
        assert [g[0][0] for g in goals] == ([] if fails else [1, 2])


def test_a_robot_with_no_free_configuration_is_told_what_collides():
    """A Panda whose base is inside the table: no roadmap, and the error names the geometries
    the exact checker finds in collision (here the table and the first link), not a guess."""
    from chekhov import Robot, World, load_scene

    T = np.eye(4)
    T[:3, 3] = (0.85, 0.25, 0.60)
    world = World(load_scene("tabletop_pole"), Robot.load("panda", T))
    with pytest.raises(RoadmapError, match=r"obstacle:tabletop / panda_link1_0 \(50 of 50\)"):
        build_roadmap(world, RoadmapConfig(n_nodes=100))
