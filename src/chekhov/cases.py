"""Planning cases: random start configurations and goal end-effector poses, and their files.

A case is a start configuration and a goal configuration, both within the joint limits and
collision-free by *both* checkers (fast and exact), each also recorded as the end-effector pose
``robot.compute_ee_pose(q)``. Planners receive the start configuration and the goal *pose*
(:meth:`CaseSet.goal`), so they may reach it with any IK solution, as in the paper.

Determinism: case ``i`` of ``generate_cases(world, n, seed)`` is drawn from its own random
stream ``numpy.random.default_rng([seed, i])``, so it does not depend on ``n`` (the first 100
cases of ``--n 5000`` are the cases of ``--n 100``) and the same scene, robot and seed give the
same cases on every machine. Case files are **not shipped**: they are generated reproducibly on
first use and cached (:func:`cached_cases`, under :func:`default_cache_dir`: beside the
roadmaps, ``~/.cache/chekhov/cases`` by default); ``chekhov cases generate`` writes one
explicitly.

File format (``CASE_FORMAT`` version ``CASE_FORMAT_VERSION`` = 1): a NumPy ``.npz`` archive
(``numpy.load(path, allow_pickle=False)`` reads it) with

* ``meta``: a 0-d unicode array holding JSON: ``{"format": "chekhov-cases", "version": 1,
  "scene": name, "scene_hash": SHA-256 of the scene content (``Scene.content_hash``),
  "robot": name, "joint_names": [...], "seed": int, "n": int, "replaced": int,
  "units": {...}}``;
* ``q_start``, ``q_goal``: float64 (N, K), rad, joint order ``joint_names``;
* ``T_world_ee_start``, ``T_world_ee_goal``: float64 (N, 4, 4), end-effector frame in the world
  (m for the translation).

``replaced`` counts the cases a solvability pass (:func:`chekhov.bench.solvability_pass`)
replaced with new samples. Loading checks the format, the version and, given a world, that the
file belongs to that world's scene (content hash) and robot.

This module sits beside :mod:`chekhov.world` (it needs a world and nothing above it), so the
benchmark, the viewer and the CLI all read cases from here; ``chekhov.bench.cases`` re-exports
it for older code.
"""

from __future__ import annotations

import json
import logging
import os
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
_log = logging.getLogger(__name__)

CASE_FORMAT = "chekhov-cases"
CASE_FORMAT_VERSION = 1
_ARRAYS = ("q_start", "q_goal", "T_world_ee_start", "T_world_ee_goal")
_UNITS = {"q_start": "rad", "q_goal": "rad", "T_world_ee_start": "4x4 homogeneous, m",
          "T_world_ee_goal": "4x4 homogeneous, m"}


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

    def __post_init__(self) -> None:
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
        return replace(self, **{a: getattr(self, a)[:n] for a in _ARRAYS})

    def same_as(self, other: CaseSet) -> bool:
        """Field-by-field equality, arrays compared exactly."""
        return (self.meta() == other.meta()
                and all(np.array_equal(getattr(self, a), getattr(other, a)) for a in _ARRAYS))

    def meta(self) -> dict[str, Any]:
        """The JSON header written to the file."""
        return {"format": CASE_FORMAT, "version": CASE_FORMAT_VERSION, "scene": self.scene,
                "scene_hash": self.scene_hash, "robot": self.robot,
                "joint_names": list(self.joint_names), "seed": int(self.seed), "n": len(self),
                "replaced": int(self.replaced), "units": _UNITS}

    # --- files --------------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """Write the cases atomically (temporary file renamed into place); returns the path."""
        path = Path(path)
        arrays = {a: getattr(self, a) for a in _ARRAYS}

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
        try:
            cases = cls(scene=meta["scene"], scene_hash=meta["scene_hash"],
                        robot=meta["robot"], joint_names=tuple(meta["joint_names"]),
                        seed=meta["seed"], replaced=meta.get("replaced", 0),
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
    if version != CASE_FORMAT_VERSION:
        raise CaseFileError(f"{path}: case file format version {version!r:.20}; this chekhov "
                            f"reads version {CASE_FORMAT_VERSION} — regenerate it with "
                            "`chekhov cases generate`")
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


def generate_cases(world: World, n: int, seed: int = 0) -> CaseSet:
    """n random cases for the world: start and goal configurations within limits and free by
    both checkers, with their end-effector poses. Deterministic for (scene, robot, seed);
    case i does not depend on n."""
    if n < 1:
        raise ChekhovError(f"cases: n must be at least 1, got {n}")
    pairs = [sample_case(world, seed, i) for i in range(n)]
    q_start = np.array([p[0] for p in pairs])
    q_goal = np.array([p[1] for p in pairs])
    return CaseSet(scene=world.scene.name, scene_hash=world.scene.content_hash(),
                   robot=world.robot.name, joint_names=tuple(world.robot.joint_names),
                   seed=int(seed), q_start=q_start, q_goal=q_goal,
                   T_world_ee_start=world.robot.compute_ee_poses(q_start),
                   T_world_ee_goal=world.robot.compute_ee_poses(q_goal))


def default_cache_dir() -> Path:
    """``$CHEKHOV_CACHE/cases`` (cases only), else ``$CHEKHOV_CACHE_DIR/cases`` (the
    roadmaps' variable too), else ``$XDG_CACHE_HOME/chekhov/cases`` or
    ``~/.cache/chekhov/cases``: beside the roadmaps."""
    root = os.environ.get("CHEKHOV_CACHE") or os.environ.get("CHEKHOV_CACHE_DIR")
    if root:
        return Path(root) / "cases"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "chekhov" / "cases"


def cached_cases(world: World, n: int, seed: int = 0, cache_dir: str | Path | None = None
                 ) -> CaseSet:
    """The n cases of ``generate_cases(world, n, seed)``, generated on first use and cached
    (``{scene}-{hash[:12]}-s{seed}-n{n}.npz``). A cached file with at least n cases is reused
    (its first n cases are the same cases). A cached file that cannot be used is regenerated
    (with a warning on the ``chekhov`` logger, which goes to stderr unless configured) and
    written atomically."""
    d = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    stem = cache_stem(world, seed)
    cases = find_cached(world, d, stem, n)
    if cases is None:
        cases = generate_cases(world, n, seed)
        cases.save(d / f"{stem}-n{n}.npz")
    return cases


def cache_stem(world: World, seed: int, kind: str = "") -> str:
    """File name stem of cached cases: scene, content hash, seed and ``kind``."""
    return f"{world.scene.name}-{world.scene.content_hash()[:12]}-s{seed}{kind}"


def find_cached(world: World, cache_dir: Path, stem: str, n: int) -> CaseSet | None:
    """The first n cases of a cached ``{stem}-n{N}.npz`` with N ≥ n, or None.

    A cached file that cannot be used (truncated, corrupt, malformed, of another world) is
    logged as a warning naming it and removed, so the caller regenerates it."""
    for p in sorted(cache_dir.glob(f"{stem}-n*.npz")):
        try:
            have = int(p.stem.rsplit("-n", 1)[1])
        except ValueError:
            continue
        if have >= n:
            cases = _load_cached(p, world)
            if cases is not None:
                return cases.head(n)
    return None


def _load_cached(path: Path, world: World) -> CaseSet | None:
    """The cases of a cached file, or None after removing it when it is unusable (unless
    another process replaced it meanwhile)."""
    try:
        before = path.stat()
        return CaseSet.load(path, world)
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
