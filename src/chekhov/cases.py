"""Planning cases: start configurations and goal end-effector poses, and their files.

A case is a start configuration and a goal configuration, both within the joint limits and
collision-free by *both* checkers (fast and exact), with their end-effector poses. Planners
receive the start configuration and the goal *pose* (:meth:`CaseSet.goal`), so they may reach
it with any IK solution, as in the paper. Two families of cases (``CaseSet.family``):

* ``"random"``: start and goal configurations drawn uniformly within the joint limits, each
  pose ``robot.compute_ee_pose(q)`` (the paper's cases).
* ``"tasks"`` (issue 17's pick-and-place workload, :func:`sample_task_case`): the start is a
  collision-free IK solution of one object's pre-grasp pose (or the robot's ready
  configuration, :func:`ready_configuration`, when its SRDF names one), the goal *pose* is
  another object's pre-grasp pose or, in about one case in five, a place pose: a pre-grasp of
  an object set down on a free spot of one of the scene's regions (:func:`place_pose`). The goal
  pose is the pre-grasp pose itself; ``q_goal`` is its collision-free IK solution nearest the
  start (``world.goal_ik.resolve(goal, near=q_start)``, confirmed by the exact checker).
  ``start_labels`` / ``goal_labels`` say what each is (``"ready"``, ``"cup/top"``,
  ``"place:above_table/cup/top"``).

Determinism: case ``i`` of ``generate_cases(world, n, seed, family)`` is drawn from its own
random stream ``numpy.random.default_rng([seed, i])`` (:func:`case_rng`; the task family's
IK runs without deadlines, so it depends on nothing but the stream), so it does not depend on
``n`` (the first 100 cases of ``--n 5000`` are the cases of ``--n 100``) and the same scene,
robot, seed and family give the same cases on every machine. Case files are **not shipped**:
they are generated reproducibly on first use and cached (:func:`cached_cases`, under
:func:`default_cache_dir`: beside the roadmaps, ``~/.cache/chekhov/cases`` by default);
``chekhov cases generate`` writes one explicitly.

File format (``CASE_FORMAT`` version ``CASE_FORMAT_VERSION`` = 2): a NumPy ``.npz`` archive
(``numpy.load(path, allow_pickle=False)`` reads it) with

* ``meta``: a 0-d unicode array holding JSON: ``{"format": "chekhov-cases", "version": 2,
  "family": "random" | "tasks", "scene": name, "scene_hash": SHA-256 of the scene content
  (``Scene.content_hash``), "robot": name, "joint_names": [...], "seed": int, "n": int,
  "replaced": int, "units": {...}}``;
* ``q_start``, ``q_goal``: float64 (N, K), rad, joint order ``joint_names``;
* ``T_world_ee_start``, ``T_world_ee_goal``: float64 (N, 4, 4), end-effector frame in the world
  (m for the translation);
* family ``tasks`` only: ``start_label``, ``goal_label``: unicode (N,), what each start and
  goal is (see above).

``replaced`` counts the cases a solvability pass (:func:`chekhov.bench.solvability_pass`)
replaced with new samples. Loading checks the format, the version and, given a world, that the
file belongs to that world's scene (content hash) and robot. Version 1 (before the families:
the same layout without ``family``) is read as family ``"random"``, which is what every
version-1 file holds; a version-2 file without ``family`` is refused, naming the file and
the field.

This module sits beside :mod:`chekhov.world` (it needs a world and nothing above it), so the
benchmark, the viewer and the CLI all read cases from here; ``chekhov.bench.cases`` re-exports
it for older code.
"""

from __future__ import annotations

import json
import logging
import os
import weakref
import xml.etree.ElementTree as ET
from dataclasses import dataclass, replace
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from chekhov.atomic import write_atomic
from chekhov.errors import CaseFileError, ChekhovError
from chekhov.npzfile import read_npz
from chekhov.robot.goal import Goal
from chekhov.scene.model import Grasp, Region, Scene, SceneObject
from chekhov.world import World

Array = NDArray[np.float64]
_log = logging.getLogger(__name__)

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
                "replaced": int(self.replaced), "units": _UNITS}

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
                        family=meta["family"], start_labels=labels[0], goal_labels=labels[1],
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
    "n": (int, "an integer ≥ 1"), "replaced": (int, "an integer ≥ 0")}


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
            if key == "replaced":
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


