"""``chekhov view SCENE --react``: the reactive executive runs live in the viewer. Its real-time
loop moves the robot and the panel follows (mode, reaction latency); a dragged obstacle is in
the sensor's frames; the scripted kicks and goal changes happen as ``run_episode`` has them;
and in a real (headless) browser the arm is seen to move."""

from __future__ import annotations

import base64
import io
import itertools
import json
import re
import socket
import subprocess
import time
import urllib.request
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("viser", reason="the viewer needs viser (pip install 'chekhov[viewer]')")

from test_viewer import chromium, free_port

from chekhov.cli import main
from chekhov.execute import EpisodeScript, Executor, GoalChange, InlineWorker, Kick
from chekhov.execute.benchmark import executive_planner
from chekhov.execute.obstacles import MovingObstacle
from chekhov.execute.script import start_and_goal
from chekhov.scene.model import Shape
from chekhov.transforms import make_transform
from chekhov.viewer.react import LiveConfig, LiveEpisode, Sensor
from chekhov.viewer.react_app import ReactViewer, open_react_viewer

MOVING = ("plan", "join", "brake", "dodge")


@pytest.fixture(scope="module")
def viewer():
    # plain lighting: software WebGL draws it several times quicker (the browser test)
    v = open_react_viewer("tabletop_pole", port=free_port(), plain_lighting=True)
    yield v
    v.close()


def _wait(what: Callable[[], bool], timeout_s: float) -> bool:
    t_end = time.monotonic() + timeout_s
    while not what():
        if time.monotonic() > t_end:
            return False
        time.sleep(0.02)
    return True


def _moving_parts(v: ReactViewer) -> np.ndarray:
    return np.array([h.position for p, h in zip(v.robot.meshes.parts, v.robot.handles,
                                                strict=True) if p.moving], dtype=float)


def _mode_shown(v: ReactViewer) -> str:
    found = re.search(r"mode \*\*(\w+)\*\*", v.handles["gui/status"].content)
    return found.group(1) if found else ""


def test_the_live_loop_moves_the_robot_and_the_panel_follows(viewer):
    loop = viewer.loop
    assert _wait(lambda: loop.state.mode in MOVING, 30), (loop.state.mode, loop.error)
    first, parts = loop.state, _moving_parts(viewer)
    status = viewer.handles["gui/status"].content
    time.sleep(1.0)
    later = loop.state
    assert later.ticks - first.ticks >= 40, "the 100 Hz loop hardly ticked in a second"
    assert later.episode != first.episode or np.abs(later.q - first.q).max() > 0.02
    assert np.abs(_moving_parts(viewer) - parts).max() > 1e-3        # drawn where it went
    assert viewer.handles["gui/status"].content != status            # its clock, its mode
    assert _mode_shown(viewer) in (*MOVING, "rest", "setup")
    assert _wait(lambda: _mode_shown(viewer) in MOVING and viewer.handles[
        "/react/trace"].visible, 10), "no motion shown with its trace"
    assert loop.error is None


def test_a_dragged_obstacle_is_sensed_and_the_reaction_latency_shown(viewer):
    """The orange cylinder dragged onto the arm's way ahead of it: the sensor reports it where
    it was put, the executive reacts, and the panel gives that reaction's latency."""
    loop = viewer.loop
    home = make_transform(np.array(viewer.handles["/obstacles/person_arm"].position))

    def early_in_a_plan() -> bool:     # and nothing open: a new conflict would join that
        s, ex = loop.state, loop.executor
        return s.mode == "plan" and s.motion is not None and s.motion.t_end - s.t > 1.0 \
            and ex is not None and all(r.t_resolved is not None for r in ex.reactions)
    assert _wait(early_in_a_plan, 60), (loop.state.mode, loop.error)
    s = loop.state
    assert s.motion is not None
    p = viewer.world.robot.compute_ee_pose(s.motion.sample(s.t + 0.4).q)[:3, 3]
    viewer.move_obstacle(make_transform(p))
    try:
        executor = loop.executor
        assert executor is not None

        def sensed() -> bool:
            track = executor.tracks.tracks.get("person_arm")
            return track is not None and np.allclose(track.T_last[:3, 3], p, atol=1e-9)
        assert _wait(sensed, 2.0), "the dragged obstacle never reached the executive"

        def answered() -> bool:
            return any(r.kind == "obstacle" and r.t_reacted is not None
                       and max(r.t_observed, r.t_reacted) >= s.t for r in executor.reactions)
        assert _wait(answered, 10.0), [(r.kind, r.t_observed, r.t_reacted)
                                       for r in executor.reactions]
        shown = re.compile(r"last reaction: \*\*(\w+)\*\* at [\d.]+ s — reacted in "
                           r"\*\*(\d+) ms\*\*, resolved in (\*\*\d+ ms\*\*|…)")
        assert _wait(lambda: shown.fullmatch(viewer.handles["gui/latency"].content)
                     is not None, 2.0), viewer.handles["gui/latency"].content
    finally:
        viewer.move_obstacle(home)
    assert loop.error is None


