"""Malformed case and roadmap files (issue 13): every bad file gets a ChekhovError naming the
file and what is wrong, cached files that are unusable are rebuilt, stale temporaries of a
killed save are cleaned up; property tests throw random, truncated and flipped bytes."""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from chekhov.bench.cases import CaseSet, cache_stem, cached_cases, find_cached, generate_cases
from chekhov.errors import CaseFileError, ChekhovError
from chekhov.roadmap.build import build_roadmap
from chekhov.roadmap.config import RoadmapConfig
from chekhov.roadmap.errors import RoadmapError
from chekhov.roadmap.graph import Roadmap
from chekhov.roadmap.io import load_or_build_roadmap, load_roadmap, save_roadmap

SCENE = "tabletop_pole"
# small but with every array filled (pre-grasp nodes give stored k shortest paths)
SMALL = RoadmapConfig(n_nodes=60, n_region_nodes=5, n_wrist_nodes=10, pregrasp_solutions=1,
                      seed=3)
PROPERTY = settings(max_examples=40, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture,
                                           HealthCheck.too_slow])


class _Bytes(bytes):
    """File contents that hypothesis reports by size, not byte by byte."""

    def __repr__(self) -> str:
        return f"<{len(self)} bytes>"


@pytest.fixture(scope="module")
def world(world_of):
    return world_of(SCENE)


@pytest.fixture(scope="module")
def cases(world):
    return generate_cases(world, 3, seed=11)


@pytest.fixture(scope="module")
def case_bytes(cases, tmp_path_factory) -> bytes:
    return _Bytes(cases.save(tmp_path_factory.mktemp("cases") / "c.npz").read_bytes())


@pytest.fixture(scope="module")
def roadmap(world):
    return build_roadmap(world, SMALL)


@pytest.fixture(scope="module")
def roadmap_bytes(roadmap, tmp_path_factory) -> bytes:
    return _Bytes(save_roadmap(roadmap, tmp_path_factory.mktemp("rm") / "rm.npz").read_bytes())


def _arrays(data: bytes, path: Path) -> dict[str, np.ndarray]:
    path.write_bytes(data)
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _rewrite(arrays: dict[str, np.ndarray], path: Path, meta_key: str, meta_edit=None,
             **changes) -> Path:
    """A copy of ``arrays`` with ``changes`` (None: drop the array) and the JSON header edited
    by ``meta_edit(meta)``, written with np.savez to ``path``."""
    out = dict(arrays)
    if meta_edit is not None:
        meta = json.loads(str(out[meta_key]))
        meta_edit(meta)
        out[meta_key] = np.array(json.dumps(meta))
    for k, v in changes.items():
        if v is None:
            out.pop(k)
        else:
            out[k] = v
    np.savez(path, **out)
    return path


# --- case files ----------------------------------------------------------------------------
@pytest.mark.parametrize("cut", [0, 1, 30, 200, -200, -22, -1])
def test_truncated_case_file_names_the_file(case_bytes, tmp_path, cut):
    path = tmp_path / "cut.npz"
    path.write_bytes(case_bytes[:cut] if cut else b"")
    with pytest.raises(CaseFileError) as e:
        CaseSet.load(path)
    assert str(path) in str(e.value)


