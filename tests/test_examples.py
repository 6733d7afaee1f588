"""The numbered examples run and say what they promise."""

import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).parents[1] / "examples"


def _run(name, *args):
    out = subprocess.run([sys.executable, str(EXAMPLES / name), *map(str, args)],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_plan_example_answers_certified():
    assert _run("00_plan.py").startswith("solved ")


def test_timed_trajectory_example_writes_its_plot(tmp_path):
    png = tmp_path / "t.png"
    stdout = _run("04_timed_trajectory.py", png)
    assert stdout.startswith("solved: ") and png.stat().st_size > 10_000


def test_dynamic_obstacle_example_replans_around_the_forearm():
    stdout = _run("02_dynamic_obstacle.py")
    assert stdout.startswith("before: solved") and "blocks it: True; after: solved" in stdout


def test_anytime_example_hears_its_solutions_in_order():
    stdout = _run("05_anytime.py")
    lines = stdout.splitlines()
    heard = [ln for ln in lines if ln.strip().endswith((
        "roadmap_seed", "shortcut", "routes", "optimise", "straight_line", "retry"))]
    assert heard and lines[-1].startswith("solved: first answer after")
    times = [float(ln.split()[0]) for ln in heard]
    lengths = [float(ln.split()[2]) for ln in heard]
    assert times == sorted(times) and lengths == sorted(lengths, reverse=True)


def test_react_example_reaches_its_goal_without_contact(tmp_path):
    png = tmp_path / "react.png"
    stdout = _run("06_react.py", png, 1)
    assert stdout.startswith("reached: True") and "collision: False" in stdout
    assert "limit violations: 0" in stdout and png.stat().st_size > 10_000
