"""Scene files (YAML): load with validation, save, and the built-in scenes.

Reading is bounded (size, nodes after alias expansion, depth, duplicate keys: see
:mod:`chekhov.scene.safe_yaml`) and every field is checked (:mod:`chekhov.scene.validate`);
every error is a :class:`SceneError` naming the file, the object and the field, e.g.
``kitchen.yaml: object 'sink_bottom': field 'size': expected 3 positive numbers, got [0.6, -1]``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import yaml

from chekhov.atomic import write_atomic
from chekhov.errors import SceneError
from chekhov.scene.model import Scene, scene_to_dict
from chekhov.scene.safe_yaml import read_yaml
from chekhov.scene.validate import scene_from_dict

__all__ = ["builtin_scenes", "load_scene", "save_scene", "scene_from_dict", "scene_to_dict"]


def load_scene(name_or_path: str | Path) -> Scene:
    """A built-in scene by name (see :func:`builtin_scenes`) or a scene YAML file."""
    path = Path(name_or_path)
    if not path.suffix:
        if str(name_or_path) not in builtin_scenes():
            raise SceneError(f"no built-in scene {str(name_or_path)!r}; available: "
                             f"{builtin_scenes()} (or give a path to a .yaml file)")
        path = Path(str(resources.files("chekhov.scene") / "data" / f"{name_or_path}.yaml"))
    return scene_from_dict(read_yaml(path, path.name), source=path.name,
                           base_dir=path.expanduser().resolve().parent)


def save_scene(scene: Scene, path: str | Path) -> None:
    """Write ``scene`` as YAML, atomically (a temporary file renamed into place)."""
    write_atomic(Path(path), lambda f: yaml.safe_dump(scene_to_dict(scene), f, sort_keys=False))




def builtin_scenes() -> list[str]:
    """Names of the scenes shipped with chekhov."""
    files = resources.files("chekhov.scene") / "data"
    return sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".yaml"))
