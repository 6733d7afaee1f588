"""The case file format and :class:`CaseSet` (private; import from :mod:`chekhov.cases`).

This module holds the format's constants (``CASE_FORMAT``, ``CASE_FORMAT_VERSION``,
``READABLE_VERSIONS``, ``FAMILIES``), :func:`check_family`, :class:`CaseSet` (the N cases of one
scene and robot, with their saving and loading) and the readers and checkers a loaded file goes
through (header, arrays, the tasks family's labels, joint limits). "The module docstring" in
the docstrings below is :mod:`chekhov.cases`'s, which describes the file format.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from chekhov.atomic import write_atomic
from chekhov.errors import CaseFileError, ChekhovError
from chekhov.npzfile import read_npz
from chekhov.robot.goal import Goal
from chekhov.world import World

Array = NDArray[np.float64]

CASE_FORMAT = "chekhov-cases"
CASE_FORMAT_VERSION = 2
READABLE_VERSIONS = (1, 2)   # 1: before families, read as family "random"
FAMILIES = ("random", "tasks")
_ARRAYS = ("q_start", "q_goal", "T_world_ee_start", "T_world_ee_goal")
_UNITS = {"q_start": "rad", "q_goal": "rad", "T_world_ee_start": "4x4 homogeneous, m",
          "T_world_ee_goal": "4x4 homogeneous, m"}
_LABELS = ("start_label", "goal_label")   # arrays of the tasks family


def check_family(family: str, what: str = "cases") -> str:
    """``family`` when it is one of :data:`FAMILIES`; else a :class:`ChekhovError`."""
    if family not in FAMILIES:
        raise ChekhovError(f"{what}: unknown case family {family!r}; choose one of "
                           f"{list(FAMILIES)}")
    return family


@dataclass(frozen=True, eq=False)
class CaseSet:
    """N planning cases for one scene and robot.

    Attributes:
        scene: scene name. scene_hash: the scene's content hash (SHA-256 hex).
        robot: robot name. joint_names: the K joints, in configuration order.
        seed: the seed the cases were generated with.
        q_start, q_goal: (N, K) configurations, rad.
        T_world_ee_start, T_world_ee_goal: (N, 4, 4) end-effector poses in the world (m).
        replaced: how many cases solvability passes replaced with new samples.
        solvability: which planners decided those passes, under what time limit ("" when
            none ran, or the file predates the field).
        family: "random" or "tasks" (see the module docstring).
        start_labels, goal_labels: N strings each for the tasks family (what the start and the
            goal are), empty for the random family.
    """

    scene: str
    scene_hash: str
    robot: str
    joint_names: tuple[str, ...]
    seed: int
    q_start: Array
    q_goal: Array
    T_world_ee_start: Array
    T_world_ee_goal: Array
    replaced: int = 0
    family: str = "random"
    solvability: str = ""
    start_labels: tuple[str, ...] = ()
    goal_labels: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        check_family(self.family)
        for name in ("start_labels", "goal_labels"):
            object.__setattr__(self, name, tuple(str(x) for x in getattr(self, name)))
        for name in _ARRAYS:
            object.__setattr__(self, name, np.ascontiguousarray(getattr(self, name),
                                                                dtype=np.float64))
        n, k = self.q_start.shape
        shapes = {"q_goal": (n, k), "T_world_ee_start": (n, 4, 4), "T_world_ee_goal": (n, 4, 4)}
        for name, shape in shapes.items():
            if getattr(self, name).shape != shape:
                raise ChekhovError(f"cases: '{name}' has shape {getattr(self, name).shape}, "
                                   f"expected {shape} for {n} cases of {k} joints")
        if len(self.joint_names) != k:
            raise ChekhovError(f"cases: {len(self.joint_names)} joint names for {k} joints")
        want = n if self.family == "tasks" else 0
        for name in ("start_labels", "goal_labels"):
            if len(getattr(self, name)) != want:
                raise ChekhovError(f"cases: {len(getattr(self, name))} '{name}' for {n} cases "
                                   f"of family '{self.family}', expected {want}")

    def __len__(self) -> int:
        return len(self.q_start)

    @property
    def dof(self) -> int:
        return int(self.q_start.shape[1])

    def goal(self, i: int, position_tolerance: float = 0.005,
             orientation_tolerance: float = 0.05) -> Goal:
        """The goal of case i as a pose goal (what planners receive)."""
        return Goal.pose(self.T_world_ee_goal[i], position_tolerance, orientation_tolerance)

    def head(self, n: int) -> CaseSet:
        """The first n cases (deterministic prefix; the same as generating with n)."""
        return replace(self, **{a: getattr(self, a)[:n] for a in _ARRAYS},
                       start_labels=self.start_labels[:n], goal_labels=self.goal_labels[:n])

    def same_as(self, other: CaseSet) -> bool:
        """Field-by-field equality, arrays compared exactly."""
        return (self.meta() == other.meta()
                and all(np.array_equal(getattr(self, a), getattr(other, a)) for a in _ARRAYS)
                and self.start_labels == other.start_labels
                and self.goal_labels == other.goal_labels)

    def meta(self) -> dict[str, Any]:
        """The JSON header written to the file."""
        return {"format": CASE_FORMAT, "version": CASE_FORMAT_VERSION, "family": self.family,
                "scene": self.scene,
                "scene_hash": self.scene_hash, "robot": self.robot,
                "joint_names": list(self.joint_names), "seed": int(self.seed), "n": len(self),
                "replaced": int(self.replaced), "solvability": self.solvability,
                "units": _UNITS}

    # --- files --------------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """Write the cases atomically (temporary file renamed into place); returns the path."""
        path = Path(path)
        arrays = {a: getattr(self, a) for a in _ARRAYS}
        if self.family == "tasks":
            arrays["start_label"] = np.array(self.start_labels, dtype=str)
            arrays["goal_label"] = np.array(self.goal_labels, dtype=str)

        def write(f: IO[bytes]) -> None:
            np.savez_compressed(f, meta=np.array(json.dumps(self.meta())), **arrays)

        write_atomic(path, write, mode="wb")
        return path

    @classmethod
    def load(cls, path: str | Path, world: World | None = None) -> CaseSet:
        """Read a case file; with ``world``, check that it was made for that scene and robot
        and that its configurations lie within the robot's joint limits.

        Everything read is checked (header fields and types, array names, dtypes, shapes,
        finiteness, poses). Raises :class:`CaseFileError` naming the file and what is wrong
        (missing, truncated, corrupt, malformed, of another scene or robot).
        """
        path = Path(path)
        data = read_npz(path, None, CaseFileError, "case")
        meta = _read_header(path, data)
        _check_arrays(path, data, meta)
        labels = _read_labels(path, data, meta)
        try:
            cases = cls(scene=meta["scene"], scene_hash=meta["scene_hash"],
                        robot=meta["robot"], joint_names=tuple(meta["joint_names"]),
                        seed=meta["seed"], replaced=meta.get("replaced", 0),
                        solvability=meta.get("solvability", ""), family=meta["family"],
                        start_labels=labels[0], goal_labels=labels[1],
                        **{a: data[a] for a in _ARRAYS})
        except ChekhovError as e:
            raise CaseFileError(f"{path}: {e}") from e
        if world is not None:
            cases.check_world(world, source=str(path))
            _check_limits(path, cases, world)
        return cases

    def check_world(self, world: World, source: str = "cases") -> None:
        """Raise :class:`CaseFileError` unless these cases belong to ``world``."""
        h = world.scene.content_hash()
        if self.scene_hash != h:
            raise CaseFileError(
                f"{source}: cases were generated for scene '{self.scene}' (content hash "
                f"{self.scene_hash[:12]}), not for scene '{world.scene.name}' (content hash "
                f"{h[:12]}); the scene differs — regenerate with `chekhov cases generate "
                f"{world.scene.name}`")
        if self.robot != world.robot.name or self.joint_names != world.robot.joint_names:
            raise CaseFileError(f"{source}: cases are for robot '{self.robot}' "
                               f"{list(self.joint_names)}, the world's robot is "
                               f"'{world.robot.name}' {list(world.robot.joint_names)}")


# --- reading and checking files ----------------------------------------------------------
# meta field: (type, what the message says is expected)
_FIELDS: dict[str, tuple[type, str]] = {
    "scene": (str, "a string"), "scene_hash": (str, "a string"), "robot": (str, "a string"),
    "joint_names": (list, "a non-empty list of joint names"), "seed": (int, "an integer"),
    "n": (int, "an integer ≥ 1"), "replaced": (int, "an integer ≥ 0"),
    "solvability": (str, "a string")}
_OPTIONAL = ("replaced", "solvability")


def _read_header(path: Path, data: dict[str, np.ndarray]) -> dict[str, Any]:
    """The checked JSON header of a case file (see the module docstring)."""
    m = data.get("meta")
    if m is None or m.shape != () or m.dtype.kind != "U":
        raise CaseFileError(f"{path}: not a chekhov case file: no readable 'meta' header")
    try:
        meta = json.loads(str(m))
    except (ValueError, RecursionError) as e:
        raise CaseFileError(f"{path}: not a chekhov case file: 'meta' header is not JSON "
                            f"({e})") from e
    if not isinstance(meta, dict) or meta.get("format") != CASE_FORMAT:
        got = meta.get("format") if isinstance(meta, dict) else meta
        raise CaseFileError(f"{path}: not a chekhov case file (its 'meta' header is not an "
                            f"object with format '{CASE_FORMAT}', got {got!r:.60})")
    version = meta.get("version")
    if isinstance(version, bool) or version not in READABLE_VERSIONS:
        raise CaseFileError(f"{path}: case file format version {version!r:.20}; this chekhov "
                            f"reads versions {', '.join(map(str, READABLE_VERSIONS))} — "
                            "regenerate it with `chekhov cases generate`")
    if version == 1:   # before the families: every version-1 file holds random cases
        meta["family"] = "random"
    elif "family" not in meta:
        raise CaseFileError(f"{path}: case file (version {version}) lacks the meta field "
                            f"'family' (one of {list(FAMILIES)})")
    elif meta["family"] not in FAMILIES:
        raise CaseFileError(f"{path}: meta field 'family' must be one of {list(FAMILIES)}, "
                            f"got {meta['family']!r:.60}")
    for key, (typ, expected) in _FIELDS.items():
        if key not in meta:
            if key in _OPTIONAL:
                continue
            raise CaseFileError(f"{path}: case file lacks the meta field '{key}'")
        v = meta[key]
        ok = isinstance(v, typ) and not isinstance(v, bool)
        if key == "joint_names":
            ok = ok and len(v) > 0 and all(isinstance(j, str) for j in v)
        elif key in ("n", "replaced"):
            ok = ok and v >= (1 if key == "n" else 0)
        if not ok:
            raise CaseFileError(f"{path}: meta field '{key}' must be {expected}, got {v!r:.60}")
    return meta


def _check_arrays(path: Path, data: dict[str, np.ndarray], meta: dict[str, Any]) -> None:
    """Names, dtypes, shapes, finiteness of the arrays, and that the poses are poses."""
    n, k = meta["n"], len(meta["joint_names"])
    for name in _ARRAYS:
        if name not in data:
            raise CaseFileError(f"{path}: case file lacks the array '{name}'")
        a = data[name]
        if a.dtype != np.float64:
            raise CaseFileError(f"{path}: array '{name}' has dtype {a.dtype}, expected float64")
        shape = (n, k) if name.startswith("q_") else (n, 4, 4)
        if a.shape != shape:
            raise CaseFileError(
                f"{path}: array '{name}' has shape {a.shape}, expected {shape}: the header has "
                f"'n' = {n} cases and {k} 'joint_names'")
        bad = ~np.isfinite(a.reshape(n, -1)).all(axis=1)
        if bad.any():
            raise CaseFileError(f"{path}: array '{name}' holds NaN or infinite values (case "
                                f"{int(np.argmax(bad))})")
        if name.startswith("T_"):
            R = a[:, :3, :3]
            err = np.abs(np.einsum("nji,njk->nik", R, R) - np.eye(3)).max(axis=(1, 2))
            bad = (err > 1e-6) | (np.abs(a[:, 3] - [0.0, 0.0, 0.0, 1.0]).max(axis=1) > 0) \
                | (np.linalg.det(R) <= 0)
            if bad.any():
                raise CaseFileError(f"{path}: array '{name}' case {int(np.argmax(bad))} is not "
                                    "a homogeneous transform (rotation and last row 0 0 0 1)")


def _read_labels(path: Path, data: dict[str, np.ndarray], meta: dict[str, Any]
                 ) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The tasks family's ``start_label`` and ``goal_label`` arrays (empty for random)."""
    if meta["family"] != "tasks":
        return (), ()
    out = []
    for name in _LABELS:
        a = data.get(name)
        if a is None:
            raise CaseFileError(f"{path}: case file of family 'tasks' lacks the array "
                                f"'{name}'")
        if a.dtype.kind != "U" or a.shape != (meta["n"],):
            raise CaseFileError(f"{path}: array '{name}' must be {meta['n']} strings, got "
                                f"dtype {a.dtype} shape {a.shape}")
        out.append(tuple(str(x) for x in a))
    return out[0], out[1]


def _check_limits(path: Path, cases: CaseSet, world: World) -> None:
    """Both configurations of every case within the robot's joint limits (1e-9 rad)."""
    for name in ("q_start", "q_goal"):
        out = ~world.robot.within_limits(getattr(cases, name))
        if out.any():
            i = int(np.argmax(out))
            raise CaseFileError(f"{path}: array '{name}' case {i} lies outside the joint "
                                f"limits of robot '{world.robot.name}'")
