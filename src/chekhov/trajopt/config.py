"""Settings of the trajectory optimiser."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

from chekhov.collision.path_check import CERTIFY_MAX_SEGMENT_RAD
from chekhov.errors import ChekhovError


@dataclass(frozen=True)
class TrajOptConfig:
    """Settings of :func:`chekhov.trajopt.solve_trajopt`, TrajOpt's defaults where they apply.

    Collision (m): terms are gathered for pairs closer than ``check_distance_m``; each is a
    hinge penalty max(0, safety_margin_m - sd). The collision constraint counts as satisfied
    when every term is at least ``min_clearance_m`` (at an end closer than that, and on the
    segment from it, at least the end's own clearance: ``TrajOptProblem.required_clearance``).

    Attributes:
        n_waypoints: T of straight-line seeds.
        max_step_rad: given seed paths are resampled so adjacent waypoints are at most this far
            apart (joint-space L2, rad; the paper's 0.16).
        terms_per_waypoint / terms_per_segment: closest pairs kept per waypoint (discrete)
            and per segment (continuous, swept spheres).
        continuous: use swept-sphere terms between waypoints (discrete terms then keep
            self-collision only, as the swept terms include both ends).
        joint_weights: per-joint weights of the smoothness cost Σ_t ||W (q_{t+1} - q_t)||²
            (rad²); None for all ones.
        collision_coeff, goal_coeff, limit_coeff, torque_coeff: scale of each penalty block
            relative to the merit coefficient (per m, per m or rad, per rad, per N·m).
        initial_penalty, penalty_increase, max_penalty_increases: the l1 merit coefficient μ,
            raised by this factor while constraints are violated.
        initial_trust_rad, trust_expand, trust_shrink, min_trust_rad: box trust region (rad).
            The first box is 0.2 rad (TrajOpt: 0.1): on 0.16 rad-resampled seeds it needs
            fewer steps for the same paths (shelf_boxes free seeds: median 10.2 → 8.9 ms).
        improve_ratio_threshold: accept a step when true / model improvement exceeds it.
        min_approx_improve, min_approx_improve_frac: convergence on the model improvement
            (absolute, and relative to the merit).
        max_iterations: QP solves in all.
        duration_s: trajectory duration (s); enables velocity, acceleration and torque limits
            with waypoints evenly spaced in time.
        velocity_scale: fraction of the URDF velocity limits allowed (with duration_s).
        acceleration_limit: rad/s², all joints (with duration_s); None for none.
        torque_limits: penalise |τ| above the URDF effort limits (N·m, with duration_s), τ
            from pinocchio's RNEA with finite-difference velocities and accelerations.
        validate: re-check of the result at ``substeps`` per segment: "exact" (the exact
            checker's decision; the fast checker screens first and coal runs only on its
            alarms, see :func:`chekhov.trajopt.solver.validate_path`), "exact_full" (coal on
            every configuration), "fast" (fast checker alone; conservative) or "none".
        substeps: interpolated configurations per segment in the validation (paper: 100).
        validate_max_segment_rad: rad, segments longer than this are split evenly before the
            validation (and the refinement's per-segment decisions), as the certification of
            a planner's answer splits them (``CERTIFY_MAX_SEGMENT_RAD``; inf: none). At the
            certification's substeps and split, an "exact" validation's certificate stands
            for the certification: a Roadmap + TrajOpt answer (segments up to 0.32 rad) was
            checked twice, at 100 substeps of its own segments and then of their halves
            (60 task cases: 1.2 of 2.2 ms a case on shelf_boxes, 0.7 of 1.0 on panda_cage).
        accept_exact_clear: when the only unmet constraint at the end is the clearance of
            the sphere model (which over-approximates the robot: near an obstacle a sphere can
            overlap it while the link is free, and a goal there then cannot get the margin),
            validate the trajectory anyway and accept it as "exact_clear" when the validation
            passes. Measured on the kitchen's 500 cases: 35 of the 51 trajectories that
            Roadmap + TrajOpt used to replace by its seed. Needs a ``validate`` other than
            "none".
        validate_each_level: with ``accept_exact_clear``, validate the trajectory at the
            end of every penalty level where the sphere model's clearance is the only unmet
            constraint, and end the run there ("exact_clear") when it passes, instead of
            raising the penalty, which only pushes the path off obstacles its links do not
            touch (a failed try costs one validation).
        refine_rounds: when the validation finds a collision (status "collision"), the
            segments whose own exact decision fails are split at their midpoints and the
            optimisation goes on from that trajectory, at most this many times while time is
            left (0: never). The swept-sphere terms interpolate each sphere's centre along a
            straight chord while the link moves on an arc, so a path clear of the terms by
            a few mm can touch an obstacle between two waypoints: 9 of 60 straight-line runs
            on panda_table_shelf task cases ended so.
        stall_levels: the penalty loop ends (and the trajectory goes to the validation)
            when this many penalty levels in a row, after the first raise, have left the
            collision violation where it was (0: never). A segment that tunnels through a
            thin obstacle has a swept-sphere distance no small move of its waypoints changes
            (the crossing's depth), so raising the penalty only shrinks the trust box: on
            straight-line seeds into the kitchen's cabinets and fridge, 10 runs that failed
            took 15-40 ms more that way (six scenes, 100 task and 100 random cases each).
            One run there that succeeded met the rule too (a Panda straight line whose
            levels 1-2 accepted no step, 0.2 mm short of the sphere model's clearance): it
            ends there and goes to the validation, as it did one level later.
        time_limit_s: wall-clock limit of the optimisation (s).
        osqp_eps: OSQP's absolute and relative tolerances (each step's model improvement is
            re-evaluated exactly at the returned point, so loose tolerances are safe).
        proximal_weight: ρ of a proximal term ½ ρ ||x - x̄||² (1/rad²) added to each QP to make
            it strongly convex (OSQP then converges in tens of iterations); not in the merit.
        osqp_rho: OSQP's initial ADMM step size (tuned on these problems: 10 needs a third of
            the iterations of OSQP's default 0.1).
    """

    n_waypoints: int = 30
    max_step_rad: float = 0.16
    safety_margin_m: float = 0.02
    check_distance_m: float = 0.06
    min_clearance_m: float = 0.002
    terms_per_waypoint: int = 4
    terms_per_segment: int = 8
    continuous: bool = True
    joint_weights: tuple[float, ...] | None = None
    collision_coeff: float = 1.0
    goal_coeff: float = 1.0
    limit_coeff: float = 1.0
    torque_coeff: float = 0.05
    initial_penalty: float = 10.0
    penalty_increase: float = 10.0
    max_penalty_increases: int = 4
    initial_trust_rad: float = 0.2
    trust_expand: float = 1.5
    trust_shrink: float = 0.1
    min_trust_rad: float = 1e-4
    improve_ratio_threshold: float = 0.25
    min_approx_improve: float = 1e-4
    min_approx_improve_frac: float = 1e-2
    max_iterations: int = 60
    duration_s: float | None = None
    velocity_scale: float = 1.0
    acceleration_limit: float | None = None
    torque_limits: bool = True
    validate: Literal["exact", "exact_full", "fast", "none"] = "exact"
    substeps: int = 100
    validate_max_segment_rad: float = CERTIFY_MAX_SEGMENT_RAD
    accept_exact_clear: bool = True
    validate_each_level: bool = False
    refine_rounds: int = 2
    stall_levels: int = 0
    time_limit_s: float = 10.0
    osqp_eps: float = 1e-2
    proximal_weight: float = 0.1
    osqp_rho: float = 10.0

    def __post_init__(self) -> None:
        n = self.stall_levels
        if not (isinstance(n, int) and not isinstance(n, bool) and n >= 0):
            raise ChekhovError(f"TrajOptConfig.stall_levels: must be an integer >= 0 (0: "
                               f"never), got {n!r}")
        v = self.validate_max_segment_rad
        if not (isinstance(v, int | float) and not isinstance(v, bool) and v > 0):
            raise ChekhovError(f"TrajOptConfig.validate_max_segment_rad: must be a number of rad "
                             f"> 0 (inf: no split), got {v!r}")

    def within(self, seconds: float) -> TrajOptConfig:
        """This config with its time limit cut to ``seconds`` (s) when that is shorter."""
        return self if self.time_limit_s <= seconds else replace(self, time_limit_s=seconds)
