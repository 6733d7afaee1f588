"""The scenario benchmark behind ``chekhov react`` (:func:`react_scene`): pick-and-place
episodes with a forearm sweeping across, a goal change and a kick each
(:mod:`~chekhov.execute.script`), run on the simulated clock, judged after the fact
(:mod:`~chekhov.execute.evaluate`), summed up in one JSON-able dict per scene and planner.

Each episode first runs undisturbed (the same start, goal and executive, nothing happening),
on the clock that does not charge compute: its duration times the goal change; the task with
that goal change, on the same clock, then aims the forearm and times the kick
(:func:`episode_script`), so every run on any machine gets the same episodes. The scripts
come from the first planner's undisturbed runs, so every planner gets the same episodes.
Each planner then runs the episode's task alone (on the run's own clock) —
its goal changes, no forearm, no kick (:meth:`EpisodeScript.task_only`) — and that run's
duration is the reference of the episode's deadline and of ``time_to_goal_ratio`` (the goal
change can send the arm much farther than the first goal: a deadline from the first goal's
duration alone had failed an episode that moved 1 m more, undisturbed by anything else).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from chekhov.execute.evaluate import EpisodeCheck, evaluate_episode, forearm_way_out
from chekhov.execute.executor import Executor
from chekhov.execute.interface import ExecutorConfig
from chekhov.execute.script import EpisodeScript, Follow, WayOut, make_script, start_and_goal
from chekhov.execute.simulate import EpisodeRecord, SimConfig, run_episode
from chekhov.execute.worker import InlineWorker
from chekhov.planners.base import Planner, PlannerBase
from chekhov.planners.registry import canonical_planner_name, make_planner
from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
from chekhov.roadmap.io import load_or_build_roadmap
from chekhov.timing import joint_limits
from chekhov.world import World

Array = NDArray[np.float64]

REACT_IMPROVE_S = 0.0
"""s, Roadmap + TrajOpt's improvement time in the executive: a replan answers with its first
certified path (shortened), nothing after; the budget is the reaction time. (Measured on 8
episodes each of tabletop_pole and shelf_boxes, one run: 5 ms of improvement gave the same or
a longer time to goal, 2-4 ms more planning wall time at the median.)"""


@dataclass(frozen=True)
class ReactConfig:
    """A benchmark run: ``episodes`` per scene from stream ``seed``, the executive's and the
    simulation's settings; an episode's deadline is ``deadline_factor`` × its undisturbed
    duration + ``deadline_extra_s`` (s)."""

    episodes: int = 20
    seed: int = 0
    planners: tuple[str, ...] = ("Roadmap+TrajOpt",)
    executor: ExecutorConfig = field(default_factory=ExecutorConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    deadline_factor: float = 3.0
    deadline_extra_s: float = 4.0
    undisturbed_limit_s: float = 30.0


@dataclass(frozen=True, eq=False)
class EpisodeResult:
    """One episode of one planner: its script, record, verdict, and the duration of this
    planner's run of the task alone (s; None when that run did not reach the goal). An episode is
    *reachable* when the first planner's undisturbed run reached its goal (the goal changes
    to another reachable pre-grasp and the forearm leaves): only those are run."""

    script: EpisodeScript
    record: EpisodeRecord
    check: EpisodeCheck
    undisturbed_s: float | None


def executive_planner(name: str, world: World) -> Planner:
    """The planner ``name`` as the executive uses it: untimed (the executive times and joins
    the path itself) and, for Roadmap + TrajOpt, with :data:`REACT_IMPROVE_S`."""
    name = canonical_planner_name(name)
    planner = make_planner(name, world, lambda: load_or_build_roadmap(world))
    if isinstance(planner, RoadmapTrajOpt):
        planner.config = replace(planner.config, improve_time_s=REACT_IMPROVE_S)
    if isinstance(planner, PlannerBase):
        planner.timing = None
    return planner


@functools.lru_cache(maxsize=2)
def checking_world(world: World) -> World:
    """The executive's own world beside the one its worker plans in (as with a worker on a
    thread): planning does not change the obstacles the executive checks against, so its
    exact checker keeps them and only resizes and moves them each sensor frame."""
    return World(world.scene, world.robot)


def run_one(world: World, planner: Planner, script: EpisodeScript, deadline_s: float,
            config: ReactConfig, *, reply_after_s: float | None = None) -> EpisodeRecord:
    """Run one script with a fresh executive (``reply_after_s``: see :class:`InlineWorker`)."""
    worker = InlineWorker(world, planner, config.executor.timing, reply_after_s=reply_after_s)
    executor = Executor(checking_world(world), worker, script.goal, config.executor,
                        wall_scale=config.sim.compute_scale)
    executor.warmup()
    return run_episode(world, executor, script, deadline_s, config.sim)


def react_scene(world: World, config: ReactConfig,
                progress: Callable[[str], None] | None = None) -> list[dict[str, object]]:
    """Every episode of ``config`` in ``world`` for each planner; one summary per planner."""
    planners = [executive_planner(n, world) for n in config.planners]
    scripts = [episode_script(world, planners[0], config, i) for i in range(config.episodes)]
    out = []
    for planner in planners:
        results: list[EpisodeResult | None] = []
        for i, script in enumerate(scripts):
            if script is None:
                results.append(None)
                continue
            results.append(scripted_episode(world, planner, script, config))
            if progress is not None:
                progress(f"{world.scene.name} {planner.name} episode {i + 1}/"
                         f"{config.episodes}")
        out.append(summarize(world.scene.name, planner.name, results, config))
    return out


def episode_script(world: World, planner: Planner, config: ReactConfig, index: int
                   ) -> EpisodeScript | None:
    """Episode ``index`` of ``config.seed``'s stream, its disturbances timed by an undisturbed
    run of ``planner`` (the goal change) and by its run of the task with that goal change
    (the forearm and the kick: :func:`make_script`'s ``follow``), on a clock that does not
    charge compute, where every plan's reply
    comes one planning budget after it is asked for — so that every run, on any machine, gets
    the same scripts: on the charged clock a tick's difference in the run's duration moved
    the forearm, and an episode that collided in a run could not be replayed. None when that
    run does not reach the goal (unreachable)."""
    q0, goal = start_and_goal(world, config.seed, index)
    free = replace(config, sim=replace(config.sim, charge_compute=False),
                   executor=replace(config.executor, search_budget_s=None))
    rec = run_one(world, planner, EpisodeScript(index, q0, goal, ""),
                  config.undisturbed_limit_s, free,
                  reply_after_s=config.executor.planning_budget_s)
    if rec.t_reached is None:
        return None

    follow = task_runner(world, planner, config.undisturbed_limit_s, free,
                         reply_after_s=config.executor.planning_budget_s)
    ee = world.robot.compute_ee_poses(rec.q)[:, :3, 3]
    return make_script(world, config.seed, index, rec.t_reached, ee, rec.q, follow=follow,
                       way_out=script_way_out(world, config))


def reaction_window_s(config: ReactConfig) -> float:
    """s, from an event to the first moment a reaction to it can be moving the arm: a sensor
    period (the frame's phase), its latency and a planning budget."""
    return config.sim.sensor_period_s + config.sim.sensor_latency_s + \
        config.executor.planning_budget_s


def script_way_out(world: World, config: ReactConfig) -> WayOut:
    """The scripts' way-out rule (:func:`forearm_way_out`) for ``config``'s reaction window
    and limits."""
    return forearm_way_out(world, reaction_window_s(config),
                           joint_limits(world.robot.velocity_limit, config.executor.timing))


def task_runner(world: World, planner: Planner, limit_s: float, config: ReactConfig, *,
                reply_after_s: float | None = None) -> Follow:
    """:func:`make_script`'s ``follow``: runs a task script with :func:`run_one` (at most
    ``limit_s`` s) and gives (its duration s, its configurations (N, K) rad at the control
    rate), or None when it does not reach its goal."""
    def follow(task: EpisodeScript) -> tuple[float, Array] | None:
        rec = run_one(world, planner, task, limit_s, config, reply_after_s=reply_after_s)
        return None if rec.t_reached is None else (rec.t_reached, rec.q)
    return follow


def scripted_episode(world: World, planner: Planner, script: EpisodeScript,
                     config: ReactConfig, t_plain: float | None = None) -> EpisodeResult:
    """One scripted episode; ``t_plain``: its undisturbed duration (s) when already run with
    this planner and the script has no goal change, else the task alone is run here."""
    if t_plain is None or script.goal_changes:
        plain = run_one(world, planner, script.task_only(), config.undisturbed_limit_s,
                        config)
        t_plain = plain.t_reached
    deadline = config.deadline_factor * (t_plain or config.undisturbed_limit_s / 3) + \
        config.deadline_extra_s
    rec = run_one(world, planner, script, deadline, config)
    limits = joint_limits(world.robot.velocity_limit, config.executor.timing)
    return EpisodeResult(script, rec, evaluate_episode(world, rec, limits,
                                                       reaction_window_s(config)), t_plain)


def _pct(x: list[float], q: float) -> float | None:
    return float(np.percentile(x, q)) if x else None


def _problem(r: EpisodeResult) -> dict[str, object]:
    """What went wrong in one episode, to find it again (its index and seed)."""
    c = r.check
    return {"index": r.script.index, "reached": r.record.reached, "collision": c.collision,
            "first_contact_s": c.first_contact_s, "unavoidable": c.unavoidable,
            "limit_violations": c.limit_violations, "violations": list(c.violation_kinds),
            "failures": sorted(set(r.record.counters.failures))}


def summarize(scene: str, planner: str, results: list[EpisodeResult | None],
              config: ReactConfig) -> dict[str, object]:
    """The JSON object of one scene and planner (keys: see ``chekhov react --help``)."""
    done = [r for r in results if r is not None]
    success = [r for r in done if r.record.reached]
    # a "lag" is the arm behind a step that overran: its time is charged to that step's reaction
    events = [x for r in done for x in r.record.reactions if x.kind != "lag"]
    reacted = [1000 * (x.t_reacted - x.t_observed) for x in events if x.t_reacted is not None]
    resolved = [1000 * (x.t_resolved - x.t_observed) for x in events
                if x.t_resolved is not None]
    unanswered = sum(1 for x in events if x.t_reacted is None)
    dt = config.executor.control_dt_s
    mins = [r.check.min_clearance_m for r in done if np.isfinite(r.check.min_clearance_m)]
    ratios = [r.record.t_reached / r.undisturbed_s for r in success
              if r.record.t_reached is not None and r.undisturbed_s]
    walls = [1000 * w for r in done for w in r.record.counters.planning_wall_s]
    steps = [1000 * w for r in done for w in r.record.counters.step_wall_s]
    collided = [r for r in done if r.check.collision]
    return {
        "scene": scene, "planner": planner, "episodes": len(results),
        "success_rate": len(success) / len(done) if done else None,
        "reachable_episodes": len(done),
        "unreachable_episodes": len(results) - len(done),
        "unreachable_why": "the first planner's undisturbed run did not reach the goal"
        if len(results) > len(done) else "",
        "undisturbed_failures": sum(r.undisturbed_s is None for r in done),
        "forearm_episodes": sum(bool(r.script.obstacles) for r in done),
        "collision_episodes": len(collided),
        "unavoidable_collision_episodes": sum(r.check.unavoidable for r in collided),
        "min_clearance_m": min(mins) if mins else None,
        "p5_clearance_m": _pct(mins, 5),
        "reaction_latency_ms_p50": _pct(reacted, 50),
        "reaction_latency_ms_p95": _pct(reacted, 95),
        "reaction_latency_ms_p99": _pct(reacted, 99),
        "resolve_latency_ms_p50": _pct(resolved, 50),
        "resolve_latency_ms_p95": _pct(resolved, 95),
        "resolve_latency_ms_p99": _pct(resolved, 99),
        "disturbances": len(events),
        "unanswered_disturbances": unanswered,
        "replans_per_episode": float(np.mean([r.record.counters.replans for r in done]))
        if done else None,
        "safe_stops": sum(r.record.counters.safe_stops for r in done),
        "dodges": sum(r.record.counters.dodges for r in done),
        "holds": sum(r.record.counters.holds for r in done),
        "swerves": sum(r.record.counters.swerves for r in done),
        "immediate_ms_max": max((1000 * w for r in done
                                 for w in r.record.counters.immediate_wall_s), default=None),
        "undecided_checks": sum(r.record.counters.undecided_checks for r in done),
        "failed_plans": sum(r.record.counters.failed_plans for r in done),
        "late_plans": sum(r.record.counters.late_plans for r in done),
        "planning_wall_ms_p50": _pct(walls, 50), "planning_wall_ms_p95": _pct(walls, 95),
        "control_step_ms_p50": _pct(steps, 50), "control_step_ms_p99": _pct(steps, 99),
        "control_step_ms_max": max(steps) if steps else None,
        "overrun_steps": sum(w > dt for r in done for w in r.record.counters.step_wall_s),
        "lag_rejoins": sum(x.kind == "lag" for r in done for x in r.record.reactions),
        "compute_charged": config.sim.charge_compute,
        "compute_scale": config.sim.compute_scale,
        "time_to_goal_ratio": float(np.median(ratios)) if ratios else None,
        "limit_violations": sum(r.check.limit_violations for r in done),
        "problem_episodes": [_problem(r) for r in done if r.check.collision
                             or r.check.limit_violations or not r.record.reached],
        "seed": config.seed, "control_hz": round(1 / config.executor.control_dt_s),
        "planning_budget_ms": 1000 * config.executor.planning_budget_s,
    }
