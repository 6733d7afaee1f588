"""Many dynamic obstacles set at once (World.set_obstacles) give the same decisions as adding
them one at a time, in both checkers; the exact checker's collision pairs and motion bounds
are those a from-scratch computation gives."""

import numpy as np
import pytest

from chekhov import Shape, World
from chekhov.collision.advance import pair_weights


def _obstacles(rng, n):
    out = {}
    for i in range(n):
        T = np.eye(4)
        T[:3, 3] = rng.uniform([0.3, -0.6, 0.7], [1.0, 0.6, 1.4])
        kind = ("box", "sphere", "cylinder")[i % 3]
        size = {"box": (0.08, 0.06, 0.1), "sphere": (0.07,), "cylinder": (0.05, 0.3)}[kind]
        out[f"o{i}"] = (Shape(kind, size), T)
    return out


@pytest.fixture(scope="module")
def worlds():
    return World.load("tabletop_pole"), World.load("tabletop_pole")


def test_set_obstacles_equals_adding_them_one_by_one(worlds):
    batch, single = worlds
    rng = np.random.default_rng(4)
    Q = batch.robot.sample_uniform(rng, 300)
    for n in (12, 3, 0):
        obs = _obstacles(rng, n)
        batch.set_obstacles(obs)
        for name in single.fast.dynamic_obstacles:
            single.remove_obstacle(name)
        for name, (shape, T) in obs.items():
            single.add_obstacle(name, shape, T)
        assert batch.fast.dynamic_obstacles == sorted(obs)
        assert np.array_equal(batch.fast.valid(Q), single.fast.valid(Q))
        assert np.array_equal(batch.exact.valid(Q), single.exact.valid(Q))
        if n:
            assert not single.exact.valid(Q).all()   # the obstacles matter
    batch.set_obstacles({})
    for name in single.fast.dynamic_obstacles:
        single.remove_obstacle(name)


def test_obstacles_resized_and_moved_in_place_decide_as_a_rebuild(worlds):
    """Setting obstacles with the names and shape kinds of those set now resizes and moves
    the exact checker's geometries in place: its collisions, distances, margins and bounds
    are those of a checker that added them from scratch."""
    reshaped, fresh = worlds
    rng = np.random.default_rng(9)
    Q = reshaped.robot.sample_uniform(rng, 300)
    first = _obstacles(rng, 6)
    reshaped.set_obstacles(first)
    pairs_before = len(reshaped.exact.geom_model.collisionPairs)
    reshaped.exact.pair_distances(Q[0], np.arange(4))        # data made before the change
    second = {n: (Shape(sh.kind, tuple(1.6 * np.asarray(sh.size))), T @ _shift(rng))
              for n, (sh, T) in _obstacles(rng, 6).items()}
    try:
        reshaped.set_obstacles(second)
        for name, (shape, T) in second.items():
            fresh.add_obstacle(name, shape, T)
        a, b = reshaped.exact, fresh.exact
        assert len(a.geom_model.collisionPairs) == pairs_before
        assert np.array_equal(a.valid(Q), b.valid(Q))
        assert not a.valid(Q).all()                               # the obstacles matter
        pairs = np.arange(len(a.geom_model.collisionPairs))
        margins = np.full(len(pairs), 0.05)
        for q in Q[:20]:
            assert np.allclose(a.pair_distances(q, pairs), b.pair_distances(q, pairs))
            assert np.array_equal(a.pairs_within(q, margins), b.pairs_within(q, margins))
            assert np.allclose(a.pair_bounds(q, pairs), b.pair_bounds(q, pairs))
    finally:
        reshaped.set_obstacles({})
        for name in second:
            fresh.remove_obstacle(name)