# --- generation -------------------------------------------------------------------------
def sample_free(world: World, rng: np.random.Generator, n: int, batch: int = 16,
                max_draws: int = 1_000_000) -> Array:
    """n configurations (n, K), uniform within the joint limits, collision-free by both
    checkers (fast first, in batches, then exact). Deterministic for the generator's state."""
    out: list[Array] = []
    drawn = 0
    while len(out) < n:
        if drawn >= max_draws:
            raise ChekhovError(f"scene '{world.scene.name}': only {len(out)} collision-free "
                               f"configurations in {drawn} uniform samples")
        Q = world.robot.sample_uniform(rng, batch)
        drawn += batch
        for q in Q[world.fast.valid(Q)]:
            if world.exact.is_valid(q):
                out.append(q)
                if len(out) == n:
                    break
    return np.array(out).reshape(n, world.robot.dof)


def case_rng(seed: int, index: int, attempt: int = 0) -> np.random.Generator:
    """The random stream of case ``index`` (attempt > 0: its replacements)."""
    key = [int(seed), int(index)] + ([int(attempt)] if attempt else [])
    return np.random.default_rng(key)


def sample_case(world: World, seed: int, index: int, attempt: int = 0) -> tuple[Array, Array]:
    """(q_start, q_goal) of case ``index``, replacement ``attempt`` (0: the original)."""
    Q = sample_free(world, case_rng(seed, index, attempt), 2)
    return Q[0], Q[1]


@dataclass(frozen=True, eq=False)
class DrawnCase:
    """One case as drawn: configurations (K,) rad, poses (4, 4) m, labels ("" for random)."""

    q_start: Array
    q_goal: Array
    T_start: Array
    T_goal: Array
    start_label: str = ""
    goal_label: str = ""


def draw_case(world: World, family: str, seed: int, index: int, attempt: int = 0
              ) -> DrawnCase:
    """Case ``index`` of ``family`` (replacement ``attempt``; 0: the original), as
    :func:`generate_cases` and the solvability pass draw it."""
    if check_family(family) == "tasks":
        return sample_task_case(world, seed, index, attempt)
    q0, q1 = sample_case(world, seed, index, attempt)
    return DrawnCase(q0, q1, world.robot.compute_ee_pose(q0), world.robot.compute_ee_pose(q1))


def generate_cases(world: World, n: int, seed: int = 0, family: str = "random") -> CaseSet:
    """n cases of ``family`` for the world: start and goal configurations within limits and
    free by both checkers, with their end-effector poses. Deterministic for (scene, robot,
    seed, family); case i does not depend on n. The random family is the paper's (see the
    module docstring)."""
    if n < 1:
        raise ChekhovError(f"cases: n must be at least 1, got {n}")
    if check_family(family) == "random":
        pairs = [sample_case(world, seed, i) for i in range(n)]
        q_start = np.array([p[0] for p in pairs])
        q_goal = np.array([p[1] for p in pairs])
        return CaseSet(scene=world.scene.name, scene_hash=world.scene.content_hash(),
                       robot=world.robot.name, joint_names=tuple(world.robot.joint_names),
                       seed=int(seed), q_start=q_start, q_goal=q_goal,
                       T_world_ee_start=world.robot.compute_ee_poses(q_start),
                       T_world_ee_goal=world.robot.compute_ee_poses(q_goal))
    drawn = [draw_case(world, family, seed, i) for i in range(n)]
    return CaseSet(scene=world.scene.name, scene_hash=world.scene.content_hash(),
                   robot=world.robot.name, joint_names=tuple(world.robot.joint_names),
                   seed=int(seed), family=family,
                   q_start=np.array([d.q_start for d in drawn]),
                   q_goal=np.array([d.q_goal for d in drawn]),
                   T_world_ee_start=np.array([d.T_start for d in drawn]),
                   T_world_ee_goal=np.array([d.T_goal for d in drawn]),
                   start_labels=tuple(d.start_label for d in drawn),
                   goal_labels=tuple(d.goal_label for d in drawn))


