"""A parsed scene mapping → :class:`Scene`, every field checked.

Every error is a :class:`SceneError` naming the file, the object and the field, e.g.
``kitchen.yaml: object 'sink_bottom': field 'size': expected 3 positive numbers, got [0.6, -1]``.

Rules beyond the README's format: numbers are ints or floats (not booleans, not text), finite,
and at most ``MAX_LENGTH`` in size (m, or rad for angles and hinge states); every object needs
a ``pose`` with ``xyz`` (no silent world origin); names are 1–100 characters of letters, digits,
``_``, ``.`` and ``-`` not starting with ``.`` or ``-`` (a scene name becomes a roadmap file
name); ``robot`` names a built-in robot or a robot description file (``.yaml`` / ``.yml``,
relative to the scene file's folder; kept as an absolute path); a scene holds at most
``MAX_OBJECTS`` objects, ``MAX_REGIONS`` regions, ``MAX_GRASPS`` grasps an object and
``MAX_STATES`` articulation states.
"""

from __future__ import annotations

import numbers
import re
import reprlib
from collections import Counter
from pathlib import Path
from typing import Any, Literal, cast

import numpy as np

from chekhov.errors import SceneError
from chekhov.robot.description import builtin_robots
from chekhov.scene.grasps import APPROACHES, generate_grasps, grasp_from_frame
from chekhov.scene.model import (
    FORMAT_VERSION,
    OBJECT_CLASSES,
    SHAPE_KINDS,
    Articulation,
    Grasp,
    Pose,
    Region,
    Scene,
    SceneObject,
    Shape,
    ShapeKind,
)
from chekhov.transforms import matrix_to_quat, rpy_to_matrix

SIZE_COUNT = {"box": 3, "cylinder": 2, "sphere": 1}
OBJECT_FIELDS = {"name", "class", "motion", "shape", "size", "pose", "grasps", "articulation"}
MAX_LOCKED = 200
SCENE_FIELDS = {"name", "description", "robot", "base_pose", "locked_joints", "objects", "regions",
                "format"}
REGION_FIELDS = {"name", "center", "size", "weight"}
MAX_LENGTH = 1000.0  # m (rad): largest coordinate, size, standoff, depth, angle, state value
MAX_WEIGHT = 1e6
MAX_OBJECTS = 1000
MAX_REGIONS = 200
MAX_GRASPS = 200
MAX_STATES = 32
MAX_DESCRIPTION = 10_000  # characters
MAX_PATH = 4096  # characters of a robot file's path
NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]{0,99}")

_REPR = reprlib.Repr()
_REPR.maxstring, _REPR.maxother, _REPR.maxlevel = 60, 60, 3


def show(v: Any) -> str:
    """A short repr for messages (bounded for huge, deep or odd values)."""
    try:
        return _REPR.repr(v)
    except Exception:  # a repr that fails (5000-digit int, broken __repr__)
        return f"<{type(v).__name__}>"


class _Ctx:
    """Where we are in a file, for error messages."""

    def __init__(self, source: str) -> None:
        self.source, self.where = source, ""

    def fail(self, field: Any, msg: str) -> SceneError:
        name = field if isinstance(field, str) else show(field)
        return SceneError(f"{self.source}:{self.where} field '{name}': {msg}")


def _is_number(x: Any) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool | np.bool_)


def _number(ctx: _Ctx, field: str, v: Any, lo: float = -MAX_LENGTH, hi: float = MAX_LENGTH
            ) -> float:
    """One int or float in [lo, hi] (NaN and inf never are)."""
    if _is_number(v):
        try:
            f = float(v)
        except (OverflowError, ValueError, TypeError):
            f = np.nan
        if lo <= f <= hi:
            return f
    raise ctx.fail(field, f"expected a number from {lo:g} to {hi:g}, got {show(v)}")


def _numbers(ctx: _Ctx, field: str, v: Any, n: int, positive: bool = False) -> Any:
    """n finite numbers of magnitude at most MAX_LENGTH as a tuple of floats (typed Any:
    callers know n)."""
    kind = "positive numbers" if positive else "numbers"
    ok = (isinstance(v, list | tuple) or (isinstance(v, np.ndarray) and v.ndim == 1)) \
        and len(v) == n and all(_is_number(x) for x in v)
    if ok:
        try:
            vals = tuple(float(x) for x in v)
        except (OverflowError, ValueError, TypeError):
            ok = False
    if not ok:
        raise ctx.fail(field, f"expected {n} {kind}, got {show(v)}")
    if not all(np.isfinite(vals)) or max(abs(x) for x in vals) > MAX_LENGTH:
        raise ctx.fail(field, f"expected {n} finite {kind} of magnitude at most {MAX_LENGTH:g}, "
                              f"got {show(v)}")
    if positive and min(vals) <= 0:
        raise ctx.fail(field, f"expected {n} {kind}, got {show(v)}")
    return vals