def test_coal_data_for_margins_and_bounds_is_made_with_the_geometry_not_by_a_query(
        worlds, monkeypatch):
    """The exact checker's data for margin tests and distances and its geometries' bounding
    spheres are made when the collision pairs change (obstacles added or set anew), not by
    the first query that asks for them: made there, a 3 ms kitchen query returned 4.7 ms
    late. After obstacles are set, reshaped in place, then one moved, the queries make none,
    and a moved obstacle's margins, distances and bounds are a fresh checker's."""
    from chekhov.collision import exact as exact_module

    w, fresh = worlds
    rng = np.random.default_rng(11)
    Q = w.robot.sample_uniform(rng, 5)
    made = {"data": 0, "spheres": 0}
    real_data = exact_module.pin.GeometryData
    real_spheres = exact_module.ExactChecker._bounding_spheres

    def counted_data(*args):
        made["data"] += 1
        return real_data(*args)

    def counted_spheres(self):
        made["spheres"] += 1
        return real_spheres(self)

    monkeypatch.setattr(exact_module.pin, "GeometryData", counted_data)
    monkeypatch.setattr(exact_module.ExactChecker, "_bounding_spheres", counted_spheres)
    try:
        obstacles = _obstacles(rng, 4)
        w.set_obstacles(obstacles)                          # a rebuild: made here
        assert made["data"] >= 1 and made["spheres"] == 1
        moved = {n: (sh, T @ _shift(rng)) for n, (sh, T) in obstacles.items()}
        one = dict(moved)
        one["o0"] = (moved["o0"][0], moved["o0"][1] @ _shift(rng))
        for step in (None, moved, one):
            if step is moved:
                w.set_obstacles(step)                       # in place
            elif step is one:
                w.move_obstacle("o0", one["o0"][1])
            before = dict(made)
            ex = w.exact
            pairs = np.arange(len(ex.geom_model.collisionPairs))
            for q in Q:
                ex.pairs_within(q, np.full(len(pairs), 0.03), pairs[: len(pairs) // 8])
                ex.pair_distances(q, pairs[:6])
                ex.pair_bounds(q, pairs)
            assert made == before
        monkeypatch.undo()
        for name, (shape, T) in one.items():
            fresh.add_obstacle(name, shape, T)
        pairs = np.arange(len(w.exact.geom_model.collisionPairs))
        margins = np.full(len(pairs), 0.05)
        for q in Q:
            assert np.array_equal(w.exact.pairs_within(q, margins),
                                  fresh.exact.pairs_within(q, margins))
            assert np.allclose(w.exact.pair_distances(q, pairs),
                               fresh.exact.pair_distances(q, pairs))
            assert np.allclose(w.exact.pair_bounds(q, pairs), fresh.exact.pair_bounds(q, pairs))
    finally:
        w.set_obstacles({})
        for name in fresh.fast.dynamic_obstacles:
            fresh.remove_obstacle(name)


def _shift(rng):
    T = np.eye(4)
    T[:3, 3] = rng.uniform(-0.1, 0.1, 3)
    return T


def test_exact_pairs_and_motion_bounds_match_a_fresh_computation(worlds):
    world = worlds[0]
    world.set_obstacles(_obstacles(np.random.default_rng(2), 7))
    try:
        gm = world.exact.geom_model
        pairs = [(cp.first, cp.second) for cp in gm.collisionPairs]
        obstacles = set(world.exact._obstacles.values())
        expected = {tuple(sorted(p)) for p in world.robot.self_collision_pairs} | {
            (min(g, o), max(g, o)) for g in world.robot.moving_geometries for o in obstacles}
        assert sorted(pairs) == sorted(expected) and len(pairs) == len(expected)
        W0, r0 = pair_weights(world.robot.model, gm)
        W1, r1 = world.exact._weights
        assert np.allclose(W0[r0], W1[r1])
    finally:
        world.set_obstacles({})


def test_set_obstacles_refuses_a_scene_objects_name(worlds):
    world = worlds[0]
    name = world.scene.objects[0].name
    with pytest.raises(KeyError, match=name):
        world.set_obstacles({name: (Shape("sphere", (0.1,)), np.eye(4))})


def test_window_packs_are_what_set_obstacles_packs():
    """The executive's time windows are packed beside the fast checker's obstacles
    (``predicted_primitives`` + ``FastChecker.packed_with``), not through obstacle objects and
    ``set_obstacles``: the same arrays as ``set_obstacles(predicted_obstacles(...))``, the
    same decisions, the checker itself unchanged — with a scene object of its own that is
    dynamic (kept by both, and followed when it moves)."""
    from dataclasses import replace

    from chekhov.execute.obstacles import (
        ObstacleTracks,
        predicted_obstacles,
        predicted_primitives,
    )
    base = World.load("tabletop_pole").scene
    scene = replace(base, objects=tuple(replace(o, dynamic=o.name == "pole")
                                        for o in base.objects))
    w = World(scene)
    fast = w.fast
    rng = np.random.default_rng(11)
    Q = w.robot.sample_uniform(rng, 3000)
    tracks = ObstacleTracks()
    first, later = _obstacles(rng, 3), _obstacles(rng, 3)
    tracks.update(first, 1.0)
    moved = {n: (s, T.copy()) for n, (s, T) in first.items()}
    for _, T in list(moved.values())[:2]:             # two move on, the third is seen once
        T[:3, 3] += rng.uniform(-0.04, 0.04, 3)
    tracks.update({**dict(list(moved.items())[:2]), "late": later["o2"]}, 1.0 + 1 / 30)
    pole = w.scene.object("pole").T_world_obj()
    for t0, horizon, margin, bound, shift in ((1.05, 0.03, 0.02, 1.0, 0.0),
                                              (1.1, 0.1, 0.0, 0.0, 0.0),
                                              (1.2, 0.5, 0.05, 1.0, 0.3)):
        if shift:
            T = pole.copy()
            T[1, 3] += shift
            fast.move_obstacle("pole", T)
        version, packed = fast.obstacles_version, fast.packed
        window = fast.packed_with(predicted_primitives(tracks, t0, horizon, margin,
                                                       speed_bound_m_s=bound))
        assert fast.obstacles_version == version and fast.packed is packed
        fast.set_obstacles(predicted_obstacles(tracks, t0, horizon, margin,
                                               speed_bound_m_s=bound))
        for field in ("dynamic", "obstacles"):
            for a, b in zip(getattr(window, field), getattr(fast.packed, field), strict=True):
                assert a.dtype == b.dtype and np.array_equal(a, b), field
        free = fast.valid(Q)
        assert np.array_equal(fast.valid_in(window, Q), free)
        fast.set_obstacles({})
        assert (free < fast.valid(Q)).sum() > 10       # the sweeps do block configurations