def test_corrupt_compressed_case_data_names_the_file(case_bytes, tmp_path):
    data = bytearray(case_bytes)
    for i in range(len(data) // 4, len(data) // 2, 7):  # garble the compressed arrays
        data[i] ^= 0x5A
    path = tmp_path / "garbled.npz"
    path.write_bytes(bytes(data))
    with pytest.raises(CaseFileError, match=r"garbled\.npz"):
        CaseSet.load(path)


def _set(key, value):
    def edit(meta):
        if value is None:
            meta.pop(key)
        else:
            meta[key] = value
    return edit


def _nan(a: np.ndarray) -> np.ndarray:
    a = a.copy()
    a.flat[1] = np.nan
    return a


def _inf(a: np.ndarray) -> np.ndarray:
    a = a.copy()
    a.flat[-5] = -np.inf
    return a


BAD_CASES = {
    "nan_q_start": ("q_start", None, lambda d: {"q_start": _nan(d["q_start"])}),
    "inf_T_goal": ("T_world_ee_goal", None,
                   lambda d: {"T_world_ee_goal": _inf(d["T_world_ee_goal"])}),
    "q_goal_shape": ("q_goal", None, lambda d: {"q_goal": d["q_goal"][:, :-1]}),
    "q_start_1d": ("q_start", None, lambda d: {"q_start": d["q_start"].ravel()}),
    "T_start_shape": ("T_world_ee_start", None,
                      lambda d: {"T_world_ee_start": d["T_world_ee_start"][:, :3]}),
    "missing_q_goal": ("q_goal", None, lambda d: {"q_goal": None}),
    "int_q_start": ("q_start", None, lambda d: {"q_start": d["q_start"].astype(np.int64)}),
    "str_q_goal": ("q_goal", None, lambda d: {"q_goal": d["q_goal"].astype(str)}),
    "T_not_a_pose": ("T_world_ee_goal", None,
                     lambda d: {"T_world_ee_goal": d["T_world_ee_goal"] * 2.0}),
    "wrong_dof": ("joint_names", lambda m: m["joint_names"].pop(), lambda d: {}),
    "n_mismatch": ("'n'", _set("n", 7), lambda d: {}),
    "seed_type": ("seed", _set("seed", "eleven"), lambda d: {}),
    "joint_names_type": ("joint_names", _set("joint_names", "abc"), lambda d: {}),
    "scene_missing": ("scene", _set("scene", None), lambda d: {}),
    "replaced_negative": ("replaced", _set("replaced", -1), lambda d: {}),
    "meta_not_object": ("meta", None, lambda d: {"meta": np.array("[1, 2]")}),
    "meta_not_json": ("meta", None, lambda d: {"meta": np.array("{not json")}),
}


@pytest.mark.parametrize("name", sorted(BAD_CASES))
def test_bad_case_contents_name_the_file_and_field(case_bytes, tmp_path, name):
    field, meta_edit, change = BAD_CASES[name]
    arrays = _arrays(case_bytes, tmp_path / "ok.npz")
    path = _rewrite(arrays, tmp_path / "bad.npz", "meta", meta_edit, **change(arrays))
    with pytest.raises(CaseFileError) as e:
        CaseSet.load(path)
    assert str(path) in str(e.value) and field in str(e.value), str(e.value)


def test_case_configurations_outside_the_joint_limits(case_bytes, world, tmp_path):
    arrays = _arrays(case_bytes, tmp_path / "ok.npz")
    q = arrays["q_start"].copy()
    q[0, 0] = world.robot.upper[0] + 0.5
    path = _rewrite(arrays, tmp_path / "limits.npz", "meta", q_start=q)
    CaseSet.load(path)  # without a world the limits are unknown
    with pytest.raises(CaseFileError, match=r"limits\.npz.*q_start.*limits"):
        CaseSet.load(path, world)


def test_other_scene_is_a_case_file_error(cases, world_of, tmp_path):
    path = cases.save(tmp_path / "c.npz")
    with pytest.raises(CaseFileError, match=r"c\.npz"):
        CaseSet.load(path, world_of("kitchen"))


@pytest.mark.parametrize("damage", ["empty", "truncated", "garbage"])
def test_corrupt_cached_cases_are_regenerated(world, tmp_path, caplog, damage):
    good = cached_cases(world, 3, seed=5, cache_dir=tmp_path)
    (path,) = tmp_path.iterdir()
    data = path.read_bytes()
    path.write_bytes({"empty": b"", "truncated": data[: len(data) // 2],
                      "garbage": b"PK\x03\x04" + bytes(200)}[damage])
    with caplog.at_level(logging.WARNING, logger="chekhov"):
        again = cached_cases(world, 2, seed=5, cache_dir=tmp_path)
    assert again.same_as(good.head(2))
    assert any(path.name in r.getMessage() for r in caplog.records), caplog.text
    # the unusable file is gone or replaced by a valid one; nothing else is left
    for p in tmp_path.iterdir():
        assert not p.name.startswith("."), p
        CaseSet.load(p, world)
    assert find_cached(world, tmp_path, cache_stem(world, 5), 2) is not None


def test_cached_cases_of_another_world_are_regenerated(world, world_of, tmp_path, caplog):
    """A readable cached file that fails check_world is replaced, not an abort."""
    good = cached_cases(world, 2, seed=5, cache_dir=tmp_path)
    (path,) = tmp_path.iterdir()
    other = world_of("kitchen")
    # a file under this world's cache name that holds another scene's cases
    generate_cases(other, 2, seed=5).save(path)
    with caplog.at_level(logging.WARNING, logger="chekhov"):
        again = cached_cases(world, 2, seed=5, cache_dir=tmp_path)
    assert again.same_as(good) and path.name in caplog.text
    CaseSet.load(path, world)


def test_cached_cases_are_kept_per_robot(world, tmp_path):
    """The same scene with another arm (``World(scene, robot)``) has a cache name of its own:
    looking its cases up neither finds the first arm's file nor removes it as unusable (they
    replaced each other's file on every use)."""
    from chekhov import Robot, World

    cached_cases(world, 2, seed=5, cache_dir=tmp_path)
    (path,) = tmp_path.iterdir()
    panda = World(world.scene, Robot.load("panda"))
    assert cache_stem(panda, 5) != cache_stem(world, 5)
    assert find_cached(panda, tmp_path, cache_stem(panda, 5), 2) is None
    assert path.exists() and find_cached(world, tmp_path, cache_stem(world, 5), 2) is not None


# --- roadmap files -------------------------------------------------------------------------
def test_empty_or_truncated_roadmap_file_names_the_file(roadmap_bytes, tmp_path):
    path = tmp_path / "cut.npz"
    for cut in (0, 1, 30, 1000, -1000, -22, -1):
        path.write_bytes(roadmap_bytes[:cut] if cut else b"")
        with pytest.raises(RoadmapError) as e:
            load_roadmap(path)
        assert str(path) in str(e.value), cut


def test_load_or_build_rebuilds_a_corrupt_cached_roadmap(world, roadmap, roadmap_bytes,
                                                         tmp_path):
    path = tmp_path / "rm.npz"
    flipped = bytearray(roadmap_bytes)
    flipped[len(flipped) // 2] ^= 0xFF
    for damaged in (b"", roadmap_bytes[: len(roadmap_bytes) // 3], bytes(flipped)):
        path.write_bytes(damaged)
        said: list[str] = []
        rm = load_or_build_roadmap(world, SMALL, path, progress=said.append)
        assert rm.n_nodes == roadmap.n_nodes and np.array_equal(rm.nodes, roadmap.nodes)
        assert any("rebuilding" in s and str(path) in s for s in said), said
        assert load_roadmap(path, world).n_nodes == roadmap.n_nodes


def test_load_or_build_says_so_without_a_progress_callback(world, roadmap, tmp_path, caplog):
    path = tmp_path / "rm.npz"
    path.write_bytes(b"")
    with caplog.at_level(logging.WARNING, logger="chekhov"):
        rm = load_or_build_roadmap(world, SMALL, path)
    assert rm.n_nodes == roadmap.n_nodes
    assert "rebuilding" in caplog.text and str(path) in caplog.text


def _bad_config(meta):
    meta["config"]["n_nodes"] = "many"


def _edges_out_of_range(d):
    e = d["edges"].copy()
    e[0, 1] = len(d["nodes"]) + 5
    return {"edges": e}


def _negative_edge(d):
    e = d["edges"].copy()
    e[3, 0] = -1
    return {"edges": e}


def _pred_out_of_range(d):
    p = d["pred"].copy()
    p[0, 1] = len(d["nodes"]) + 1
    return {"pred": p}


def _indices_out_of_range(d):
    i = d["indices"].copy()
    i[2] = len(d["nodes"])
    return {"indices": i}


def _kpath_nodes_out_of_range(d):
    k = d["kpath_nodes"].copy()
    k[0] = 10**6
    return {"kpath_nodes": k}


BAD_ROADMAPS = {
    "no_config": ("config", _set("config", None), lambda d: {}),
    "config_type": ("n_nodes", _bad_config, lambda d: {}),
    "config_not_dict": ("config", _set("config", [1, 2]), lambda d: {}),
    "config_unknown_field": ("config", lambda m: m["config"].update(x=1), lambda d: {}),
    "robot_type": ("robot", _set("robot", 3), lambda d: {}),
    "scene_hash_missing": ("scene_hash", _set("scene_hash", None), lambda d: {}),
    "build_s_type": ("build_s", _set("build_s", "slow"), lambda d: {}),
    "node_counts_type": ("node_counts", _set("node_counts", [1]), lambda d: {}),
    "notes_type": ("notes", _set("notes", "x"), lambda d: {}),
    "dropped_nodes_type": ("dropped_nodes", _set("dropped_nodes", 1.5), lambda d: {}),
    "meta_not_object": ("meta", None, lambda d: {"meta_json": np.array("[]")}),
    "nan_nodes": ("nodes", None, lambda d: {"nodes": _nan(d["nodes"])}),
    "nodes_1d": ("nodes", None, lambda d: {"nodes": d["nodes"].ravel()}),
    "int_nodes": ("nodes", None, lambda d: {"nodes": d["nodes"].astype(np.int64)}),
    "edges_out_of_range": ("edges", None, _edges_out_of_range),
    "negative_edge": ("edges", None, _negative_edge),
    "edges_shape": ("edges", None, lambda d: {"edges": d["edges"][:, :1]}),
    "edges_float": ("edges", None, lambda d: {"edges": d["edges"].astype(np.float64)}),
    "edge_length_nan": ("edge_length", None, lambda d: {"edge_length": _nan(d["edge_length"])}),
    "edge_length_short": ("edge_length", None,
                          lambda d: {"edge_length": d["edge_length"][:-1]}),
    "node_kind_range": ("node_kind", None,
                        lambda d: {"node_kind": np.full_like(d["node_kind"], 9)}),
    "ee_position_shape": ("ee_position", None,
                          lambda d: {"ee_position": d["ee_position"][:, :2]}),
    "ee_rotation_nan": ("ee_rotation", None, lambda d: {"ee_rotation": _nan(d["ee_rotation"])}),
    "dist_nan": ("dist", None, lambda d: {"dist": _nan(d["dist"])}),
    "dist_shape": ("dist", None, lambda d: {"dist": d["dist"][:-1]}),
    "pred_out_of_range": ("pred", None, _pred_out_of_range),
    "indptr_bad": ("indptr", None, lambda d: {"indptr": d["indptr"][::-1].copy()}),
    "indices_out_of_range": ("indices", None, _indices_out_of_range),
    "weights_nan": ("weights", None, lambda d: {"weights": _nan(d["weights"])}),
    "edge_id_range": ("edge_id", None,
                      lambda d: {"edge_id": d["edge_id"] + len(d["edges"])}),
    "kpath_ptr_bad": ("kpath_ptr", None, lambda d: {"kpath_ptr": d["kpath_ptr"][:-1]}),
    "kpath_nodes_range": ("kpath_nodes", None, _kpath_nodes_out_of_range),
    "kpath_key_shape": ("kpath_key", None, lambda d: {"kpath_key": d["kpath_key"][:, :2]}),
    "node_label_type": ("node_label", None,
                        lambda d: {"node_label": np.zeros(len(d["nodes"]))}),
}


@pytest.mark.parametrize("name", sorted(BAD_ROADMAPS))
def test_bad_roadmap_contents_name_the_file_and_field(roadmap_bytes, tmp_path, name):
    field, meta_edit, change = BAD_ROADMAPS[name]
    arrays = _arrays(roadmap_bytes, tmp_path / "ok.npz")
    path = _rewrite(arrays, tmp_path / "bad.npz", "meta_json", meta_edit, **change(arrays))
    with pytest.raises(RoadmapError) as e:
        load_roadmap(path)
    assert str(path) in str(e.value) and field in str(e.value), str(e.value)


def test_roadmap_of_another_dof_for_the_world(roadmap_bytes, world, tmp_path):
    arrays = _arrays(roadmap_bytes, tmp_path / "ok.npz")
    path = _rewrite(arrays, tmp_path / "dof.npz", "meta_json", nodes=arrays["nodes"][:, :-1])
    with pytest.raises(RoadmapError, match=r"dof\.npz.*nodes.*joints"):
        load_roadmap(path, world)


# --- temporaries of a killed save ----------------------------------------------------------
_KILLED_SAVE = """
import os, signal, sys
import chekhov.roadmap.io as rio
roadmap = rio.load_roadmap(sys.argv[1])
def torn(f, **arrays):  # half the file is written, then the process is killed
    f.write(b"PK\\x03\\x04" + bytes(100_000))
    f.flush()
    os.kill(os.getpid(), signal.SIGKILL)
rio.np.savez = torn
rio.save_roadmap(roadmap, sys.argv[2])
"""


def _killed_save(source: Path, target: Path) -> list[Path]:
    """Run a save of ``source`` to ``target`` in a process killed half-way; its temporaries."""
    from chekhov.roadmap.io import remove_stale_temporaries

    r = subprocess.run([sys.executable, "-c", _KILLED_SAVE, str(source), str(target)],
                       capture_output=True, timeout=120)
    assert r.returncode == -9, r.stderr.decode()
    left = sorted(target.parent.glob(f".{target.name}.*"))
    assert left, "the killed save left no temporary file"
    assert remove_stale_temporaries(target) == []  # too fresh to tell from a live writer
    past = time.time() - 60  # untouched for a minute
    for p in left:
        os.utime(p, (past, past))
    return left


def test_stale_temporary_of_a_killed_save_is_removed(roadmap, world, tmp_path):
    source = save_roadmap(roadmap, tmp_path / "src" / "rm.npz")
    target = tmp_path / "rm.npz"
    _killed_save(source, target)
    save_roadmap(roadmap, target)  # the next save into that folder cleans up
    assert not list(tmp_path.glob(".rm.npz.*"))
    _killed_save(source, target)
    load_or_build_roadmap(world, SMALL, target)  # reuses the file, and cleans up
    assert not list(tmp_path.glob(".rm.npz.*"))
    assert load_roadmap(target, world).n_nodes == roadmap.n_nodes


def test_temporaries_of_live_writers_and_other_files_are_kept(roadmap, tmp_path):
    from chekhov.roadmap.io import temporary_name

    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        live_tmp = tmp_path / temporary_name(tmp_path / "rm.npz", pid=live.pid)
        live_tmp.write_bytes(b"being written")
        old = time.time() - 3600  # untouched for an hour, but its writer is alive
        os.utime(live_tmp, (old, old))
        fresh_legacy = tmp_path / ".rm.npz.abcd1234"  # a mkstemp name: no pid, recent
        fresh_legacy.write_bytes(b"x")
        old_legacy = tmp_path / ".rm.npz.zzzz9999"
        old_legacy.write_bytes(b"x")
        os.utime(old_legacy, (old, old))
        other_target = tmp_path / ".other.npz.abcd1234"
        other_target.write_bytes(b"x")
        os.utime(other_target, (old, old))
        user_file = tmp_path / ".rm.npz.notes.txt"
        user_file.write_bytes(b"x")
        os.utime(user_file, (old, old))
        save_roadmap(roadmap, tmp_path / "rm.npz")
        assert live_tmp.exists() and fresh_legacy.exists()
        assert other_target.exists() and user_file.exists()
        assert not old_legacy.exists()
    finally:
        live.kill()
        live.wait()
    save_roadmap(roadmap, tmp_path / "rm.npz")  # now its writer is gone
    assert not live_tmp.exists() and fresh_legacy.exists()


# --- property tests ------------------------------------------------------------------------
def _valid_cases(c: CaseSet) -> None:
    assert isinstance(c, CaseSet) and len(c) >= 1
    assert all(np.isfinite(getattr(c, a)).all() for a in ("q_start", "q_goal"))


def _valid_roadmap(r: Roadmap) -> None:
    assert isinstance(r, Roadmap) and r.n_nodes >= 1 and np.isfinite(r.nodes).all()
    assert r.edges.size == 0 or r.edges.max() < r.n_nodes


def _check(load, valid, path: Path, data: bytes) -> None:
    path.write_bytes(data)
    t0 = time.perf_counter()
    try:
        obj = load(path)
    except ChekhovError as e:
        assert str(path) in str(e), str(e)
    else:
        valid(obj)
    assert time.perf_counter() - t0 < 1.0


def _member_starts(data: bytes) -> list[int]:
    """Offsets of the members' local headers in a zip archive (npy headers follow)."""
    import io
    import zipfile

    with zipfile.ZipFile(io.BytesIO(data)) as z:
        return [i.header_offset for i in z.infolist()]


def _flip(data: bytes, flips: list[tuple[int, int]]) -> bytes:
    b = bytearray(data)
    for pos, mask in flips:
        b[pos % len(b)] ^= mask
    return bytes(b)


# anywhere, or in the first local headers, or in the central directory at the end
_POSITIONS = st.one_of(st.integers(0, 10**7), st.integers(0, 400), st.integers(-2500, -1))
_FLIPS = st.lists(st.tuples(_POSITIONS, st.integers(1, 255)), min_size=1, max_size=4)


@pytest.fixture(scope="module")
def scratch(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


@PROPERTY
@given(data=st.binary(max_size=3000))
def test_random_bytes_as_case_file(scratch, data):
    _check(CaseSet.load, _valid_cases, scratch / "random.npz", data)


@PROPERTY
@given(cut=st.floats(0, 1, exclude_max=True))
def test_truncated_case_file(scratch, case_bytes, cut):
    _check(CaseSet.load, _valid_cases, scratch / "cut.npz",
           case_bytes[: int(cut * len(case_bytes))])


@PROPERTY
@given(flips=_FLIPS)
def test_flipped_case_file(scratch, case_bytes, world, flips):
    _check(lambda p: CaseSet.load(p, world), _valid_cases, scratch / "flip.npz",
           _flip(case_bytes, flips))


@PROPERTY
@given(data=st.binary(max_size=3000))
def test_random_bytes_as_roadmap(scratch, data):
    _check(load_roadmap, _valid_roadmap, scratch / "random_rm.npz", data)


@PROPERTY
@given(cut=st.floats(0, 1, exclude_max=True))
def test_truncated_roadmap(scratch, roadmap_bytes, cut):
    _check(load_roadmap, _valid_roadmap, scratch / "cut_rm.npz",
           roadmap_bytes[: int(cut * len(roadmap_bytes))])


@PROPERTY
@example(flips=[], header=(0, 68, 1))  # garbles the npy header of 'nodes': TokenError
@example(flips=[], header=(11, 29, 128))  # a local header's name length: EOFError
@given(flips=_FLIPS, header=st.none() | st.tuples(st.integers(0, 100), st.integers(0, 200),
                                                   st.integers(1, 255)))
def test_flipped_roadmap(scratch, roadmap_bytes, world, flips, header):
    """Random flips, and (``header``: member, offset, mask) one in a member's local header or
    the npy header after it: the roadmap's members are stored uncompressed, so NumPy's
    header parser sees these bytes."""
    if header is not None:
        starts = _member_starts(roadmap_bytes)
        flips = [*flips, (starts[header[0] % len(starts)] + header[1], header[2])]
    _check(lambda p: load_roadmap(p, world), _valid_roadmap, scratch / "flip_rm.npz",
           _flip(roadmap_bytes, flips))