# --- the task family ----------------------------------------------------------------------
READY_SHARE = 0.25        # share of task starts at the ready configuration (when there is one)
PLACE_SHARE = 0.2         # share of task goals that are place poses
TASK_TRIES = 200          # draws per case before giving up
GOAL_SOLUTIONS = 4        # IK solutions asked of the goal resolver per pose
PLACE_CLEARANCE = 0.005   # m, gap under and around a placed object
READY_STATES = ("ready", "home", "default")   # SRDF group_state names taken as "ready"


@dataclass(frozen=True, eq=False)
class PregraspTarget:
    """A pre-grasp pose and its collision-free IK solutions.

    Attributes:
        label: ``SceneObject.pregrasp_poses`` label ("cup/top", "door/handle@open").
        obj: the object's name. T: (4, 4) the pre-grasp pose in the world (m).
        Q: (m, K) rad, its IK solutions free by both checkers, within limits (m ≥ 1).
    """

    label: str
    obj: str
    T: Array
    Q: Array


@dataclass(frozen=True, eq=False)
class TaskTargets:
    """What task cases of a world are drawn from: the reachable pre-grasps (in scene order)
    and the ready configuration (None when the robot has none that is free here)."""

    pregrasps: tuple[PregraspTarget, ...]
    ready: Array | None


_TARGETS: weakref.WeakKeyDictionary[World, TaskTargets] = weakref.WeakKeyDictionary()


def task_targets(world: World) -> TaskTargets:
    """The world's :class:`TaskTargets`, computed once per world (the scene's obstacles; the
    dynamic obstacles added to a world later are not seen). Each pre-grasp pose goes to
    ``world.goal_ik.resolve`` (no deadline, so the result is the same on every machine), and
    its solutions are kept when the exact checker calls them free."""
    got = _TARGETS.get(world)
    if got is None:
        out = []
        for obj in world.scene.objects:
            for label, T in obj.pregrasp_poses():
                Q = _free_solutions(world, T)
                if len(Q):
                    out.append(PregraspTarget(label, obj.name, T, Q))
        got = TaskTargets(tuple(out), ready_configuration(world))
        _TARGETS[world] = got
    return got


def _free_solutions(world: World, T: Array, near: Array | None = None) -> Array:
    """IK solutions of pose T (4, 4) that are within limits and free by the exact checker (the
    resolver's are free by the fast one), nearest ``near`` first when given; (m, K)."""
    found = world.goal_ik.resolve(Goal.pose(T), n=GOAL_SOLUTIONS, near=near)
    Q = [q for q in found.Q if world.robot.within_limits(q)[0] and world.exact.is_valid(q)]
    return np.array(Q).reshape(len(Q), world.robot.dof)


def ready_configuration(world: World) -> Array | None:
    """The robot's ready configuration (K,) rad: the first SRDF ``group_state`` named one of
    :data:`READY_STATES` that sets every planned joint (the Panda's "default"; Baxter's SRDF
    has none), when it is within limits and free in this scene by both checkers; else None."""
    srdf = world.robot.description.srdf
    if not srdf:
        return None
    try:
        root = ET.parse(world.robot.description.resolve(srdf)).getroot()
    except (OSError, ET.ParseError):
        return None
    states = {s.get("name"): {j.get("name"): j.get("value") for j in s.iter("joint")}
              for s in root.iter("group_state")}
    for name in READY_STATES:
        values = states.get(name, {})
        try:
            q = np.array([float(values[j]) for j in world.robot.joint_names])  # type: ignore[arg-type]
        except (KeyError, TypeError, ValueError):
            continue
        if (world.robot.within_limits(q)[0] and world.fast.valid(q[None])[0]
                and world.exact.is_valid(q)):
            return q
    return None


