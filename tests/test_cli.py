import subprocess
import sys

import pytest

from chekhov.cli import main


def test_scenes_lists_four(capsys):
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out
    for name in ("tabletop_pole", "tabletop_container", "kitchen", "shelf_boxes"):
        assert name in out


def test_show_writes_png(tmp_path):
    out = tmp_path / "s.png"
    rc = subprocess.run([sys.executable, "-m", "chekhov.cli", "show", "tabletop_pole", "--q",
                         "0.2", "-0.5", "0", "1.2", "0", "0.8", "0", "--out", str(out)],
                        capture_output=True, text=True, timeout=300)
    assert rc.returncode == 0, rc.stderr
    assert "q free" in rc.stdout
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000


def test_show_plans_a_case_with_a_registry_planner(tmp_path, monkeypatch, capsys):
    """``show --case`` takes any registry planner (aliases too), not only the viewer's menu."""
    from chekhov.cases import generate_cases
    from chekhov.world import World

    cases = tmp_path / "c.npz"
    generate_cases(World.load("tabletop_pole"), 1, seed=3).save(cases)
    out = tmp_path / "case.png"
    assert main(["show", "tabletop_pole", "--case", "0", "--cases", str(cases), "--planner",
                 "lazyprm+trajopt", "--out", str(out)]) == 0
    assert "LazyPRM+TrajOpt case 0" in capsys.readouterr().out
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["show", "tabletop_pole", "--case", "0", "--planner", "Nope"]) == 2
    assert "--planner: unknown planner 'Nope'" in capsys.readouterr().err


def test_bad_input_gets_a_clear_error(capsys):
    assert main(["show", "tabletop_pole", "--q", "1", "2"]) == 2
    assert "expected 7 joint values" in capsys.readouterr().err
    assert main(["show", "no_such_scene"]) == 2
    assert "no built-in scene" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["--help"]])
def test_help(argv):
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 0
