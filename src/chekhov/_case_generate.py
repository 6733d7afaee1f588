"""Generating case sets and caching them (private; import from :mod:`chekhov.cases`).

This module holds :func:`draw_case` (case ``index`` of either family, as generation and the
solvability pass draw it), :func:`generate_cases` (n cases of a family as a :class:`CaseSet`)
and the on-disk cache of generated case sets (:func:`default_cache_dir`,
:func:`cached_cases`, :func:`cache_stem`, :func:`find_cached`), whose warnings go to the
``chekhov.cases`` logger. "The module docstring" in the docstrings below is
:mod:`chekhov.cases`'s.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from chekhov._case_file import CaseSet, check_family
from chekhov._case_sampling import DrawnCase, sample_case
from chekhov._case_tasks import sample_task_case
from chekhov.errors import CaseFileError, ChekhovError
from chekhov.world import World

_log = logging.getLogger("chekhov.cases")   # the public module's name, as before the split


# --- generation -------------------------------------------------------------------------
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
    cached (``{cache_stem}-n{n}.npz``). A cached file with at least n cases is reused (its
    first n cases are the same cases). A cached file that cannot be used is regenerated (with
    a warning on the ``chekhov`` logger, which goes to stderr unless configured) and written
    atomically."""
    d = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    stem = cache_stem(world, seed, family=family)
    cases = find_cached(world, d, stem, n, family)
    if cases is None:
        cases = generate_cases(world, n, seed, family)
        cases.save(d / f"{stem}-n{n}.npz")
    return cases


def cache_stem(world: World, seed: int, kind: str = "", family: str = "random") -> str:
    """File name stem of cached cases: scene, the scene's and the robot's content hashes,
    family, seed and ``kind`` (the robot's too: one scene with two arms, e.g. a URDF given to
    ``World(scene, robot)``, has two case sets, which would otherwise replace each other's
    file on every use)."""
    return (f"{world.scene.name}-{world.scene.content_hash()[:12]}"
            f"-{world.robot.content_hash()[:8]}-{check_family(family)}-s{seed}{kind}")


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
