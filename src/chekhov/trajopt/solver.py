"""The TrajOpt algorithm: l1-penalty SQP with a box trust region (Schulman et al. 2014, Alg. 1).

    for each penalty coefficient μ = μ₀, kμ₀, k²μ₀, …:
        repeat:  convexify at x̄ (distance terms, goal and torque Jacobians)
                 repeat:  solve the QP in the trust box; ratio = true / model merit improvement
                          accept and grow the box if ratio > c, else shrink it
        until the model improvement or the box is tiny
        stop when every constraint holds
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.path_check import (
    CERTIFY_MAX_SEGMENT_RAD,
    PathCertificate,
    PathDecision,
    exact_path_decision,
    path_digest,
)
from chekhov.errors import DeadlineError
from chekhov.paths import path_length, resample_path
from chekhov.trajopt.problem import Evaluation, TrajOptError, TrajOptProblem, build_trajopt
from chekhov.trajopt.qp import TrajOptQP, term_counts
from chekhov.trajopt.result import TrajOptResult
from chekhov.world import World

Array = NDArray[np.float64]


SUCCESS = frozenset({"converged", "iteration_limit", "exact_clear"})

ABANDON_AFTER_STEPS = 2
"""Accepted steps before ``solve_trajopt``'s ``abandon_above_rad`` is looked at: the first step
from a seed is often the longest (the collision terms push the path off the obstacles it
hugs), the second shows where the run is heading (see ``RoadmapTrajOptConfig.abandon_ratio``)."""

STALL_TOLERANCE_M = 1e-5
"""m: a penalty level that lowers the collision violation by less leaves it where it was
(``TrajOptConfig.stall_levels``)."""

FIRST_STEP_S = 2.5e-3
"""s: expected cost of the first SQP step (OSQP's setup and factorisation, one ADMM solve, one
evaluation), for not starting a step that cannot finish by the time limit."""


@dataclass
class _SQPState:
    """The SQP's state as it runs (mutable: one per ``solve_trajopt`` call).

    Attributes:
        x: the current trajectory, flattened (T·K,) rad. ev: its evaluation.
        qp: the QP subproblem (rebuilt larger when the terms outgrow it; ``rebuilds`` counts).
        mu: the penalty coefficient. trust: the trust box's half-width, rad.
        deadline: ``time.perf_counter()`` value, s. step_s: s, expected cost of the next step.
        timing: s per phase (collision, linearise, qp, validate, …).
        converged / out_of_budget / abandoned: why the current penalty's loop ended;
        stalled: the penalty loop ended on ``stall_levels``; validated: (x, its exact
        validation) made at the end of a level short of the sphere model's clearance only
        (``validate_each_level``), reused when x is the final trajectory.
        accepted: steps accepted. abandon_above: rad, the length that abandons the run.
    """

    x: Array
    ev: Evaluation
    qp: TrajOptQP
    mu: float
    trust: float
    deadline: float
    timing: dict[str, float]
    step_s: float = FIRST_STEP_S
    iterations: int = 0
    penalty_increases: int = 0
    rebuilds: int = 0
    converged: bool = False
    out_of_budget: bool = False
    accepted: int = 0
    abandon_above: float = math.inf
    abandoned: bool = False
    stalled: bool = False
    validated: tuple[Array, PathDecision] | None = None


def solve_trajopt(problem: TrajOptProblem, deadline: float = math.inf, *,
                  abandon_above_rad: float = math.inf) -> TrajOptResult:
    """Optimise the problem's seed; validate the result as ``config.validate`` says.

    A result that fails the validation is refined (``config.refine_rounds``: its colliding
    segments split, the optimisation continued) while time is left, and otherwise gets status
    "collision" and ``success`` False. The optimisation and validation end by
    ``config.time_limit_s`` after the call or by ``deadline`` (a ``time.perf_counter()``
    value, s: a planner's query deadline), whichever comes first. ``abandon_above_rad``: an
    anytime caller's answer so far (joint-space length, rad); once the trajectory is longer
    than that after :data:`ABANDON_AFTER_STEPS` accepted steps, the run stops with status
    "abandoned" (not a success, not validated). ``result.info["refinements"]`` counts the
    refinements; iterations and timings are summed over them.
    """
    deadline = min(deadline, time.perf_counter() + problem.config.time_limit_s)
    result = _solve_once(problem, deadline, abandon_above_rad)
    for rounds in range(1, problem.config.refine_rounds + 1):
        if result.status != "collision" or time.perf_counter() + FIRST_STEP_S > deadline:
            break
        seed = _split_colliding(problem, result.trajectory, deadline)
        if seed is None:
            break
        try:
            refined = build_trajopt(problem.world, problem.q_start, problem.goal, seed,
                                    problem.config, problem.distances)
        except TrajOptError:   # the first problem's checks passed: not expected
            break
        again = _solve_once(refined, deadline, abandon_above_rad)
        result = _after_refinement(result, again, rounds)
    return result


def _split_colliding(problem: TrajOptProblem, Q: Array, deadline: float) -> Array | None:
    """Q (T, K) rad with a midpoint inserted in each segment whose own exact decision (at
    ``config.substeps``, split as the validation splits it) fails; None when there is none or
    ``deadline`` passed first."""
    cfg = problem.config
    bad = []
    for i in range(len(Q) - 1):
        valid = validate_path(problem.world, Q[i:i + 2], "exact", cfg.substeps, deadline,
                              max_segment_rad=cfg.validate_max_segment_rad).valid
        if valid is None:
            return None
        if not valid:
            bad.append(i)
    if not bad:
        return None
    mids = 0.5 * (Q[bad] + Q[np.asarray(bad) + 1])
    return np.insert(Q, np.asarray(bad) + 1, mids, axis=0)


def _after_refinement(before: TrajOptResult, after: TrajOptResult, rounds: int
                      ) -> TrajOptResult:
    """The refined run's result with the runs' iterations and timings summed, the first
    run's seed, and ``info["refinements"]``."""
    timing = {k: before.timing_s.get(k, 0.0) + after.timing_s.get(k, 0.0)
              for k in before.timing_s.keys() | after.timing_s.keys()}
    return replace(after, iterations=before.iterations + after.iterations,
                   penalty_increases=before.penalty_increases + after.penalty_increases,
                   timing_s=timing, seed=before.seed,
                   info={**after.info, "refinements": rounds})


def _solve_once(problem: TrajOptProblem, deadline: float, abandon_above_rad: float
                ) -> TrajOptResult:
    """One optimisation of the problem's seed until ``deadline``, validated."""
    cfg = problem.config
    t_start = time.perf_counter()
    cpu_start = time.process_time()
    timing = {"collision": 0.0, "linearise": 0.0, "qp": 0.0, "validate": 0.0}
    try:
        ev = problem.evaluate(problem.seed, timing, deadline)
    except DeadlineError:
        return _timed_out(problem, t_start, timing)
    if time.perf_counter() + FIRST_STEP_S > deadline:
        return _timed_out(problem, t_start, timing)
    state = _SQPState(x=problem.seed.ravel().copy(), ev=ev, qp=_sized_qp(problem, ev, None),
                      mu=cfg.initial_penalty, trust=cfg.initial_trust_rad, deadline=deadline,
                      timing=timing, abandon_above=abandon_above_rad)
    _penalty_loop(problem, state)
    cpu_s = time.process_time() - cpu_start
    return _finish(problem, state, t_start, cpu_s)


def _penalty_loop(problem: TrajOptProblem, s: _SQPState) -> None:
    """The outer loop: optimise at each penalty μ = μ₀, kμ₀, … until the constraints hold,
    the budget ends, ``max_penalty_increases`` is reached or the collision violation stalls
    (``stall_levels``)."""
    cfg = problem.config
    flat = 0      # penalty levels in a row (after the first raise) that left it where it was
    before = 0.0  # m, the collision violation as the level began (read only with stall_levels)
    for _ in range(cfg.max_penalty_increases + 1):
        _optimise_at_penalty(problem, s)
        if s.out_of_budget or s.abandoned or problem.satisfied(s.ev) or _cleared(problem, s):
            break
        if s.penalty_increases == cfg.max_penalty_increases:
            break
        if cfg.stall_levels > 0:   # a level starts where the one before it ended
            after = problem.constraint_report(s.ev)["collision_m"]
            if s.penalty_increases >= 1:
                flat = flat + 1 if after > 0.0 and after >= before - STALL_TOLERANCE_M else 0
                if flat >= cfg.stall_levels:
                    s.stalled = True
                    break
            before = after
        s.mu *= cfg.penalty_increase
        s.penalty_increases += 1
        s.trust = max(s.trust, cfg.initial_trust_rad)


def _cleared(problem: TrajOptProblem, s: _SQPState) -> bool:
    """With ``validate_each_level``: whether the trajectory, short of the sphere model's
    clearance only, passes the exact validation now (kept in ``s.validated``), so that no
    higher penalty pushes it off obstacles that its links do not touch."""
    cfg = problem.config
    if not (cfg.validate_each_level and cfg.validate != "none" and _clearance_only(problem, s)):
        return False
    t0 = time.perf_counter()
    valid = _validation(problem, s).valid
    s.timing["validate"] += time.perf_counter() - t0
    return valid is True


def _clearance_only(problem: TrajOptProblem, s: _SQPState) -> bool:
    """Whether the sphere model's clearance is the only unmet constraint at s.ev and the
    config lets the exact validation decide then (``accept_exact_clear``)."""
    return problem.config.accept_exact_clear and problem.unmet(s.ev) == {"collision_m"}


def _validation(problem: TrajOptProblem, s: _SQPState) -> PathDecision:
    """The exact validation (``config.validate``) of the trajectory s.x, made once per x (kept
    in ``s.validated``)."""
    if s.validated is None or s.validated[0] is not s.x:
        cfg = problem.config
        s.validated = (s.x, validate_path(
            problem.world, s.x.reshape(problem.n_waypoints, problem.dof), cfg.validate,
            cfg.substeps, s.deadline, max_segment_rad=cfg.validate_max_segment_rad))
    return s.validated[1]


def _optimise_at_penalty(problem: TrajOptProblem, s: _SQPState) -> None:
    """Convexify and take trust-region steps at the current penalty until the model's
    improvement or the trust box is tiny, no step is accepted, or the budget ends."""
    s.converged = False
    while True:
        accepted = _trust_region_step(problem, s, problem.merit(s.ev, s.mu))
        if s.trust < problem.config.min_trust_rad:
            s.converged = True
        if accepted:
            s.accepted += 1
            s.abandoned = (s.accepted >= ABANDON_AFTER_STEPS and path_length(
                s.x.reshape(problem.n_waypoints, problem.dof)) > s.abandon_above)
        if s.converged or s.out_of_budget or s.abandoned or not accepted:
            break


def _trust_region_step(problem: TrajOptProblem, s: _SQPState, merit_old: float) -> bool:
    """Solve the QP in the trust box, shrinking the box until the true merit improvement is
    a large enough share of the model's (then accept the step and grow the box: True).
    False when the box became tiny, the model's improvement is tiny (``s.converged``) or the
    budget ended (``s.out_of_budget``)."""
    cfg = problem.config
    while s.trust >= cfg.min_trust_rad:
        # a step that cannot finish by the deadline is not started (its cost: the last
        # step's, or FIRST_STEP_S for the first, which sets OSQP up)
        if s.iterations >= cfg.max_iterations or time.perf_counter() + s.step_s > s.deadline:
            s.out_of_budget = True
            return False
        t0 = time.perf_counter()
        if not s.qp.fits(s.ev):  # more terms than rows: a larger pattern, set up anew
            if t0 + FIRST_STEP_S > s.deadline:
                s.out_of_budget = True
                return False
            s.qp = _sized_qp(problem, s.ev, s.qp)
            s.rebuilds += 1
        x_new, model, _ = s.qp.solve(s.ev, s.x, s.trust, s.mu,
                                     max(s.deadline - time.perf_counter(), 1e-5))
        s.timing["qp"] += time.perf_counter() - t0
        s.iterations += 1
        if time.perf_counter() > s.deadline:   # no time left to evaluate the step
            s.out_of_budget = True
            return False
        approx = merit_old - model
        if approx < cfg.min_approx_improve or \
                approx < cfg.min_approx_improve_frac * abs(merit_old):
            s.converged = True
            return False
        try:
            ev_new = problem.evaluate(x_new.reshape(problem.n_waypoints, problem.dof),
                                      s.timing, s.deadline)
        except DeadlineError:
            s.out_of_budget = True
            return False
        s.step_s = time.perf_counter() - t0
        if merit_old - problem.merit(ev_new, s.mu) > cfg.improve_ratio_threshold * approx:
            s.x, s.ev = x_new, ev_new
            s.trust *= cfg.trust_expand
            return True
        s.trust *= cfg.trust_shrink
    return False


def _finish(problem: TrajOptProblem, s: _SQPState, t_start: float, cpu_s: float
            ) -> TrajOptResult:
    """The result of the SQP's last trajectory, validated (``config.validate``)."""
    Q = s.x.reshape(problem.n_waypoints, problem.dof)
    t0 = time.perf_counter()
    status, valid, certificate = _validated_status(problem, s)
    s.timing["validate"] += time.perf_counter() - t0
    total = time.perf_counter() - t_start
    s.timing["other"] = max(0.0, total - sum(s.timing.values()))
    s.timing["total"] = total
    return TrajOptResult(
        trajectory=Q, status=status, success=status in SUCCESS,
        valid=valid, certificate=certificate, costs={"smoothness": problem.smoothness(Q),
                                                     "merit": problem.merit(s.ev, s.mu)},
        violations=problem.constraint_report(s.ev), iterations=s.iterations,
        penalty_increases=s.penalty_increases, timing_s=s.timing, seed=problem.seed,
        info={"cpu_s": cpu_s, "penalty": s.mu, "trust_rad": s.trust,
              "qp_rebuilds": s.rebuilds, "admm_iterations": s.qp.admm_iterations,
              "stalled": s.stalled})


def _validated_status(problem: TrajOptProblem, s: _SQPState
                      ) -> tuple[str, bool | None, PathCertificate | None]:
    """(status, the validation's decision, its certificate) of the final trajectory s.x:
    "converged" / "iteration_limit" / "infeasible" / "abandoned" from the SQP, then
    "timeout", "collision" or "exact_clear" as the validation decides."""
    cfg = problem.config
    if s.abandoned:
        return "abandoned", None, None
    satisfied = problem.satisfied(s.ev)
    status = ("converged" if s.converged else "iteration_limit") if satisfied else "infeasible"
    if cfg.validate == "none" or not (satisfied or _clearance_only(problem, s)):
        return status, None, None
    # short of the sphere model's margin only: the checker decides (config docstring)
    valid, certificate = _validation(problem, s)
    if valid is None:
        status = "timeout"
    elif satisfied and not valid:
        status = "collision"
    elif not satisfied and valid:
        status = "exact_clear"
    return status, valid, certificate


def validate_path(world: World, path: Array, mode: str = "exact", substeps: int = 100,
                  deadline: float = math.inf, *, max_segment_rad: float = math.inf
                  ) -> PathDecision:
    """Whether a path (T, K) is collision-free at its waypoints and ``substeps`` interpolated
    configurations per segment (the paper's check), each segment longer than
    ``max_segment_rad`` (rad) split evenly first: (True / False / None when ``deadline``, a
    ``time.perf_counter()`` value, passed first, certificate — of the split path; at the
    certification's split, ``CERTIFY_MAX_SEGMENT_RAD``, it also names ``path`` as what was
    resampled, so ``planners.certify`` need not check ``path`` again).

    "exact": the exact checker's decision, fast: the fast checker screens the same
    configurations and, since its spheres contain the robot's collision geometry (fast free ⇒
    exact free), coal runs only on its alarms
    (:func:`chekhov.collision.path_check.exact_path_decision`; only this mode leaves a
    certificate). "exact_full": the exact checker on every configuration. "fast": the fast
    checker alone (conservative).
    """
    P = np.atleast_2d(np.asarray(path, dtype=float))
    D = resample_path(P, max_segment_rad) if len(P) > 1 and math.isfinite(max_segment_rad) \
        else P
    if mode == "exact":
        valid, certificate = exact_path_decision(world.fast, world.exact, D, substeps, deadline)
        if certificate is not None and D is not P \
                and max_segment_rad == CERTIFY_MAX_SEGMENT_RAD:   # the certification's split
            certificate = replace(certificate, resampled_from=path_digest(P))
        return PathDecision(valid, certificate)
    if mode == "exact_full":
        return PathDecision(world.exact.path_valid(D, substeps=substeps), None)
    return PathDecision(world.fast.dense_path_valid(D, substeps), None)


def _timed_out(problem: TrajOptProblem, t_start: float, timing: dict[str, float]
               ) -> TrajOptResult:
    """The result when the time limit passes before the first step (the seed's evaluation,
    or no time left for a step after it)."""
    timing["total"] = time.perf_counter() - t_start
    return TrajOptResult(
        trajectory=problem.seed.copy(), status="timeout", success=False, valid=None,
        certificate=None, costs={}, violations={}, iterations=0, penalty_increases=0,
        timing_s=timing, seed=problem.seed, info={"cpu_s": 0.0, "penalty": 0.0,
                                                  "trust_rad": 0.0, "qp_rebuilds": 0,
                                                  "admm_iterations": 0})


def _sized_qp(problem: TrajOptProblem, ev: Evaluation, old: TrajOptQP | None) -> TrajOptQP:
    """A QP with room for every term at ev plus ``_HEADROOM`` per waypoint and segment (terms
    appear as the trajectory moves), and at least the old capacities."""
    w, s = term_counts(ev)
    w, s = w + _HEADROOM, s + _HEADROOM
    if old is not None:
        w = np.maximum(w, old.waypoint_capacity)
        s = np.maximum(s, old.segment_capacity)
    qp = TrajOptQP(problem, w, s)
    if old is not None:    # info["admm_iterations"] counts the whole run's
        qp.admm_iterations = old.admm_iterations
    return qp


_HEADROOM = 1