def sample_task_case(world: World, seed: int, index: int, attempt: int = 0) -> DrawnCase:
    """Case ``index`` of the task family (replacement ``attempt``), from the stream
    ``case_rng(seed, index, attempt)``:

    * start: with probability :data:`READY_SHARE` the ready configuration (when there is one),
      else a pre-grasp drawn uniformly among the reachable ones and one of its free IK
      solutions drawn uniformly;
    * goal: with probability :data:`PLACE_SHARE` a place pose (:func:`place_pose`: the start's
      object — or, from the ready configuration, a drawn graspable one — set down in a region
      drawn by weight), else the pre-grasp pose of another object drawn uniformly; ``q_goal``
      is its free IK solution nearest the start.

    Draws that give no free goal solution are drawn again (up to :data:`TASK_TRIES`)."""
    targets = task_targets(world)
    objects = {t.obj for t in targets.pregrasps}
    if len(objects) < 2:
        raise ChekhovError(f"scene '{world.scene.name}': task cases need reachable pre-grasps "
                           f"of two objects at least, found {sorted(objects)}")
    rng = case_rng(seed, index, attempt)
    for _ in range(TASK_TRIES):
        if targets.ready is not None and rng.random() < READY_SHARE:
            q_start, start_label, start_obj = targets.ready, "ready", None
        else:
            t = targets.pregrasps[int(rng.integers(len(targets.pregrasps)))]
            q_start, start_label, start_obj = t.Q[int(rng.integers(len(t.Q)))], t.label, t.obj
        goal = (_draw_place(world, rng, start_obj) if rng.random() < PLACE_SHARE
                else _draw_pregrasp(targets, rng, start_obj))
        if goal is None:
            continue
        T_goal, goal_label = goal
        Q = _free_solutions(world, T_goal, near=q_start)
        if len(Q) == 0:
            continue
        return DrawnCase(q_start.copy(), Q[0], world.robot.compute_ee_pose(q_start),
                         T_goal, start_label, goal_label)
    raise ChekhovError(f"scene '{world.scene.name}': no task case {index} (seed {seed}, "
                       f"attempt {attempt}) in {TASK_TRIES} draws")


def _draw_pregrasp(targets: TaskTargets, rng: np.random.Generator, start_obj: str | None
                   ) -> tuple[Array, str]:
    others = [t for t in targets.pregrasps if t.obj != start_obj]
    t = others[int(rng.integers(len(others)))]
    return t.T, t.label


def _draw_place(world: World, rng: np.random.Generator, start_obj: str | None
                ) -> tuple[Array, str] | None:
    """A place pose (and its label) of the start's object, or of a drawn one from the ready
    configuration, in a region drawn by weight; None when that draw finds no free spot."""
    scene = world.scene
    regions = [r for r in scene.regions if r.weight > 0]
    movable = [o for o in scene.objects if o.grasps and o.articulation is None]
    if not regions or not movable:
        return None
    if start_obj is None:
        obj = movable[int(rng.integers(len(movable)))]
    else:
        obj = scene.object(start_obj)
        if obj.articulation is not None or not obj.grasps:
            return None
    w = np.array([r.weight for r in regions])
    region = regions[int(rng.choice(len(regions), p=w / w.sum()))]
    grasp = obj.grasps[int(rng.integers(len(obj.grasps)))]
    T = place_pose(scene, obj, grasp, region, rng.random(2))
    if T is None:
        return None
    return T, f"place:{region.name}/{obj.name}/{grasp.name}"


def place_pose(scene: Scene, obj: SceneObject, grasp: Grasp, region: Region, u: Array
               ) -> Array | None:
    """The pre-grasp pose (4, 4) of ``grasp`` with ``obj`` set down in ``region``, or None.

    The object keeps its orientation; its centre goes to the point ``u`` ∈ [0, 1)² of the
    region's horizontal extent (shrunk by the object's half footprint), standing on the highest
    top of the other objects under its footprint within the region's height (or floating on
    the region's floor), :data:`PLACE_CLEARANCE` above it. The spot is free when the object's
    axis-aligned box there, grown by the clearance, overlaps no other object's box and fits
    in the region. Grasps are relative to the object, so the place pre-grasp approaches the
    set-down object as the pick pre-grasp approaches it where it stands."""
    T_obj = obj.T_world_obj()
    ext = _world_half_extents(obj, T_obj)
    c, size = np.asarray(region.center, dtype=float), np.asarray(region.size, dtype=float)
    lo, hi = c - size / 2, c + size / 2
    room = size[:2] - 2 * (ext[:2] + PLACE_CLEARANCE)
    if np.any(room <= 0):
        return None
    xy = lo[:2] + ext[:2] + PLACE_CLEARANCE + np.asarray(u, dtype=float) * room
    boxes = [_aabb(o) for o in scene.objects if o.name != obj.name]
    floor = lo[2]
    for b_lo, b_hi in boxes:
        if (np.all(b_lo[:2] < xy + ext[:2]) and np.all(xy - ext[:2] < b_hi[:2])
                and lo[2] - PLACE_CLEARANCE <= b_hi[2] <= hi[2]):
            floor = max(floor, float(b_hi[2]))
    centre = np.array([xy[0], xy[1], floor + PLACE_CLEARANCE + ext[2]])
    if centre[2] + ext[2] > hi[2]:
        return None
    grown = ext + PLACE_CLEARANCE / 2
    for b_lo, b_hi in boxes:
        if np.all(b_lo < centre + grown) and np.all(centre - grown < b_hi):
            return None
    T = T_obj.copy()
    T[:3, 3] = centre
    return T @ grasp.T_obj_pregrasp