def _name(ctx: _Ctx, field: str, v: Any) -> str:
    if not isinstance(v, str) or not NAME.fullmatch(v):
        raise ctx.fail(field, "expected a name of 1-100 letters, digits, '_', '.', '-' (not "
                              f"starting with '.' or '-'), got {show(v)}")
    return v


def _choice(ctx: _Ctx, field: str, v: Any, options: tuple[str, ...] | list[str]) -> str:
    if not isinstance(v, str) or v not in options:
        raise ctx.fail(field, f"expected one of {list(options)}, got {show(v)}")
    return v


def _mapping(ctx: _Ctx, field: str, d: Any, keys: set[str], what: str) -> dict[Any, Any]:
    """``d`` as a mapping whose keys are among ``keys``."""
    if not isinstance(d, dict):
        raise ctx.fail(field, f"expected a mapping with {what}, got {show(d)}")
    unknown = [k for k in d if k not in keys]
    if unknown:
        raise ctx.fail(field, f"unknown key {show(unknown[0])}; known: {sorted(keys)}")
    return d


def _list(ctx: _Ctx, field: str, v: Any, most: int, what: str) -> list[Any]:
    if not isinstance(v, list | tuple):
        raise ctx.fail(field, f"expected a list of {what}, got {show(v)}")
    if len(v) > most:
        raise ctx.fail(field, f"{len(v)} {what}; at most {most} are allowed")
    return list(v)


def _pose(ctx: _Ctx, field: str, d: Any) -> Pose:
    """{xyz, rpy | quat}: xyz required (m), rpy (rad) or unit quaternion (w x y z) optional."""
    _mapping(ctx, field, d, {"xyz", "rpy", "quat"}, "xyz and rpy or quat (w x y z)")
    if "xyz" not in d:
        raise ctx.fail(f"{field}.xyz", "missing (write xyz: [0, 0, 0] for the origin)")
    if "rpy" in d and "quat" in d:
        raise ctx.fail(field, "give either rpy or quat, not both")
    xyz = _numbers(ctx, f"{field}.xyz", d["xyz"], 3)
    if "quat" in d:
        q = np.array(_numbers(ctx, f"{field}.quat", d["quat"], 4))
        if abs(np.linalg.norm(q) - 1.0) > 1e-3:
            raise ctx.fail(f"{field}.quat", f"quaternion {list(q)} is not unit length")
        q = q / np.linalg.norm(q)
    else:
        q = matrix_to_quat(rpy_to_matrix(_numbers(ctx, f"{field}.rpy", d.get("rpy", [0, 0, 0]),
                                                  3)))
    return Pose(xyz, (float(q[0]), float(q[1]), float(q[2]), float(q[3])))


def _generated(ctx: _Ctx, f: str, shape: Shape, g: dict[Any, Any]) -> list[Grasp]:
    """A ``{generate: {approaches, standoff, depth}}`` entry: one grasp per approach."""
    _mapping(ctx, f, g, {"generate"}, "generate")
    gen = {} if g["generate"] is None else g["generate"]
    _mapping(ctx, f"{f}.generate", gen, {"approaches", "standoff", "depth"},
             "approaches, standoff, depth")
    approaches = _list(ctx, f"{f}.generate.approaches", gen.get("approaches", ["top"]),
                       len(APPROACHES), "approaches")
    for a in approaches:
        _choice(ctx, f"{f}.generate.approaches", a, sorted(APPROACHES))
    if not approaches or len(set(approaches)) != len(approaches):
        raise ctx.fail(f"{f}.generate.approaches",
                       f"expected distinct approaches, got {show(approaches)}")
    standoff = _number(ctx, f"{f}.generate.standoff", gen.get("standoff", 0.1), 0.0)
    depth = _number(ctx, f"{f}.generate.depth", gen.get("depth", 0.02), 0.0)
    return generate_grasps(shape, tuple(approaches), standoff, depth)