def test_a_live_episode_has_its_kicks_goal_changes_and_sensor_frames(world_of):
    """On a simulated clock (an inline worker): the kick moves the arm (shrunk as
    run_episode shrinks it), the new goal reaches the executive on its tick, and frames are
    taken every period and delivered a latency later, the dragged obstacles in them."""
    world = world_of("tabletop_pole")
    config = LiveConfig()
    rc = config.react
    planner = executive_planner("Roadmap+TrajOpt", world)
    q0, goal = start_and_goal(world, 0, 0)
    _, other = start_and_goal(world, 0, 1)
    arm = MovingObstacle("forearm", Shape("sphere", (0.05,)), np.eye(3),
                         np.array([2.0, 2.0, 1.0]), np.array([2.0, 3.0, 1.0]), 0.0, 0.5)
    script = EpisodeScript(0, q0, goal, "", (arm,), (GoalChange(0.2, other, ""),),
                           (Kick(0.3, np.full(world.robot.dof, 0.02)),))
    executor = Executor(world, InlineWorker(world, planner, rc.executor.timing), goal,
                        rc.executor)
    episode = LiveEpisode(world, executor, script, deadline_s=10.0, sim=rc.sim)
    box = (Shape("box", (0.1, 0.1, 0.1)), make_transform((3.0, 0.0, 0.5)))
    try:
        for k in range(41):
            t = k * rc.executor.control_dt_s
            command = episode.step(t, {"dragged": box})
            assert (executor.goal is other) == (t >= 0.2 - 1e-9)
            if abs(t - 0.3) < 1e-9:
                assert len(episode.kicks_applied) == 1
                dq = episode.kicks_applied[0]
                assert np.allclose(dq, dq[0]) and 0.0 < dq[0] <= 0.02
            episode.follow(command)
        assert not episode.kicks and not episode.changes and episode.outcome(t) is None
        assert set(executor.tracks.tracks) == {"forearm", "dragged"}
    finally:
        world.set_obstacles({})            # a shared world: leave it as it was

    sensor = Sensor((arm,), period_s=0.1, latency_s=0.04)
    assert sensor.frame(0.03, {}) is None                   # taken at 0, not delivered yet
    frame, stamp = sensor.frame(0.05, {"dragged": box})
    assert stamp == 0.0 and set(frame) == {"forearm"}        # dragged after it was taken
    assert np.allclose(frame["forearm"][1], arm.pose(0.0))
    assert sensor.frame(0.12, {"dragged": box}) is None
    frame, stamp = sensor.frame(0.33, {"dragged": box})      # frames 1-3 taken, 1-2 due
    assert stamp == pytest.approx(0.2) and set(frame) == {"forearm", "dragged"}


def test_react_flag_refuses_planning_options_and_a_taken_port(capsys):
    assert main(["view", "tabletop_pole", "--react", "--n-cases", "3"]) == 2
    assert "--n-cases is for planning in the viewer" in capsys.readouterr().err
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = s.getsockname()[1]
        assert main(["view", "tabletop_pole", "--react", "--port", str(port)]) == 2
        assert "already in use" in capsys.readouterr().err


# --- the browser -----------------------------------------------------------------------
def _canvas(img: np.ndarray) -> np.ndarray:
    return img[160:, :650]  # the 3D canvas, left of the GUI panel, below the notice


