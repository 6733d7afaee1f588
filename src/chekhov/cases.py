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
  "replaced": int, "solvability": str, "units": {...}}``;
* ``q_start``, ``q_goal``: float64 (N, K), rad, joint order ``joint_names``;
* ``T_world_ee_start``, ``T_world_ee_goal``: float64 (N, 4, 4), end-effector frame in the world
  (m for the translation);
* family ``tasks`` only: ``start_label``, ``goal_label``: unicode (N,), what each start and
  goal is (see above).

``replaced`` counts the cases a solvability pass (:func:`chekhov.bench.solvability_pass`)
replaced with new samples; ``solvability`` says which planners decided it and under what limit
("" for none, and in files written before the field: both optional, so files with and without
it read alike, in this chekhov and in one before it). Loading checks the format, the version
and, given a world, that the file belongs to that world's scene (content hash) and robot.
Version 1 (before the families: the same layout without ``family``) is read as family
``"random"``, which is what every version-1 file holds; a version-2 file without ``family`` is
refused, naming the file and the field.

This module sits beside :mod:`chekhov.world` (it needs a world and nothing above it), so the
benchmark, the viewer and the CLI all read cases from here; ``chekhov.bench.cases`` re-exports
it for older code.

The code lives in private modules, re-exported here (import from this module, not from them):
:mod:`chekhov._case_file` (the format and :class:`CaseSet`), :mod:`chekhov._case_sampling`
(the per-case stream and the random family's draws), :mod:`chekhov._case_tasks` (the task
family) and :mod:`chekhov._case_generate` (generation and the cache). ``__all__`` lists the
public names; the private ones this module held before the split (``_read_header``,
``_TARGETS``, …) are re-exported too (``_name as _name``) for code that reached into it.
"""

from __future__ import annotations

from chekhov._case_file import _ARRAYS as _ARRAYS
from chekhov._case_file import _FIELDS as _FIELDS
from chekhov._case_file import _LABELS as _LABELS
from chekhov._case_file import _UNITS as _UNITS
from chekhov._case_file import (
    CASE_FORMAT,
    CASE_FORMAT_VERSION,
    FAMILIES,
    READABLE_VERSIONS,
    Array,
    CaseSet,
    check_family,
)
from chekhov._case_file import _check_arrays as _check_arrays
from chekhov._case_file import _check_limits as _check_limits
from chekhov._case_file import _read_header as _read_header
from chekhov._case_file import _read_labels as _read_labels
from chekhov._case_generate import _load_cached as _load_cached
from chekhov._case_generate import _log as _log
from chekhov._case_generate import (
    cache_stem,
    cached_cases,
    default_cache_dir,
    draw_case,
    find_cached,
    generate_cases,
)
from chekhov._case_sampling import DrawnCase, case_rng, sample_case, sample_free
from chekhov._case_tasks import _TARGETS as _TARGETS
from chekhov._case_tasks import (
    GOAL_SOLUTIONS,
    PLACE_CLEARANCE,
    PLACE_SHARE,
    READY_SHARE,
    READY_STATES,
    TASK_TRIES,
    PregraspTarget,
    TaskTargets,
    place_pose,
    ready_configuration,
    sample_task_case,
    task_targets,
)
from chekhov._case_tasks import _aabb as _aabb
from chekhov._case_tasks import _draw_place as _draw_place
from chekhov._case_tasks import _draw_pregrasp as _draw_pregrasp
from chekhov._case_tasks import _free_solutions as _free_solutions
from chekhov._case_tasks import _world_half_extents as _world_half_extents

__all__ = [
    "CASE_FORMAT",
    "CASE_FORMAT_VERSION",
    "FAMILIES",
    "GOAL_SOLUTIONS",
    "PLACE_CLEARANCE",
    "PLACE_SHARE",
    "READABLE_VERSIONS",
    "READY_SHARE",
    "READY_STATES",
    "TASK_TRIES",
    "Array",
    "CaseSet",
    "DrawnCase",
    "PregraspTarget",
    "TaskTargets",
    "cache_stem",
    "cached_cases",
    "case_rng",
    "check_family",
    "default_cache_dir",
    "draw_case",
    "find_cached",
    "generate_cases",
    "place_pose",
    "ready_configuration",
    "sample_case",
    "sample_free",
    "sample_task_case",
    "task_targets",
]