def _grasps(ctx: _Ctx, shape: Shape, spec: Any) -> tuple[Grasp, ...]:
    if spec is None:
        return ()
    entries = _list(ctx, "grasps", spec, MAX_GRASPS, "grasps or {generate: {...}} entries")
    out: list[Grasp] = []
    for i, g in enumerate(entries):
        f = f"grasps[{i}]"
        if not isinstance(g, dict):
            raise ctx.fail(f, f"expected a mapping, got {show(g)}")
        if "generate" in g:
            out += _generated(ctx, f, shape, g)
            continue
        name = _name(ctx, f"{f}.name", g["name"]) if "name" in g else f"grasp{i}"
        if "grasp" in g:
            _mapping(ctx, f, g, {"name", "grasp", "pregrasp"}, "name, grasp, pregrasp")
            T = _pose(ctx, f"{f}.grasp", g["grasp"]).T
            pre = _pose(ctx, f"{f}.pregrasp", g["pregrasp"]).T if "pregrasp" in g else T
            out.append(Grasp(name, T, pre))
        else:
            _mapping(ctx, f, g, {"name", "xyz", "rpy", "quat", "standoff"},
                     "name, xyz, rpy or quat, standoff (or grasp/pregrasp, or generate)")
            standoff = _number(ctx, f"{f}.standoff", g.get("standoff", 0.1), 0.0)
            frame = _pose(ctx, f, {k: v for k, v in g.items() if k in ("xyz", "rpy", "quat")})
            out.append(grasp_from_frame(name, frame.T, standoff))
    names = [g.name for g in out]
    if len(out) > MAX_GRASPS or len(set(names)) != len(names):
        raise ctx.fail("grasps", f"expected at most {MAX_GRASPS} grasps with distinct names, "
                                 f"got {show(names)}")
    return tuple(out)


def _articulation(ctx: _Ctx, d: Any) -> Articulation | None:
    if d is None:
        return None
    keys = {"type", "axis", "origin", "states", "state"}
    _mapping(ctx, "articulation", d, keys, f"keys {sorted(keys)}")
    kind = _choice(ctx, "articulation.type", d.get("type"), ("hinge", "slide"))
    axis = _numbers(ctx, "articulation.axis", d.get("axis"), 3)
    if np.linalg.norm(axis) < 1e-9:
        raise ctx.fail("articulation.axis", "axis must be non-zero")
    origin = _numbers(ctx, "articulation.origin", d.get("origin", [0, 0, 0]), 3)
    states = d.get("states")
    if not isinstance(states, dict) or not 0 < len(states) <= MAX_STATES:
        raise ctx.fail("articulation.states", f"expected a mapping of 1 to {MAX_STATES} "
                                              f"name -> value (rad or m), got {show(states)}")
    values = tuple((_name(ctx, "articulation.states", k),
                    _number(ctx, f"articulation.states.{k}", v)) for k, v in states.items())
    state = d.get("state", values[0][0])
    if not isinstance(state, str) or state not in states:
        raise ctx.fail("articulation.state", f"{show(state)} is not one of {sorted(states)}")
    return Articulation(cast(Literal["hinge", "slide"], kind), axis, origin, values, state)


def _object(ctx: _Ctx, d: Any, index: int) -> SceneObject:
    ctx.where = f" objects[{index}]:"
    if not isinstance(d, dict):
        raise SceneError(f"{ctx.source}: objects[{index}]: expected a mapping, got {show(d)}")
    name = _name(ctx, "name", d.get("name"))
    ctx.where = f" object '{name}':"
    unknown = [k for k in d if k not in OBJECT_FIELDS]
    if unknown:
        raise ctx.fail(unknown[0], f"unknown field; known: {sorted(OBJECT_FIELDS)}")
    kind = _choice(ctx, "shape", d.get("shape"), SHAPE_KINDS)
    size = _numbers(ctx, "size", d.get("size"), SIZE_COUNT[kind], positive=True)
    shape = Shape(cast(ShapeKind, kind), size)
    cls = _choice(ctx, "class", d.get("class", "object"), OBJECT_CLASSES)
    motion = _choice(ctx, "motion", d.get("motion", "static"), ("static", "dynamic"))
    if "pose" not in d:
        raise ctx.fail("pose", "missing (write pose: {xyz: [0, 0, 0]} for the world origin)")
    obj = SceneObject(name, shape, _pose(ctx, "pose", d["pose"]), cls, motion == "dynamic",
                      _grasps(ctx, shape, d.get("grasps")),
                      _articulation(ctx, d.get("articulation")))
    ctx.where = ""
    return obj


