"""Write the README's pictures to docs/images/: each built-in scene with the robot at the start
of a case, one optimised Roadmap + TrajOpt plan (robot ghosts along the trajectory, its seed),
and, where headless Chromium is installed, a screenshot of the interactive viewer.

    python scripts/make_pictures.py [--out docs/images] [--no-viewer]

Deterministic: cached cases (seed 0) and the cached roadmaps (built when missing).
"""

from __future__ import annotations

import argparse
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from chekhov.bench.cases import cached_cases
from chekhov.planners.base import path_length
from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
from chekhov.roadmap.io import load_or_build_roadmap
from chekhov.scene.io import builtin_scenes
from chekhov.viewer.planning import ee_length
from chekhov.viewer.render import render_scene
from chekhov.world import World

PLAN_SCENE = "shelf_boxes"


def scene_pictures(out: Path) -> None:
    for name in builtin_scenes():
        world = World.load(name)
        q = cached_cases(world, 20).q_start[0]
        png = render_scene(world, q=q, out=out / f"scene_{name}.png", title=name)
        print(f"wrote {png}")


def plan_picture(out: Path, n_cases: int = 20) -> None:
    """The solved case with the longest end-effector travel among the first n_cases."""
    world = World.load(PLAN_SCENE)
    planner = RoadmapTrajOpt(world, load_or_build_roadmap(world))
    cases = cached_cases(world, n_cases)
    best = None
    for i in range(len(cases)):
        r = planner.plan(cases.q_start[i], cases.goal(i))
        if not r.success or r.path is None or r.info.get("fallback_to_seed"):
            continue
        travel = ee_length(world.robot.compute_ee_poses(r.path)[:, :3, 3])
        if best is None or travel > best[0]:
            best = (travel, i, r)
    if best is None:
        raise SystemExit(f"no case of {PLAN_SCENE} solved")
    _, i, r = best
    seed = np.asarray(r.info["roadmap_seed"])
    title = (f"{PLAN_SCENE}, case {i}: Roadmap + TrajOpt, {1e3 * r.time_s:.0f} ms, "
             f"{r.path_length:.2f} rad (roadmap seed {path_length(seed):.2f} rad)")
    png = render_scene(world, path=r.path, seed=seed, ghosts=7,
                       out=out / f"plan_{PLAN_SCENE}.png", title=title)
    print(f"wrote {png}")


def viewer_screenshot(out: Path, scene: str = "tabletop_pole") -> None:
    browser = next((b for b in ("chromium", "chromium-browser") if shutil.which(b)), None)
    if browser is None:
        print("no chromium: skipping the viewer screenshot")
        return
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = subprocess.Popen([sys.executable, "-m", "chekhov.cli", "view", scene, "--port",
                             str(port)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    try:
        assert proc.stdout is not None
        t_end = time.monotonic() + 300
        while time.monotonic() < t_end:
            line = proc.stdout.readline()
            if line.startswith("chekhov viewer:") or (not line and proc.poll() is not None):
                break
        with tempfile.TemporaryDirectory() as profile:
            png = out / "viewer.png"
            subprocess.run([browser, "--headless", "--no-sandbox", "--use-angle=swiftshader",
                            "--enable-unsafe-swiftshader", "--hide-scrollbars",
                            f"--user-data-dir={profile}", f"--screenshot={png}",
                            "--window-size=1400,900", "--virtual-time-budget=30000",
                            f"http://127.0.0.1:{port}/"], capture_output=True, timeout=180)
        print(f"wrote {png}")
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/images", help="folder for the PNGs")
    ap.add_argument("--no-viewer", action="store_true", help="skip the viewer screenshot")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    scene_pictures(out)
    plan_picture(out)
    if not args.no_viewer:
        viewer_screenshot(out)


if __name__ == "__main__":
    main()
