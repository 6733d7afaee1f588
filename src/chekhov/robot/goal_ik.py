"""The one goal resolver: a :class:`~chekhov.robot.goal.Goal` → the joint configurations that
meet it, for every planner.

A configuration goal is its configuration. A pose goal is solved by damped least squares from
the seeds a caller knows to be good (the start, the roadmap nodes whose end-effector poses are
nearest), then from random restarts, compiled (:class:`ChainKinematics`, ~10–30 µs a solve) for
a serial revolute chain — more rounds of them when every solution found collides; when that
finds nothing (or the chain is not serial) pinocchio's thorough
:func:`~chekhov.robot.ik.solve_ik` has its restarts (none after the deadline). Only solutions the
caller's ``valid`` accepts (collision-free, by the fast checker) count.

Random restarts draw from ``np.random.default_rng(seed)`` made afresh for every call, so the same
query gets the same goal configurations every time.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chekhov.errors import ChekhovError, IKError
from chekhov.robot.chain_kinematics import ChainKinematics
from chekhov.robot.goal import Goal
from chekhov.robot.ik import solve_ik
from chekhov.robot.robot import Robot, joint_axis

Array = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

TURN = 2.0 * math.pi


@dataclass(frozen=True)
class GoalIKConfig:
    """Settings of :class:`GoalResolver`.

    Attributes:
        random_seeds: random restarts per compiled round. random_rounds: compiled rounds of
            random restarts after the caller's seeds (none start after the deadline).
        obstructed_rounds: more such rounds when solutions were found but every one was in
            collision (the pose is reachable, its free solutions rare). Measured: an xArm7
            pre-grasp in shelf_boxes had valid solutions from 1.8% of random seeds; the 4
            rounds and pinocchio's 40 restarts found none, and Roadmap + TrajOpt answered
            "no_ik" at 68 ms of a 2 s limit where RRTConnect (another seed order) solved it.
        min_separation: rad, solutions closer than this (joint-space norm) are one.
        thorough: when the compiled rounds find nothing, pinocchio's ``solve_ik`` (slower;
            up to ``IKConfig.max_restarts`` restarts, none after the deadline).
        seed: seed of the random restarts (a fresh generator per call).
    """

    random_seeds: int = 32
    random_rounds: int = 4
    obstructed_rounds: int = 60
    min_separation: float = 0.1
    thorough: bool = True
    seed: int = 0


@dataclass(frozen=True, eq=False)
class GoalConfigurations:
    """What :meth:`GoalResolver.resolve` found.

    Attributes:
        Q: (n, K) rad, distinct valid configurations meeting the goal (n = 0: none).
        reason: why there are none ("" when there are).
    """

    Q: Array
    reason: str

    def __len__(self) -> int:
        return len(self.Q)

    def nearest(self, q: Array) -> Array:
        """The configuration nearest q (K,) in joint space; IKError when there is none."""
        if len(self.Q) == 0:
            raise IKError(self.reason)
        return self.Q[int(np.argmin(np.linalg.norm(self.Q - q, axis=1)))]


class GoalResolver:
    """Goal configurations of one robot, accepted by ``valid`` (a batch test (N, K) → (N,) bool,
    e.g. ``FastChecker.valid``)."""

    def __init__(self, robot: Robot, valid: Callable[[Array], BoolArray],
                 config: GoalIKConfig | None = None) -> None:
        self.robot = robot
        self.valid = valid
        self.config = config if config is not None else GoalIKConfig()
        revolute = np.zeros(robot.dof, dtype=bool)
        for j in robot.model.joints[1:]:   # continuous joints are bounded revolute ones here
            revolute[j.idx_q] = joint_axis(j) is not None
        self._full_turn = revolute & (robot.upper - robot.lower >= TURN)
        try:
            self.kinematics: ChainKinematics | None = ChainKinematics.from_robot(robot)
        except ChekhovError:
            self.kinematics = None  # not a serial revolute chain: pinocchio only

    def warmup(self) -> None:
        """Compile (or load) the IK kernel now rather than in the first timed query."""
        if self.kinematics is not None:
            self.kinematics.solve(np.eye(4), self.robot.lower[None], max_iterations=1)

    def resolve(self, goal: Goal, *, n: int, seeds: Array | None = None,
                near: Array | None = None, deadline: float = math.inf) -> GoalConfigurations:
        """Up to n distinct valid configurations meeting ``goal``.

        Args:
            seeds: (M, K) rad, tried first, in order. near: (K,) rad; when given, tried first
                of all and the result is sorted by joint distance to it (else seed order).
            deadline: ``time.perf_counter()`` value, s; no restart round begins after it.
        """
        if goal.q is not None:
            q = self.robot.check_configuration(goal.q, "goal configuration")
            ok = bool(self.robot.within_limits(q)[0] and self.valid(q[None])[0])
            if ok:
                return GoalConfigurations(q[None], "")
            return self._none("the goal configuration is in collision or outside the joint "
                              "limits")
        assert goal.T_world_ee is not None
        T = goal.T_world_ee
        shoulder, reach = self.robot.reach
        dist = float(np.linalg.norm(T[:3, 3] - shoulder))
        if dist > reach:
            return self._none(f"position {np.round(T[:3, 3], 3).tolist()} is {dist:.3f} m from "
                              f"the arm's first joint, beyond its reach of {reach:.3f} m")
        first = [np.asarray(near, dtype=float)[None]] if near is not None else []
        if seeds is not None and len(seeds):
            first.append(np.asarray(seeds, dtype=float))
        # a start alone rarely converges to n solutions: without the caller's seeds, the first
        # round also gets a random batch (as the straight-line TrajOpt's IK always had)
        Q, tried = self._compiled(T, first, n, deadline, pad=seeds is None or not len(seeds))
        if len(Q) == 0 and self.config.thorough and time.perf_counter() < deadline:
            Q, why = self._thorough(T, n, near, deadline)
            if len(Q) == 0:
                return self._none(why)
        elif len(Q) == 0:
            return self._none(f"no valid IK solution from {tried} seeds"
                              + (" (time limit reached)" if time.perf_counter() >= deadline
                                 else ""))
        if near is not None:
            Q = self._nearest_turns(Q, np.asarray(near, dtype=float))
        Q = distinct_rows(Q, self.config.min_separation, n)
        if near is not None:
            Q = Q[np.argsort(np.linalg.norm(Q - near, axis=1), kind="stable")]
        return GoalConfigurations(Q, "")

    def _nearest_turns(self, Q: Array, near: Array) -> Array:
        """Q (M, K) rad with each revolute joint whose limits span a full turn or more (a
        UR arm's ±2π, a Kinova's continuous ones) moved by whole turns to the value nearest
        ``near``'s (K,) within its limits: the same pose and the same geometry, a shorter
        move. The IK lands a joint in whichever turn its seed led to: a Jaco's pose goals on
        the pole's table, 20 queries, mean path 4.94 → 3.79 rad (``benchmarks/arms.py``). A
        row the checker ``valid`` rejects once moved (rounding) stays as it was."""
        turns = self._full_turn
        if not turns.any() or len(Q) == 0:
            return Q
        lo, hi = self.robot.lower, self.robot.upper
        out = Q + TURN * np.round((near - Q) / TURN) * turns
        out = np.where(out > hi, out - TURN, out)
        out = np.where(out < lo, out + TURN, out)
        out = np.where((out < lo) | (out > hi), Q, out)    # limits less than two turns apart
        moved = np.flatnonzero((out != Q).any(axis=1))
        if len(moved):
            refused = moved[~self.valid(out[moved])]
            out[refused] = Q[refused]
        return out

    def nearest(self, goal: Goal, q_near: Array, *, n: int = 6,
                deadline: float = math.inf) -> Array:
        """The valid goal configuration nearest q_near (K,) among up to n found; raises
        :class:`IKError` (with the reason) when there is none."""
        return self.resolve(goal, n=n, near=q_near, deadline=deadline).nearest(q_near)

    def _none(self, reason: str) -> GoalConfigurations:
        return GoalConfigurations(np.empty((0, self.robot.dof)), reason)

    def _compiled(self, T: Array, first: list[Array], n: int, deadline: float,
                  pad: bool = False) -> tuple[Array, int]:
        """Valid solutions from the caller's seeds (with ``pad``, and a random batch), then
        random rounds (``obstructed_rounds`` more once a solution was found in collision);
        (solutions, seeds tried)."""
        if self.kinematics is None:
            return np.empty((0, self.robot.dof)), 0
        cfg = self.config
        rng = np.random.default_rng(cfg.seed)
        rounds = [np.vstack(first)] if first else []
        if rounds and pad:
            rounds[0] = np.vstack([rounds[0], self.robot.sample_uniform(rng, cfg.random_seeds)])
        tried = r = 0
        sols = np.empty((0, self.robot.dof))
        converged = False
        while r < len(rounds) + cfg.random_rounds + (cfg.obstructed_rounds if converged else 0):
            if r and time.perf_counter() >= deadline:
                break
            S = (rounds[r] if r < len(rounds)
                 else self.robot.sample_uniform(rng, cfg.random_seeds))
            tried += len(S)
            r += 1
            Q, ok = self.kinematics.solve(T, S, stop_after=n)
            Q = Q[ok]
            converged = converged or len(Q) > 0
            sols = Q[self.valid(Q)] if len(Q) else Q
            if len(sols):
                break
        return sols, tried

    def _thorough(self, T: Array, n: int, near: Array | None, deadline: float
                  ) -> tuple[Array, str]:
        try:
            Q = solve_ik(self.robot, T, n, q_seed=near,
                         rng=np.random.default_rng(self.config.seed),
                         accept=lambda q: bool(self.valid(q[None])[0]), deadline=deadline)
        except IKError as e:
            return np.empty((0, self.robot.dof)), str(e)
        return Q, ""


def distinct_rows(Q: Array, min_dist: float, n: int) -> Array:
    """The first rows of Q (M, K), in order, each at least ``min_dist`` rad from those kept
    before it; at most n."""
    if len(Q) == 0:
        return Q[:0]
    # all pairwise distances at once, then the greedy pass in plain Python (a norm call per
    # pair cost ~3 µs; queries ask this for 10-30 rows, several times)
    D = np.sqrt(((Q[:, None, :] - Q[None, :, :]) ** 2).sum(axis=2)).tolist()
    keep: list[int] = []
    for i, row in enumerate(D):
        if all(row[j] >= min_dist for j in keep):
            keep.append(i)
            if len(keep) == n:
                break
    return Q[keep]