def _regions(ctx: _Ctx, spec: Any) -> tuple[Region, ...]:
    if spec is None:
        return ()
    regions = []
    for i, r in enumerate(_list(ctx, "regions", spec, MAX_REGIONS, "regions")):
        ctx.where = f" regions[{i}]:"
        _mapping(ctx, "regions", r, REGION_FIELDS, "name, center, size, weight")
        regions.append(Region(_name(ctx, "name", r["name"]) if "name" in r else f"region{i}",
                              _numbers(ctx, "center", r.get("center"), 3),
                              _numbers(ctx, "size", r.get("size"), 3, positive=True),
                              _number(ctx, "weight", r.get("weight", 1.0), 0.0, MAX_WEIGHT)))
    ctx.where = ""
    dup = sorted(n for n, c in Counter(r.name for r in regions).items() if c > 1)
    if dup:
        raise ctx.fail("regions", f"duplicate region names {dup}")
    return tuple(regions)


def _robot(ctx: _Ctx, v: Any, base_dir: Path | None) -> str:
    """``robot``: a built-in robot's name, or the absolute path of an existing robot
    description file (``.yaml`` / ``.yml``, relative to ``base_dir``, else the working
    folder)."""
    if isinstance(v, str) and v in builtin_robots():
        return v
    if isinstance(v, str) and v.endswith((".yaml", ".yml")) and len(v) <= MAX_PATH:
        path = Path(v).expanduser()
        path = path if path.is_absolute() else (base_dir or Path.cwd()) / path
        if not path.is_file():
            raise ctx.fail("robot", f"no robot description file at {path}")
        return str(path.resolve())
    raise ctx.fail("robot", f"expected one of {builtin_robots()} or a robot description file "
                            f"(.yaml), got {show(v)}")


def _header(ctx: _Ctx, d: Any, base_dir: Path | None = None) -> tuple[str, str, str]:
    """Checks the top level; returns (name, robot, description)."""
    if not isinstance(d, dict):
        raise SceneError(f"{ctx.source}: expected a mapping at top level, got "
                         f"{type(d).__name__}")
    unknown = [k for k in d if k not in SCENE_FIELDS]
    if unknown:
        raise ctx.fail(unknown[0], f"unknown field; known: {sorted(SCENE_FIELDS)}")
    fmt = d.get("format", FORMAT_VERSION)
    if type(fmt) is not int or fmt != FORMAT_VERSION:
        raise ctx.fail("format", f"unsupported scene format {show(fmt)}; "
                                 f"this chekhov reads {FORMAT_VERSION}")
    name = _name(ctx, "name", d.get("name"))
    robot = _robot(ctx, d.get("robot", "baxter_left"), base_dir)
    description = d.get("description", "")
    if not isinstance(description, str) or len(description) > MAX_DESCRIPTION:
        raise ctx.fail("description", f"expected text of at most {MAX_DESCRIPTION} characters, "
                                      f"got {show(description)}")
    return name, robot, description


def scene_from_dict(d: Any, source: str = "<dict>", base_dir: Path | None = None) -> Scene:
    """Validate a parsed scene mapping and build a :class:`Scene` (rules: module docstring);
    a robot file's relative path is taken from ``base_dir`` (the scene file's folder)."""
    ctx = _Ctx(source)
    name, robot, description = _header(ctx, d, base_dir)
    objs = _list(ctx, "objects", d.get("objects", []), MAX_OBJECTS, "objects")
    objects = tuple(_object(ctx, o, i) for i, o in enumerate(objs))
    dup = sorted(n for n, c in Counter(o.name for o in objects).items() if c > 1)
    if dup:
        raise ctx.fail("objects", f"duplicate object names {dup}")
    regions = _regions(ctx, d.get("regions"))
    base = _pose(ctx, "base_pose", d["base_pose"]) if "base_pose" in d else None
    return Scene(name=name, objects=objects, regions=regions, robot=robot, base_pose=base,
                 description=description, source=source,
                 locked_joints=_locked(ctx, d.get("locked_joints", {})))


def _locked(ctx: _Ctx, d: Any) -> tuple[tuple[str, float], ...]:
    """locked_joints: {joint name: value (rad or m)} for joints outside the planning group
    (which joints exist is checked when the robot is built)."""
    if not isinstance(d, dict):
        raise ctx.fail("locked_joints", f"expected a mapping of joint name to value, got "
                                        f"{show(d)}")
    if len(d) > MAX_LOCKED:
        raise ctx.fail("locked_joints", f"{len(d)} joints; at most {MAX_LOCKED} are allowed")
    out = []
    for k, v in d.items():
        out.append((_name(ctx, "locked_joints", k), _number(ctx, f"locked_joints.{k}", v)))
    return tuple(sorted(out))