def _robot_pixels(img: np.ndarray) -> np.ndarray:
    """The robot's pixels on the canvas: its dark body and joints and the dark red of its
    links (the forearm's bright orange and the blue trace are neither)."""
    c = _canvas(img).astype(float)
    R, G, B = c[..., 0], c[..., 1], c[..., 2]
    return (c.mean(axis=2) < 90) | ((R < 180) & (R > 2 * G) & (R > 1.8 * B))


def _devtools_page(port: int, timeout_s: float) -> str | None:
    """The DevTools websocket of the browser's page on ``port``, or None."""
    t_end = time.monotonic() + timeout_s
    while time.monotonic() < t_end:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=2) as r:
                pages = [t for t in json.load(r) if t.get("type") == "page"]
            if pages:
                return str(pages[0]["webSocketDebuggerUrl"])
        except OSError:
            pass
        time.sleep(0.2)
    return None


def _screenshots(browser: str, url: str, tmp_path: Path, gap_s: float, tries: int,
                 done: Callable[[np.ndarray, np.ndarray], bool]
                 ) -> list[np.ndarray] | str:
    """Screenshots of ``url`` in headless chromium (DevTools protocol), the first once the
    robot is drawn, then one every ``gap_s`` until ``done(previous, latest)`` or ``tries`` more
    have been taken; or why none could be taken."""
    from PIL import Image
    from websockets.sync.client import connect

    port = free_port()
    log = tmp_path / "chromium.log"
    with log.open("w") as err:
        proc = subprocess.Popen(
            [browser, "--headless", "--no-sandbox", "--disable-dev-shm-usage",
             "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--hide-scrollbars",
             f"--user-data-dir={tmp_path / 'chromium'}", "--window-size=1000,700",
             f"--remote-debugging-port={port}", url],
            stdout=subprocess.DEVNULL, stderr=err)
    try:
        page = _devtools_page(port, 60)
        if page is None:
            return f"no DevTools page (rc {proc.poll()}): {log.read_text()[-400:]}"
        with connect(page, max_size=None, open_timeout=30) as ws:
            def shot() -> np.ndarray:
                ws.send(json.dumps({"id": 1, "method": "Page.captureScreenshot",
                                    "params": {"format": "png"}}))
                while (msg := json.loads(ws.recv(timeout=120))).get("id") != 1:
                    pass
                png = base64.b64decode(msg["result"]["data"])
                return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float)

            t_end = time.monotonic() + 150
            shots = [shot()]
            while (_canvas(shots[0]).std() <= 12 or _robot_pixels(shots[0]).sum() < 2000) \
                    and time.monotonic() < t_end:
                time.sleep(0.5)
                shots = [shot()]
            for _ in range(tries):
                time.sleep(gap_s)
                shots.append(shot())
                if done(shots[-2], shots[-1]):
                    break
            return shots
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()


def _robot_change(a: np.ndarray, b: np.ndarray) -> int:
    """Pixels that are the robot's in one screenshot and not in the other."""
    return int((_robot_pixels(a) ^ _robot_pixels(b)).sum())


def test_react_viewer_moves_the_arm_in_headless_chromium(viewer, tmp_path):
    browser = chromium()
    if browser is None:
        pytest.skip("no chromium on PATH (Debian: apt-get install -y chromium); "
                    "the browser test cannot run")
    # a second apart, several times: the arm rests between episodes (and, on a busy
    # machine, while the next one is prepared), so one pair may fall where it stands still
    shots = _screenshots(browser, viewer.url, tmp_path, gap_s=1.0, tries=12,
                         done=lambda a, b: _robot_change(a, b) > 100)
    if isinstance(shots, str):
        pytest.skip(f"chromium could not take a screenshot here: {shots}")
    first = shots[0]
    assert _canvas(first).std() > 12.0, f"blank screenshot (std {_canvas(first).std():.1f})"
    assert all(_robot_pixels(s).sum() > 2000 for s in shots), "no robot drawn"
    changed = [_robot_change(a, b) for a, b in itertools.pairwise(shots)]
    assert max(changed) > 100, f"the arm did not move between the screenshots ({changed} px)"
    assert viewer.loop.error is None
