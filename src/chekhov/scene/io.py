"""Scene files (YAML): load with validation, save, and the built-in scenes.

Every error names the file, the object and the field, e.g.
``kitchen.yaml: object 'sink_bottom': field 'size': expected 3 positive numbers, got [0.6, -1]``.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from chekhov.errors import SceneError
from chekhov.scene.grasps import generate_grasps, grasp_from_frame
from chekhov.scene.model import (
    OBJECT_CLASSES,
    SHAPE_KINDS,
    Articulation,
    Grasp,
    Pose,
    Region,
    Scene,
    SceneObject,
    Shape,
)
from chekhov.transforms import matrix_to_quat, rpy_to_matrix

SIZE_COUNT = {"box": 3, "cylinder": 2, "sphere": 1}
OBJECT_FIELDS = {"name", "class", "motion", "shape", "size", "pose", "grasps", "articulation"}
SCENE_FIELDS = {"name", "description", "robot", "base_pose", "objects", "regions", "format"}
FORMAT_VERSION = 1


class _Ctx:
    """Where we are in a file, for error messages."""

    def __init__(self, source: str) -> None:
        self.source, self.where = source, ""

    def fail(self, field: str, msg: str) -> SceneError:
        return SceneError(f"{self.source}:{self.where} field '{field}': {msg}")


def _numbers(ctx: _Ctx, field: str, v: Any, n: int, positive: bool = False) -> Any:
    """n finite floats as a tuple (typed Any: callers know n)."""
    ok = isinstance(v, list | tuple) and len(v) == n
    if ok:
        try:
            vals = tuple(float(x) for x in v)
        except (TypeError, ValueError):
            ok = False
    if not ok or not all(np.isfinite(vals)) or (positive and min(vals) <= 0):
        kind = "positive numbers" if positive else "numbers"
        raise ctx.fail(field, f"expected {n} {kind}, got {v!r}")
    return vals


def _pose(ctx: _Ctx, field: str, d: Any) -> Pose:
    if d is None:
        return Pose()
    if not isinstance(d, dict) or not set(d) <= {"xyz", "rpy", "quat"}:
        raise ctx.fail(field, f"expected a mapping with xyz and rpy or quat (w x y z), got {d!r}")
    if "rpy" in d and "quat" in d:
        raise ctx.fail(field, "give either rpy or quat, not both")
    xyz = _numbers(ctx, f"{field}.xyz", d.get("xyz", [0, 0, 0]), 3)
    if "quat" in d:
        q = np.array(_numbers(ctx, f"{field}.quat", d["quat"], 4))
        if abs(np.linalg.norm(q) - 1.0) > 1e-3:
            raise ctx.fail(f"{field}.quat", f"quaternion {list(q)} is not unit length")
        q = q / np.linalg.norm(q)
    else:
        q = matrix_to_quat(rpy_to_matrix(_numbers(ctx, f"{field}.rpy", d.get("rpy", [0, 0, 0]), 3)))
    return Pose(xyz, (float(q[0]), float(q[1]), float(q[2]), float(q[3])))


def _grasps(ctx: _Ctx, shape: Shape, spec: Any) -> tuple[Grasp, ...]:
    if spec is None:
        return ()
    if not isinstance(spec, list):
        raise ctx.fail("grasps", "expected a list of grasps or {generate: {...}} entries")
    out: list[Grasp] = []
    for i, g in enumerate(spec):
        f = f"grasps[{i}]"
        if not isinstance(g, dict):
            raise ctx.fail(f, f"expected a mapping, got {g!r}")
        if "generate" in g:
            gen = g["generate"] or {}
            if not isinstance(gen, dict) or not set(gen) <= {"approaches", "standoff", "depth"}:
                raise ctx.fail(f"{f}.generate", "expected approaches, standoff, depth")
            try:
                out += generate_grasps(shape, tuple(gen.get("approaches", ("top",))),
                                       float(gen.get("standoff", 0.1)),
                                       float(gen.get("depth", 0.02)))
            except ValueError as e:
                raise ctx.fail(f"{f}.generate", str(e)) from e
        elif "grasp" in g:
            if not set(g) <= {"name", "grasp", "pregrasp"}:
                raise ctx.fail(f, f"unknown keys {sorted(set(g) - {'name', 'grasp', 'pregrasp'})}")
            out.append(Grasp(str(g.get("name", f"grasp{i}")),
                             _pose(ctx, f"{f}.grasp", g["grasp"]).T,
                             _pose(ctx, f"{f}.pregrasp", g.get("pregrasp", g["grasp"])).T))
        else:
            standoff = float(g.get("standoff", 0.1))
            frame = _pose(ctx, f, {k: v for k, v in g.items() if k in ("xyz", "rpy", "quat")})
            out.append(grasp_from_frame(str(g.get("name", f"grasp{i}")), frame.T, standoff))
    names = [g.name for g in out]
    if len(set(names)) != len(names):
        raise ctx.fail("grasps", f"duplicate grasp names {names}")
    return tuple(out)


def _articulation(ctx: _Ctx, d: Any) -> Articulation | None:
    if d is None:
        return None
    keys = {"type", "axis", "origin", "states", "state"}
    if not isinstance(d, dict) or not set(d) <= keys:
        raise ctx.fail("articulation", f"expected a mapping with keys {sorted(keys)}, got {d!r}")
    kind = d.get("type")
    if kind not in ("hinge", "slide"):
        raise ctx.fail("articulation.type", f"expected 'hinge' or 'slide', got {kind!r}")
    axis = _numbers(ctx, "articulation.axis", d.get("axis"), 3)
    if np.linalg.norm(axis) < 1e-9:
        raise ctx.fail("articulation.axis", "axis must be non-zero")
    states = d.get("states")
    if not isinstance(states, dict) or not states:
        raise ctx.fail("articulation.states", f"expected a mapping name -> value, got {states!r}")
    state = str(d.get("state", next(iter(states))))
    if state not in states:
        raise ctx.fail("articulation.state", f"'{state}' is not one of {sorted(states)}")
    return Articulation(kind, axis, _numbers(ctx, "articulation.origin", d.get("origin", [0, 0, 0]),
                                             3),
                        tuple((str(k), float(v)) for k, v in states.items()), state)


def _object(ctx: _Ctx, d: Any, index: int) -> SceneObject:
    if not isinstance(d, dict):
        raise SceneError(f"{ctx.source}: objects[{index}]: expected a mapping, got {d!r}")
    name = d.get("name")
    if not isinstance(name, str) or not name:
        raise SceneError(f"{ctx.source}: objects[{index}]: field 'name': missing or empty")
    ctx.where = f" object '{name}':"
    unknown = set(d) - OBJECT_FIELDS
    if unknown:
        raise ctx.fail(sorted(unknown)[0], f"unknown field; known: {sorted(OBJECT_FIELDS)}")
    kind = d.get("shape")
    if kind not in SHAPE_KINDS:
        raise ctx.fail("shape", f"expected one of {list(SHAPE_KINDS)}, got {kind!r}")
    shape = Shape(kind, _numbers(ctx, "size", d.get("size"), SIZE_COUNT[kind], positive=True))
    cls = d.get("class", "object")
    if cls not in OBJECT_CLASSES:
        raise ctx.fail("class", f"unknown class {cls!r}; known: {list(OBJECT_CLASSES)}")
    motion = d.get("motion", "static")
    if motion not in ("static", "dynamic"):
        raise ctx.fail("motion", f"expected 'static' or 'dynamic', got {motion!r}")
    obj = SceneObject(name, shape, _pose(ctx, "pose", d.get("pose")), cls, motion == "dynamic",
                      _grasps(ctx, shape, d.get("grasps")),
                      _articulation(ctx, d.get("articulation")))
    ctx.where = ""
    return obj


def scene_from_dict(d: Any, source: str = "<dict>") -> Scene:
    """Validate a parsed scene mapping and build a :class:`Scene`."""
    ctx = _Ctx(source)
    if not isinstance(d, dict):
        raise SceneError(f"{source}: expected a mapping at top level, got {type(d).__name__}")
    unknown = set(d) - SCENE_FIELDS
    if unknown:
        raise ctx.fail(sorted(unknown)[0], f"unknown field; known: {sorted(SCENE_FIELDS)}")
    if d.get("format", FORMAT_VERSION) != FORMAT_VERSION:
        raise ctx.fail("format", f"unsupported scene format {d.get('format')!r}; "
                                 f"this chekhov reads {FORMAT_VERSION}")
    name = d.get("name")
    if not isinstance(name, str) or not name:
        raise ctx.fail("name", "missing or empty")
    objs = d.get("objects")
    if not isinstance(objs, list) or not objs:
        raise ctx.fail("objects", "expected a non-empty list of objects")
    objects = tuple(_object(ctx, o, i) for i, o in enumerate(objs))
    names = [o.name for o in objects]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ctx.fail("objects", f"duplicate object names {dup}")
    regions = []
    for i, r in enumerate(d.get("regions") or []):
        ctx.where = f" regions[{i}]:"
        if not isinstance(r, dict) or not set(r) <= {"name", "center", "size", "weight"}:
            raise ctx.fail("regions", f"expected name, center, size, weight; got {r!r}")
        w = float(r.get("weight", 1.0))
        if not np.isfinite(w) or w < 0:
            raise ctx.fail("weight", f"expected a non-negative number, got {r.get('weight')!r}")
        regions.append(Region(str(r.get("name", f"region{i}")),
                              _numbers(ctx, "center", r.get("center"), 3),
                              _numbers(ctx, "size", r.get("size"), 3, positive=True), w))
    ctx.where = ""
    base = _pose(ctx, "base_pose", d["base_pose"]) if "base_pose" in d else None
    return Scene(name=name, objects=objects, regions=tuple(regions),
                 robot=str(d.get("robot", "baxter_left")), base_pose=base,
                 description=str(d.get("description", "")), source=source)


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
    out["objects"] = objects
    out["regions"] = [{"name": r.name, "center": list(r.center), "size": list(r.size),
                       "weight": r.weight} for r in scene.regions]
    return out


def load_scene(name_or_path: str | Path) -> Scene:
    """A built-in scene by name (see :func:`builtin_scenes`) or a scene YAML file."""
    path = Path(name_or_path)
    if not path.suffix:
        builtin = resources.files("chekhov.scene") / "data" / f"{name_or_path}.yaml"
        if not builtin.is_file():
            raise SceneError(f"no built-in scene '{name_or_path}'; available: {builtin_scenes()}"
                             " (or give a path to a .yaml file)")
        path = Path(str(builtin))
    try:
        d = yaml.safe_load(path.read_text())
    except OSError as e:
        raise SceneError(f"{path}: cannot read scene file: {e.strerror}") from e
    except yaml.YAMLError as e:
        raise SceneError(f"{path}: not valid YAML: {e}") from e
    return scene_from_dict(d, source=path.name)


def save_scene(scene: Scene, path: str | Path) -> None:
    """Write ``scene`` as YAML, atomically (a temporary file renamed into place)."""
    write_atomic(Path(path), lambda f: yaml.safe_dump(scene_to_dict(scene), f, sort_keys=False))


def write_atomic(path: Path, write: Callable[[Any], None], mode: str = "w") -> None:
    """Call ``write(file)`` on a temporary file next to ``path``, then rename it into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, mode) as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def builtin_scenes() -> list[str]:
    """Names of the scenes shipped with chekhov."""
    files = resources.files("chekhov.scene") / "data"
    return sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".yaml"))