def _world_half_extents(obj: SceneObject, T_world_obj: Array) -> Array:
    """Half extents (3,) of the object's world axis-aligned bounding box (m)."""
    return np.abs(T_world_obj[:3, :3]) @ obj.shape.half_extents


def _aabb(obj: SceneObject) -> tuple[Array, Array]:
    T = obj.T_world_obj()
    ext = _world_half_extents(obj, T)
    return T[:3, 3] - ext, T[:3, 3] + ext


# --- the cache ----------------------------------------------------------------------------
def default_cache_dir() -> Path:
    """``$CHEKHOV_CACHE/cases`` (cases only), else ``$CHEKHOV_CACHE_DIR/cases`` (the
    roadmaps' variable too), else ``$XDG_CACHE_HOME/chekhov/cases`` or
    ``~/.cache/chekhov/cases``: beside the roadmaps."""
    root = os.environ.get("CHEKHOV_CACHE") or os.environ.get("CHEKHOV_CACHE_DIR")
    if root:
        return Path(root) / "cases"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "chekhov" / "cases"


def cached_cases(world: World, n: int, seed: int = 0, cache_dir: str | Path | None = None,
                 family: str = "random") -> CaseSet:
    """The n cases of ``generate_cases(world, n, seed, family)``, generated on first use and
    cached (``{scene}-{hash[:12]}-{family}-s{seed}-n{n}.npz``). A cached file with at least n
    cases is reused (its first n cases are the same cases). A cached file that cannot be used
    is regenerated (with a warning on the ``chekhov`` logger, which goes to stderr unless
    configured) and written atomically."""
    d = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    stem = cache_stem(world, seed, family=family)
    cases = find_cached(world, d, stem, n, family)
    if cases is None:
        cases = generate_cases(world, n, seed, family)
        cases.save(d / f"{stem}-n{n}.npz")
    return cases


def cache_stem(world: World, seed: int, kind: str = "", family: str = "random") -> str:
    """File name stem of cached cases: scene, content hash, family, seed and ``kind``."""
    return (f"{world.scene.name}-{world.scene.content_hash()[:12]}-{check_family(family)}"
            f"-s{seed}{kind}")


def find_cached(world: World, cache_dir: Path, stem: str, n: int, family: str | None = None
                ) -> CaseSet | None:
    """The first n cases of a cached ``{stem}-n{N}.npz`` with N ≥ n (of ``family``, when
    given), or None.

    A cached file that cannot be used (truncated, corrupt, malformed, of another world or
    family) is logged as a warning naming it and removed, so the caller regenerates it."""
    for p in sorted(cache_dir.glob(f"{stem}-n*.npz")):
        try:
            have = int(p.stem.rsplit("-n", 1)[1])
        except ValueError:
            continue
        if have >= n:
            cases = _load_cached(p, world, family)
            if cases is not None:
                return cases.head(n)
    return None


def _load_cached(path: Path, world: World, family: str | None = None) -> CaseSet | None:
    """The cases of a cached file, or None after removing it when it is unusable (unless
    another process replaced it meanwhile)."""
    try:
        before = path.stat()
        cases = CaseSet.load(path, world)
        if family is None or cases.family == family:
            return cases
        _log.warning("chekhov: cached case file %s holds family '%s', not '%s'; "
                     "regenerating it", path, cases.family, family)
    except FileNotFoundError:
        return None
    except CaseFileError as e:
        _log.warning("chekhov: cached case file %s is unusable, regenerating it: %s", path, e)
    try:
        now = path.stat()
        if (now.st_ino, now.st_size, now.st_mtime_ns) == (
                before.st_ino, before.st_size, before.st_mtime_ns):
            path.unlink()
    except FileNotFoundError:
        pass
    return None
