"""OMPL's RRTConnect, RRT, RRT* and PRM* (PyPI ``ompl`` bindings) on our fast checker.

How each is configured (the same for all four, apart from the objective):

* State space: ``RealVectorStateSpace(K)`` bounded by the joint limits; OMPL's Euclidean
  joint-space metric (rad), the same metric as our path length and motion resolution.
* State validity: ``FastChecker.valid`` (numba) on the state.
* Motions: a custom ``MotionValidator`` — the end state with ``FastChecker.valid`` and the
  interior with ``FastChecker.motions_valid(q0, q1, resolution)`` (one numba call per motion,
  every ``resolution`` rad of joint-space distance) — the same check and resolution as every
  other planner here. OMPL's own validity-checking resolution is set to the same step.
* Goal: ``GoalStates`` holding up to ``n_ik`` collision-free IK solutions of the goal pose
  (``World.solve_ik``); a path ends exactly at one of them.
* Planner parameters: OMPL's defaults, nothing changed — range 0.2 × the space's maximum extent
  (RRT, RRTConnect, RRT*), goal bias 0.05 (RRT, RRT*), RRT* rewiring factor 1.1 with
  k-nearest rewiring, PRM* with its k* connection strategy.
* RRT* and PRM* optimise path length (``PathLengthOptimizationObjective``) with no cost
  threshold, so they **run to their time limit**, as in the paper; RRT and RRTConnect stop at
  the first exact solution.
* ``simplify=False`` (default): the planner's path as it comes; ``True``: OMPL's
  ``PathSimplifier.simplify`` (shortcutting, vertex reduction, B-spline smoothing under the same
  motion check) for at most ``simplify_time_s``, timed separately, and only while the time
  limit allows: it checks its budget between steps, so it is given ``simplify_time_s`` or
  the time left, less :data:`SIMPLIFY_STEP_S`, and is not started when that is not positive
  (the path as it comes). The simplified path is certified here; when it fails (its motions
  are checked every ``resolution`` rad, the certification's 100 substeps a segment are finer,
  and smoothing hugs the obstacles), the path as it came is the answer, and
  ``info["simplified_rejected"]`` says why (that check's time: ``timing_s["simplify_check"]``).

``time_limit_s`` bounds the whole ``plan`` call: IK first, then the planner gets the rest but
a reserve (10% of it, at most 50 ms) for the certification of its path (RRT* and PRM* stop
that much before the limit): an RRT path's long segments are split at 0.16 rad before the 100
substeps, and when the reserve was set certifying one took 9-23 ms (tabletop_pole,
panda_cage; deadline.py's certify_p99_ms; the walk's per-sphere certificates have cut that
since).
Approximate solutions count as failures ("timeout").

PRM* and several goals: OMPL's PRM checks for solutions in a second C++ thread which, with
several goal states, calls the Python validity checker while ``solve`` holds the GIL — a
deadlock in these bindings. We therefore add the goal states as milestones from the calling
thread first (one zero-time ``solve`` per extra goal, counted in the planning time) so that the
solution thread never calls back into Python.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.path_check import PathCertificate
from chekhov.errors import ChekhovError
from chekhov.planners.base import (
    CERTIFY_RESERVE,
    PlannerBase,
    PlanResult,
    search_deadline,
    solve_goal_ik,
)
from chekhov.planners.certify import check_path
from chekhov.planners.query import PlanQuery
from chekhov.planners.status import PlanStatus
from chekhov.world import World

Array = NDArray[np.float64]

PLANNERS = ("RRTConnect", "RRT", "RRTstar", "PRMstar")
_ALIASES = {"rrtconnect": "RRTConnect", "rrt": "RRT", "rrtstar": "RRTstar", "rrt*": "RRTstar",
            "prmstar": "PRMstar", "prm*": "PRMstar"}
OPTIMAL = frozenset({"RRTstar", "PRMstar"})
SIMPLIFY_STEP_S = 0.003
"""s: the longest step of OMPL's simplifier (a shortcutting pass, a B-spline round), which it
does not interrupt: kept back from its budget. Before (2026-12-02), asked for at least one
whole pass, it returned after 5-21 ms under a 5 ms limit in panda_cage (its B-spline
smoothing alone 3-16 ms), and those answers were timeouts; started with the budget alone,
a step still overran it by up to 2.6 ms."""


def _ompl() -> tuple[Any, Any, Any]:
    try:
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou
    except ImportError as e:  # pragma: no cover - ompl is a dependency
        raise ChekhovError("OMPL planners need the PyPI package 'ompl' (pip install ompl)") from e
    return ob, og, ou


class OmplPlanner(PlannerBase):
    """One OMPL planner (``planner`` in RRTConnect, RRT, RRTstar, PRMstar) for one world.

    Args:
        world: the planning world (fast checker, robot, IK).
        planner: OMPL planner name (case-insensitive; "RRT*", "PRM*" accepted).
        resolution: rad, joint-space step of motion checks.
        simplify: post-process the path with OMPL's PathSimplifier.
        simplify_time_s: s, most time spent simplifying.
        n_ik: IK solutions of the goal pose used as goal states.
        seed: seeds the IK restarts (OMPL's own sampler is seeded by OMPL).

    Its state validity is the fast checker's: an end that only the exact checker accepts is
    planned to through its exit (``fast_free_ends``).
    """

    fast_free_ends = True

    def __init__(self, world: World, planner: str = "RRTConnect", *, resolution: float = 0.02,
                 simplify: bool = False, simplify_time_s: float = 1.0, n_ik: int = 4,
                 seed: int | None = None) -> None:
        kind = _ALIASES.get(planner.lower())
        if kind is None:
            raise ChekhovError(f"unknown OMPL planner '{planner}'; available: {list(PLANNERS)}")
        if resolution <= 0:
            raise ChekhovError(f"resolution must be positive, got {resolution}")
        ob, og, ou = _ompl()
        ou.setLogLevel(ou.LOG_WARN)
        self.world = world
        self.kind = kind
        self.name = kind + ("+simplify" if simplify else "")
        self.resolution = float(resolution)
        self.simplify = simplify
        self.simplify_time_s = float(simplify_time_s)
        self.n_ik = int(n_ik)
        self.rng = np.random.default_rng(seed)
        self._ob, self._og = ob, og
        self.counts = {"state_checks": 0, "motion_checks": 0}
        K = world.robot.dof
        self.dof = K
        space = ob.RealVectorStateSpace(K)
        bounds = ob.RealVectorBounds(K)
        for i in range(K):
            bounds.setLow(i, float(world.robot.lower[i]))
            bounds.setHigh(i, float(world.robot.upper[i]))
        space.setBounds(bounds)
        si = ob.SpaceInformation(space)
        fast = world.fast
        world.goal_ik.warmup()   # its IK kernel compiles now, not in the first timed query
        counts = self.counts

        def state_valid(s: Any) -> bool:
            counts["state_checks"] += 1
            return bool(fast.valid(np.array(s[0:K]))[0])

        res = self.resolution

        class _MotionValidator(ob.MotionValidator):  # type: ignore[name-defined]
            def checkMotion(self, s1: Any, s2: Any, *rest: Any) -> bool:
                counts["motion_checks"] += 1
                q1 = np.array(s2[0:K])
                if not fast.valid(q1)[0]:
                    return False
                return bool(fast.motions_valid(np.array(s1[0:K]), q1, res)[0])

        si.setStateValidityChecker(state_valid)
        self._mv = _MotionValidator(si)          # kept alive: OMPL holds a raw reference
        si.setMotionValidator(self._mv)
        si.setStateValidityCheckingResolution(min(1.0, res / space.getMaximumExtent()))
        si.setup()
        self._state_valid = state_valid
        self.si = si
        self.space = space

    # --- helpers ------------------------------------------------------------------------
    def _state(self, q: Array) -> Any:
        s = self.si.allocState()
        for i, v in enumerate(np.asarray(q, dtype=float)):
            s[i] = float(v)
        return s

    def _path_array(self, path: Any) -> Array:
        K = self.dof
        return np.array([path.getState(i)[0:K] for i in range(path.getStateCount())],
                        dtype=float).reshape(-1, K)

    def describe(self) -> dict[str, object]:
        """How the planner is configured (for reports)."""
        p = self._make_planner()
        p.setProblemDefinition(self._ob.ProblemDefinition(self.si))
        p.setup()   # resolves OMPL's defaults (e.g. range from the space's extent)
        d: dict[str, object] = {"planner": self.kind, "resolution": self.resolution,
                                "simplify": self.simplify, "n_ik": self.n_ik,
                                "optimal": self.kind in OPTIMAL}
        for attr in ("getRange", "getGoalBias", "getRewireFactor"):
            if hasattr(p, attr):
                d[attr[3:].lower()] = float(getattr(p, attr)())
        return d

    def _make_planner(self) -> Any:
        return getattr(self._og, self.kind)(self.si)

    # --- planning -----------------------------------------------------------------------
    def _plan(self, query: PlanQuery) -> PlanResult:
        """Plan for a checked query within its time limit (s, IK included)."""
        ob = self._ob
        t0, q_start = query.t0, query.q_start
        robot = self.world.robot
        timing: dict[str, float] = {}
        info: dict[str, object] = {"planner": self.kind}
        c0 = dict(self.counts)

        def done(status: PlanStatus, path: Array | None = None,
                 certificate: PathCertificate | None = None) -> PlanResult:
            info.update({k: self.counts[k] - c0[k] for k in self.counts})
            return PlanResult(path is not None, path, status, time.perf_counter() - t0,
                              timing, info=info, certificate=certificate)

        goals = solve_goal_ik(self.world, query, self.n_ik, timing, info)
        if goals is None:
            return done(PlanStatus.TIMEOUT if query.expired() else PlanStatus.NO_IK)
        if query.expired():
            return done(PlanStatus.TIMEOUT)
        if not (robot.within_limits(q_start)[0] and self.world.fast.is_valid(q_start)):
            return done(PlanStatus.INVALID_START)
        t = time.perf_counter()
        pdef = ob.ProblemDefinition(self.si)
        pdef.addStartState(self._state(q_start))
        gs = ob.GoalStates(self.si)
        for q in goals:
            gs.addState(self._state(q))
        pdef.setGoal(gs)
        if self.kind in OPTIMAL:
            pdef.setOptimizationObjective(ob.PathLengthOptimizationObjective(self.si))
        planner = self._make_planner()
        planner.setProblemDefinition(pdef)
        planner.setup()
        if hasattr(planner, "getRange"):
            info["range"] = float(planner.getRange())
        if self.kind == "PRMstar":   # goal milestones from this thread (module docstring)
            for _ in range(len(goals) - 1):
                planner.solve(ob.plannerAlwaysTerminatingCondition())
        timing["setup"] = time.perf_counter() - t
        t = time.perf_counter()
        # leave time for the path's certification: an answer after the limit is a timeout
        remaining = search_deadline(query, t) - t
        status = planner.solve(max(remaining, 1e-6)) if remaining > 0 else None
        timing["solve"] = time.perf_counter() - t
        info["ompl_status"] = status.asString() if status is not None else "not run"
        exact = (status is not None
                 and status.getStatus() == ob.PlannerStatus.PlannerStatusType.EXACT_SOLUTION)
        if not exact:
            return done(PlanStatus.TIMEOUT)
        path = pdef.getSolutionPath()
        info["raw_waypoints"] = int(path.getStateCount())
        if not self.simplify:
            return done(PlanStatus.SOLVED, self._path_array(path))
        return done(PlanStatus.SOLVED, *self._simplified(path, gs, query, timing, info))

    def _simplified(self, path: Any, goal: Any, query: PlanQuery, timing: dict[str, float],
                    info: dict[str, object]) -> tuple[Array, PathCertificate | None]:
        """The OMPL ``path`` simplified within its budget, with its certificate — or, when
        the simplified path fails the certification, the path as it came (module
        docstring)."""
        raw = self._path_array(path)
        t = time.perf_counter()
        budget = min(self.simplify_time_s,
                     query.remaining() * (1 - CERTIFY_RESERVE)) - SIMPLIFY_STEP_S
        if budget <= 0:      # OMPL's "at least once" would run a whole pass past the budget
            timing["simplify"] = time.perf_counter() - t
            return raw, None
        self._og.PathSimplifier(self.si, goal).simplify(path, budget, False)
        simplified = self._path_array(path)
        timing["simplify"] = time.perf_counter() - t
        t = time.perf_counter()
        why, certificate = check_path(self.world, query, simplified)
        timing["simplify_check"] = time.perf_counter() - t
        if why is None:
            return simplified, certificate
        info["simplified_rejected"] = f"{why[0].value}: {why[1]}"
        return raw, None
