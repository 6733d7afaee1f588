"""The layering of src/chekhov (docs/architecture.md): no import cycles, no upward imports."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "check_layers.py"


def _checker() -> ModuleType:
    spec = importlib.util.spec_from_file_location("check_layers", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("check_layers", module)
    spec.loader.exec_module(module)
    return module


def test_chekhov_has_no_cycles_or_upward_imports() -> None:
    assert _checker().problems() == []


def _write(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        p = root / "chekhov" / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return root


def test_checker_finds_cycles_upward_and_sideways_imports(tmp_path: Path) -> None:
    src = _write(tmp_path, {
        "__init__.py": "",
        "errors.py": "def f():\n    from chekhov.collision import fast\n",  # upward, in a function
        "collision/__init__.py": "",
        "collision/fast.py": "from . import exact\n",
        "collision/exact.py": "from chekhov.collision.fast import x\n",       # cycle
        "bench/__init__.py": "", "bench/cases.py": "",
        "viewer/__init__.py": "", "viewer/app.py": "from chekhov.bench import cases\n",
        "roadmap/__init__.py": "",
        "roadmap/a.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                        "    from chekhov.roadmap.b import B\n",
        "roadmap/b.py": "from chekhov.roadmap.a import A\n",  # a cycle, if only in types
    })
    found = _checker().problems(src)
    assert len(found) == 4, found
    assert "import cycle: chekhov.roadmap.a <-> chekhov.roadmap.b" in found
    assert any("upward import: chekhov.errors" in f and "chekhov.collision.fast" in f
               for f in found)
    assert any("sideways import: chekhov.viewer.app" in f for f in found)
    assert "import cycle: chekhov.collision.exact <-> chekhov.collision.fast" in found
