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

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.path_check import PathCertificate, PathDecision, exact_path_decision
from chekhov.errors import DeadlineError
from chekhov.trajopt.problem import Evaluation, TrajOptProblem
from chekhov.trajopt.qp import TrajOptQP, term_counts
from chekhov.trajopt.result import TrajOptResult
from chekhov.world import World

Array = NDArray[np.float64]


SUCCESS = frozenset({"converged", "iteration_limit", "exact_clear"})

FIRST_STEP_S = 2.5e-3
"""s: expected cost of the first SQP step (OSQP's setup and factorisation, one ADMM solve, one
evaluation), for not starting a step that cannot finish by the time limit."""


def solve_trajopt(problem: TrajOptProblem, deadline: float = math.inf) -> TrajOptResult:
    """Optimise the problem's seed; validate the result as ``config.validate`` says.

    A result that fails the validation gets status "collision" and ``success`` False. The
    optimisation and validation end by ``config.time_limit_s`` after the call or by
    ``deadline`` (a ``time.perf_counter()`` value, s: a planner's query deadline), whichever
    comes first.
    """
    cfg = problem.config
    t_start = time.perf_counter()
    cpu_start = time.process_time()
    deadline = min(deadline, t_start + cfg.time_limit_s)
    timing = {"collision": 0.0, "linearise": 0.0, "qp": 0.0, "validate": 0.0}
    T, K = problem.n_waypoints, problem.dof
    x = problem.seed.ravel().copy()
    try:
        ev = problem.evaluate(problem.seed, timing, deadline)
    except DeadlineError:
        return _timed_out(problem, t_start, timing)
    if time.perf_counter() + FIRST_STEP_S > deadline:
        return _timed_out(problem, t_start, timing)
    qp = _sized_qp(problem, ev, None)
    rebuilds = 0
    mu = cfg.initial_penalty
    trust = cfg.initial_trust_rad
    iterations = penalty_increases = 0
    converged = False
    out_of_budget = False
    step_s = FIRST_STEP_S
    for _ in range(cfg.max_penalty_increases + 1):
        converged = False
        while True:
            merit_old = problem.merit(ev, mu)
            accepted = False
            while trust >= cfg.min_trust_rad:
                # a step that cannot finish by the deadline is not started (its cost: the
                # last step's, or FIRST_STEP_S for the first, which sets OSQP up)
                if iterations >= cfg.max_iterations or \
                        time.perf_counter() + step_s > deadline:
                    out_of_budget = True
                    break
                t0 = time.perf_counter()
                if not qp.fits(ev):  # more terms than rows: a larger pattern, set up anew
                    if t0 + FIRST_STEP_S > deadline:
                        out_of_budget = True
                        break
                    qp = _sized_qp(problem, ev, qp)
                    rebuilds += 1
                x_new, model, _ = qp.solve(ev, x, trust, mu,
                                           max(deadline - time.perf_counter(), 1e-5))
                timing["qp"] += time.perf_counter() - t0
                iterations += 1
                if time.perf_counter() > deadline:   # no time left to evaluate the step
                    out_of_budget = True
                    break
                approx = merit_old - model
                if approx < cfg.min_approx_improve or \
                        approx < cfg.min_approx_improve_frac * abs(merit_old):
                    converged = True
                    break
                try:
                    ev_new = problem.evaluate(x_new.reshape(T, K), timing, deadline)
                except DeadlineError:
                    out_of_budget = True
                    break
                step_s = time.perf_counter() - t0
                exact = merit_old - problem.merit(ev_new, mu)
                if exact > cfg.improve_ratio_threshold * approx:
                    x, ev = x_new, ev_new
                    trust *= cfg.trust_expand
                    accepted = True
                    break
                trust *= cfg.trust_shrink
            if trust < cfg.min_trust_rad:
                converged = True
            if converged or out_of_budget or not accepted:
                break
        if out_of_budget or problem.satisfied(ev):
            break
        if penalty_increases == cfg.max_penalty_increases:
            break
        mu *= cfg.penalty_increase
        penalty_increases += 1
        trust = max(trust, cfg.initial_trust_rad)
    Q = x.reshape(T, K)
    satisfied = problem.satisfied(ev)
    cpu_s = time.process_time() - cpu_start
    status = ("converged" if converged else "iteration_limit") if satisfied else "infeasible"
    valid: bool | None = None
    certificate: PathCertificate | None = None
    t0 = time.perf_counter()
    clearance_only = cfg.accept_exact_clear and problem.unmet(ev) == {"collision_m"}
    if cfg.validate != "none" and (satisfied or clearance_only):
        # short of the sphere model's margin only: the checker decides (config docstring)
        valid, certificate = validate_path(problem.world, Q, cfg.validate, cfg.substeps,
                                           deadline)
        if valid is None:
            status = "timeout"
        elif satisfied and not valid:
            status = "collision"
        elif not satisfied and valid:
            status = "exact_clear"
    timing["validate"] = time.perf_counter() - t0
    total = time.perf_counter() - t_start
    timing["other"] = max(0.0, total - sum(timing.values()))
    timing["total"] = total
    return TrajOptResult(
        trajectory=Q, status=status, success=status in SUCCESS,
        valid=valid, certificate=certificate, costs={"smoothness": problem.smoothness(Q),
                            "merit": problem.merit(ev, mu)},
        violations=problem.constraint_report(ev), iterations=iterations,
        penalty_increases=penalty_increases, timing_s=timing, seed=problem.seed,
        info={"cpu_s": cpu_s, "penalty": mu, "trust_rad": trust, "qp_rebuilds": rebuilds,
              "admm_iterations": qp.admm_iterations})


def validate_path(world: World, path: Array, mode: str = "exact", substeps: int = 100,
                  deadline: float = math.inf) -> PathDecision:
    """Whether a path (T, K) is collision-free at its waypoints and ``substeps`` interpolated
    configurations per segment (the paper's check): (True / False / None when ``deadline``, a
    ``time.perf_counter()`` value, passed first, certificate).

    "exact": the exact checker's decision, fast: the fast checker screens the same
    configurations and, since its spheres contain the robot's collision geometry (fast free ⇒
    exact free), coal runs only on its alarms
    (:func:`chekhov.collision.path_check.exact_path_decision`; only this mode leaves a
    certificate). "exact_full": the exact checker on every configuration. "fast": the fast
    checker alone (conservative).
    """
    if mode == "exact":
        return exact_path_decision(world.fast, world.exact, path, substeps, deadline)
    if mode == "exact_full":
        return PathDecision(world.exact.path_valid(path, substeps=substeps), None)
    return PathDecision(world.fast.dense_path_valid(path, substeps), None)


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
    return TrajOptQP(problem, w, s)


_HEADROOM = 1
