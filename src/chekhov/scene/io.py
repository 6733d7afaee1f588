"""Scene files (YAML): load with validation, save, and the built-in scenes.

Reading is bounded (size, nodes after alias expansion, depth, duplicate keys: see
:mod:`chekhov.scene.safe_yaml`) and every field is checked (:mod:`chekhov.scene.validate`);
every error is a :class:`SceneError` naming the file, the object and the field, e.g.
``kitchen.yaml: object 'sink_bottom': field 'size': expected 3 positive numbers, got [0.6, -1]``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from chekhov.atomic import write_atomic
from chekhov.errors import SceneError
from chekhov.scene.model import Scene
from chekhov.scene.safe_yaml import read_yaml
from chekhov.scene.validate import FORMAT_VERSION, scene_from_dict
from chekhov.transforms import matrix_to_quat

__all__ = ["builtin_scenes", "load_scene", "save_scene", "scene_from_dict", "scene_to_dict"]


def _pose_dict(T: np.ndarray) -> dict[str, list[float]]:
    q = matrix_to_quat(T[:3, :3])
    return {"xyz": [round(float(x), 9) for x in T[:3, 3]], "quat": [round(float(x), 12) for x in q]}


def scene_to_dict(scene: Scene) -> dict[str, Any]:
    """A plain mapping that :func:`scene_from_dict` turns back into an equal scene."""
    objects = []
    for o in scene.objects:
        d: dict[str, Any] = {"name": o.name, "class": o.cls,
                             "motion": "dynamic" if o.dynamic else "static",
                             "shape": o.shape.kind, "size": list(o.shape.size),
                             "pose": {"xyz": list(o.pose.xyz), "quat": list(o.pose.quat_wxyz)}}
        if o.grasps:
            d["grasps"] = [{"name": g.name, "grasp": _pose_dict(g.T_obj_grasp),
                            "pregrasp": _pose_dict(g.T_obj_pregrasp)} for g in o.grasps]
        if o.articulation is not None:
            a = o.articulation
            d["articulation"] = {"type": a.kind, "axis": list(a.axis), "origin": list(a.origin),
                                 "states": dict(a.states), "state": a.state}
        objects.append(d)
    out: dict[str, Any] = {"format": FORMAT_VERSION, "name": scene.name,
                           "description": scene.description, "robot": scene.robot}
    if scene.base_pose is not None:
        out["base_pose"] = {"xyz": list(scene.base_pose.xyz),
                            "quat": list(scene.base_pose.quat_wxyz)}
    if scene.locked_joints:
        out["locked_joints"] = dict(scene.locked_joints)
    out["objects"] = objects
    out["regions"] = [{"name": r.name, "center": list(r.center), "size": list(r.size),
                       "weight": r.weight} for r in scene.regions]
    return out


def load_scene(name_or_path: str | Path) -> Scene:
    """A built-in scene by name (see :func:`builtin_scenes`) or a scene YAML file."""
    path = Path(name_or_path)
    if not path.suffix:
        if str(name_or_path) not in builtin_scenes():
            raise SceneError(f"no built-in scene {str(name_or_path)!r}; available: "
                             f"{builtin_scenes()} (or give a path to a .yaml file)")
        path = Path(str(resources.files("chekhov.scene") / "data" / f"{name_or_path}.yaml"))
    return scene_from_dict(read_yaml(path, path.name), source=path.name)


def save_scene(scene: Scene, path: str | Path) -> None:
    """Write ``scene`` as YAML, atomically (a temporary file renamed into place)."""
    write_atomic(Path(path), lambda f: yaml.safe_dump(scene_to_dict(scene), f, sort_keys=False))




def builtin_scenes() -> list[str]:
    """Names of the scenes shipped with chekhov."""
    files = resources.files("chekhov.scene") / "data"
    return sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".yaml"))
