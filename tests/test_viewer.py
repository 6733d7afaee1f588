"""The 3D viewer: it renders in a real (headless) browser, replans when the dynamic obstacle
moves, and refuses a taken port with a clear error."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("viser", reason="the viewer needs viser (pip install 'chekhov[viewer]')")

from chekhov import World, build_roadmap, save_roadmap
from chekhov.cases import generate_cases
from chekhov.errors import ChekhovError
from chekhov.roadmap.config import RoadmapConfig
from chekhov.scene.model import Shape
from chekhov.transforms import make_transform
from chekhov.viewer.app import Viewer, ViewerError, check_port_free
from chekhov.viewer.meshes import box_mesh, cluster_decimate, cylinder_mesh, sphere_mesh
from chekhov.viewer.planning import interpolate_path

SMALL = RoadmapConfig(n_nodes=150, n_region_nodes=20, n_wrist_nodes=60, seed=3)
SRC = str(Path(__file__).resolve().parents[1] / "src")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


@pytest.fixture(scope="module")
def world() -> World:
    return World.load("tabletop_pole")  # own world: the viewer adds a dynamic obstacle


@pytest.fixture(scope="module")
def roadmap(world):
    return build_roadmap(world, SMALL)


@pytest.fixture(scope="module")
def cases(world):
    return generate_cases(world, 4, seed=0)


def test_meshes_are_closed_and_decimation_keeps_shape():
    for _V, F in (box_mesh(np.array([0.1, 0.2, 0.3])), cylinder_mesh(0.05, 0.2),
                 sphere_mesh(0.1)):
        edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
        _, count = np.unique(edges, axis=0, return_counts=True)
        assert np.all(count == 2)  # every edge shared by two triangles: closed surface
    V, F = sphere_mesh(0.1, 48)
    V2, F2 = cluster_decimate(V, F, 0.02)
    assert len(F2) < len(F) / 2
    assert np.allclose(np.linalg.norm(V2, axis=1), 0.1, atol=0.02)
    P = np.array([[0.0, 0.0], [1.0, 2.0], [2.0, 2.0]])
    assert np.allclose(interpolate_path(P, 0.25), [0.5, 1.0])
    assert np.allclose(interpolate_path(P, 1.0), P[-1])


def test_replanning_through_the_python_api_changes_the_trajectory(world, roadmap, cases):
    with Viewer(world, roadmap, cases, port=free_port(), plan_on_start=False,
                obstacle=Shape("sphere", (0.06,))) as v:
        assert v.handles["gui/play"].value is True
        # the obstacle goes halfway along the hand's way: the first case where that leaves the
        # start and a goal IK solution free (else the question has no answer to find)
        for i in range(3):
            v.select_case(i, plan=False)
            first = v.replan()
            assert first.result.success
            before = v.shown_path()
            assert before is not None and np.allclose(before, first.ee_path, atol=1e-5)
            assert "path length" in v.handles["gui/result"].content
            arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(before, axis=0),
                                                                  axis=1))])
            mid = before[int(np.searchsorted(arc, arc[-1] / 2))]
            v.move_obstacle(make_transform(mid))
            if world.exact.is_valid(cases.q_start[i]) and len(world.goal_ik.resolve(
                    cases.goal(i), n=1)):
                break
        else:
            raise AssertionError("in 3 cases the obstacle took the start or the goal")
        assert np.allclose(v.obstacles[v.obstacle_name].position, mid, atol=1e-6)
        assert not world.fast.path_valid(first.path)
        second = v.replan()
        after = v.shown_path()
        assert second.result.success and after is not None
        assert after.shape != before.shape or not np.allclose(after, before, atol=1e-3)
        assert world.fast.path_valid(second.path)
        assert second.result.time_s < 5.0
        # what a gizmo drag does: a background replan, its time shown in the panel
        v.move_obstacle(make_transform(mid + np.array([0.0, 0.0, 0.05])))
        v.request_replan()
        t_end = time.monotonic() + 20
        while not v.replan_times_s and time.monotonic() < t_end:
            time.sleep(0.05)
        assert v.replan_times_s, "the background replan did not run"
        assert "last replan" in v.handles["gui/replan_time"].content


def test_the_viewer_shows_and_replans_for_the_panda():
    """A second robot (meshes, locked fingers) in its own scene: the viewer draws it (visual
    meshes loaded on first use) and its replans give exactly checked paths."""
    w = World.load("panda_cage")
    rm = build_roadmap(w, SMALL)
    with Viewer(w, rm, generate_cases(w, 2, seed=0), port=free_port(),
                plan_on_start=False) as v:
        v.select_case(0, plan=False)
        r = v.replan()
        assert r.result.success, r.result.status
        assert w.exact.path_valid(r.path, substeps=100)
        assert v.shown_path() is not None
        # played in real time: the slider's fraction of the timed trajectory's duration
        assert r.timed is not None and r.timed.duration > 0
        q_half = r.timed.sample(0.5 * r.timed.duration)[0]
        assert np.allclose(r.configuration_at(0.5), q_half)
        assert np.allclose(r.configuration_at(1.0), r.path[-1], atol=1e-9)
        assert "motion duration" in v.handles["gui/result"].content


def test_taken_port_is_a_clear_error(world, roadmap, cases):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = s.getsockname()[1]
        with pytest.raises(ViewerError, match="already in use"):
            check_port_free("127.0.0.1", port)
        with pytest.raises(ChekhovError, match=f"port {port}"):
            Viewer(world, roadmap, cases, port=port)
        env = {**os.environ, "PYTHONPATH": SRC}
        r = subprocess.run([sys.executable, "-m", "chekhov.cli", "view", "tabletop_pole",
                            "--port", str(port)], capture_output=True, text=True, env=env,
                           timeout=60)
        assert r.returncode == 2
        assert "already in use" in r.stderr and "--port" in r.stderr


def test_viewer_renders_in_headless_chromium(world, roadmap, cases, tmp_path):
    browser = chromium()
    if browser is None:
        pytest.skip("no chromium on PATH (Debian: apt-get install -y chromium); "
                    "the browser test cannot run")
    from PIL import Image

    rm_file = save_roadmap(roadmap, tmp_path / "roadmap.npz")
    cases_file = cases.save(tmp_path / "cases.npz")
    port = free_port()
    env = {**os.environ, "PYTHONPATH": SRC}
    proc = subprocess.Popen(
        [sys.executable, "-m", "chekhov.cli", "view", "tabletop_pole", "--roadmap",
         str(rm_file), "--cases", str(cases_file), "--port", str(port)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    try:
        assert proc.stdout is not None
        t_end, lines = time.monotonic() + 90, []
        while time.monotonic() < t_end:
            line = proc.stdout.readline()
            if not line and proc.poll() is not None:
                break
            lines.append(line)
            if line.startswith("chekhov viewer: http://"):
                break
        assert any(x.startswith("chekhov viewer:") for x in lines), "".join(lines)
        shot = tmp_path / "viewer.png"
        r = subprocess.run(
            [browser, "--headless", "--no-sandbox", "--disable-dev-shm-usage",
             "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--hide-scrollbars",
             f"--user-data-dir={tmp_path / 'chromium'}", f"--screenshot={shot}",
             "--window-size=1000,700", "--virtual-time-budget=15000",
             f"http://127.0.0.1:{port}/"],
            capture_output=True, text=True, timeout=120)
        if not shot.is_file():
            pytest.skip(f"chromium could not take a screenshot here (rc {r.returncode}): "
                        f"{r.stderr[-400:]}")
        img = np.asarray(Image.open(shot).convert("RGB"), dtype=float)
        canvas = img[160:, :650]  # the 3D canvas, left of the GUI panel, below the notice
        assert canvas.std() > 12.0, f"blank screenshot (std {canvas.std():.1f})"
        colored = (canvas.max(axis=2) - canvas.min(axis=2)) > 40
        dark = canvas.mean(axis=2) < 120
        assert colored.mean() > 0.005 and dark.mean() > 0.01, "no robot or scene drawn"
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()


def test_show_draws_a_trajectory_file(world, cases, tmp_path, capsys):
    from chekhov.cli import main

    path = np.linspace(cases.q_start[0], cases.q_goal[0], 12)
    np.save(tmp_path / "path.npy", path)
    out = tmp_path / "plan.png"
    assert main(["show", "tabletop_pole", "--path", str(tmp_path / "path.npy"), "--out",
                 str(out), "--ghosts", "3"]) == 0
    assert out.is_file() and out.stat().st_size > 10_000
    assert "path of 12 waypoints" in capsys.readouterr().out
    np.savetxt(tmp_path / "bad.csv", path[:, :5], delimiter=",")
    assert main(["show", "tabletop_pole", "--path", str(tmp_path / "bad.csv"), "--out",
                 str(out)]) == 2
    assert "expected waypoints of shape (T, 7)" in capsys.readouterr().err
