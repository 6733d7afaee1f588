"""Scripted, seeded disturbances for one pick-and-place episode (:class:`EpisodeScript`,
:func:`make_script`): a task case (from a pre-grasp or ready configuration to another object's
pre-grasp pose), and during the motion a person's forearm sweeping across the arm's way, a goal
change to a third object's pre-grasp, and a kick.

The script leaves the arm a way out: the forearm (a capsule: a cylinder with a sphere on each
end, radius :data:`FOREARM_RADIUS_M`) moves at most 1 m/s and its whole sweep stays at least
:data:`BASE_CLEARANCE_M` horizontally from the robot's base (its torso) and
:data:`SHOULDER_CLEARANCE_M` from the arm's first joint; a kick is at most 0.1 rad per joint
and is shrunk (halved, up to 4 times, when it lands:
:func:`~chekhov.execute.simulate.shrunk_kick`) until the kicked configuration is within the
limits and collision-free, so is the kicked arm going on at its velocity for 0.1 s, and one
motion within the limits from the kicked state (a brake, or a constant acceleration) stays
free of the scene and of the forearm's true motion for 0.5 s. The
forearm enters from beyond the arm's reach, where no route the executed arm may have taken
can put the arm on it (before 2026-12-02 it appeared 0.3 m from the arm in the motion it was
aimed at, and twice in 60 episodes on an arm that had gone another way); one that would have
had to set out before the episode begins is there from :data:`FIRST_APPEAR_S`, at least
0.3 m from the arm as it is then in the motion it is aimed at (the task with its goal change,
when :func:`make_script` is given how to run it; else the undisturbed motion) — the arm has
then hardly left its start. When the script is given a rule for it (``way_out``:
:func:`~chekhov.execute.evaluate.forearm_way_out`), the arm in that motion could still get
away from it. Units: s, m, rad.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chekhov.cases import sample_task_case, task_targets
from chekhov.execute.obstacles import MovingObstacle, to_segment
from chekhov.robot.goal import Goal
from chekhov.scene.model import Shape
from chekhov.world import World

Array = NDArray[np.float64]

FOREARM_RADIUS_M = 0.045
FOREARM_LENGTH_M = 0.28
BASE_CLEARANCE_M = 0.3
SHOULDER_CLEARANCE_M = 0.15
APPEAR_CLEARANCE_M = 0.3
SWEEP_M = 1.2
REACH_MARGIN_M = 0.15
FIRST_APPEAR_S = 0.05
KICK_RAD = 0.1
SPEED_MPS = (0.3, 1.0)


@dataclass(frozen=True, eq=False)
class Kick:
    """At time ``t`` (s) the arm is displaced by ``dq`` (K,) rad (before shrinking)."""

    t: float
    dq: Array


@dataclass(frozen=True, eq=False)
class GoalChange:
    """At time ``t`` (s) the goal becomes ``goal`` (labelled ``label``)."""

    t: float
    goal: Goal
    label: str


@dataclass(frozen=True, eq=False)
class EpisodeScript:
    """One episode: start (K,) rad, the first goal, and what happens when."""

    index: int
    q_start: Array
    goal: Goal
    goal_label: str
    obstacles: tuple[MovingObstacle, ...] = ()
    goal_changes: tuple[GoalChange, ...] = ()
    kicks: tuple[Kick, ...] = ()

    @property
    def last_event_s(self) -> float:
        """s, when the last scripted disturbance is over."""
        times = [o.t_end for o in self.obstacles] + [g.t for g in self.goal_changes] + \
                [k.t for k in self.kicks]
        return max(times, default=0.0)

    def undisturbed(self) -> EpisodeScript:
        return EpisodeScript(self.index, self.q_start, self.goal, self.goal_label)

    def task_only(self) -> EpisodeScript:
        """The episode's task as given — its goal changes too — with no forearm and no kick:
        the reference its deadline and time to goal are measured against."""
        return EpisodeScript(self.index, self.q_start, self.goal, self.goal_label,
                             goal_changes=self.goal_changes)


Follow = Callable[["EpisodeScript"], "tuple[float, Array] | None"]
"""Runs an episode's task with its goal change and nothing else: (its duration s, its
configurations (N, K) rad evenly in time), or None when it does not reach its goal."""

WayOut = Callable[[tuple[MovingObstacle, ...], float, Array], bool]
"""Whether a drawn forearm (its parts), crossing a motion (its duration s, its configurations
(N, K) rad evenly in time), leaves the arm a way out
(:func:`~chekhov.execute.evaluate.forearm_way_out`)."""


def episode_rng(seed: int, index: int, part: int = 0) -> np.random.Generator:
    """The stream of one part of episode ``index`` of stream ``seed`` (1: the goal change,
    2: the forearm, 3: the kick): each its own, so that one drawn differently (a forearm
    aimed at another motion) does not move the others."""
    return np.random.default_rng([seed, index, 18, part])


def make_script(world: World, seed: int, index: int, duration_s: float,
                ee_path: Array, q_path: Array | None = None, *,
                follow: Follow | None = None, way_out: WayOut | None = None
                ) -> EpisodeScript:
    """Episode ``index`` of stream ``seed``: its task case and one disturbance of each kind
    timed against the undisturbed motion (``duration_s`` s, end-effector positions
    ``ee_path`` (N, 3) m along it, evenly in time). With the undisturbed configurations
    ``q_path`` (N, K) rad, the forearm appears at least :data:`APPEAR_CLEARANCE_M` from the
    arm as it is then (points along its links). With ``follow``, the forearm and the kick
    are timed against the motion of the task *with its goal change* instead (when that
    reaches its goal): after a goal change the arm is elsewhere than in the undisturbed
    motion, and a forearm placed against that had crossed where the arm no longer went, or
    appeared beside where it was (shelf_boxes, seed 3, episode 5: contact 30 ms after the
    forearm appeared). With ``way_out`` (and ``q_path``), a forearm is drawn again while it
    leaves the arm in that motion no way out."""
    case = sample_task_case(world, seed, index)
    goal = Goal.pose(case.T_goal)
    change = _goal_change(world, episode_rng(seed, index, 1), duration_s, case.goal_label)
    changes = () if change is None else (change,)
    if follow is not None and changes:
        moved = follow(EpisodeScript(index, case.q_start, goal, case.goal_label,
                                     goal_changes=changes))
        if moved is not None:
            duration_s, q_path = moved
            ee_path = world.robot.compute_ee_poses(q_path)[:, :3, 3]
    arm = _forearm(world, episode_rng(seed, index, 2), duration_s, ee_path, q_path, way_out)
    rng = episode_rng(seed, index, 3)
    kick = Kick(float(rng.uniform(0.1, 0.9) * duration_s),
                rng.uniform(-KICK_RAD, KICK_RAD, world.robot.dof))
    return EpisodeScript(index, case.q_start, goal, case.goal_label, arm, changes, (kick,))


def start_and_goal(world: World, seed: int, index: int) -> tuple[Array, Goal]:
    case = sample_task_case(world, seed, index)
    return case.q_start, Goal.pose(case.T_goal)


def _forearm(world: World, rng: np.random.Generator, duration_s: float, ee_path: Array,
             q_path: Array | None, way_out: WayOut | None = None
             ) -> tuple[MovingObstacle, ...]:
    """A capsule crossing the end-effector path near a random point of it, in a random
    horizontal direction, at a random speed, entering from beyond the arm's reach
    (:func:`_lead_in_m`) — or, when it would have to set out before the episode starts, there
    at :data:`FIRST_APPEAR_S` where it would then be; redrawn while its sweep comes nearer
    than :data:`BASE_CLEARANCE_M` to the base, it appears nearer than
    :data:`APPEAR_CLEARANCE_M` to the arm, or (with ``way_out``) it leaves the arm no way
    out."""
    base = world.robot.T_world_base[:3, 3]
    shoulder, reach_m = world.robot.reach
    for _ in range(50):
        u = float(rng.uniform(0.3, 0.8))
        p = ee_path[min(int(u * len(ee_path)), len(ee_path) - 1)] + rng.uniform(-0.1, 0.1, 3)
        a = float(rng.uniform(0, 2 * np.pi))
        d = np.array([np.cos(a), np.sin(a), 0.0])
        lead = _lead_in_m(p - shoulder, d, reach_m)
        p_far, p1 = p - d * lead, p + d * SWEEP_M / 2
        if _horizontal_distance(base, p_far, p1) < BASE_CLEARANCE_M or \
                _horizontal_distance(shoulder, p_far, p1) < SHOULDER_CLEARANCE_M:
            continue
        speed = float(rng.uniform(*SPEED_MPS))
        t_cross = u * duration_s
        t0 = max(t_cross - lead / speed, FIRST_APPEAR_S)
        p0 = p - d * (t_cross - t0) * speed
        axis = float(rng.uniform(0, np.pi))
        R = _axis_rotation(np.array([np.cos(axis), np.sin(axis), 0.0]))
        half = R[:, 2] * FOREARM_LENGTH_M / 2
        if q_path is not None and _arm_distance(world, q_path, t0 / duration_s, p0 - half,
                                                p0 + half) < APPEAR_CLEARANCE_M:
            continue
        parts = (("forearm", Shape("cylinder", (FOREARM_RADIUS_M, FOREARM_LENGTH_M)), 0.0),
                 ("elbow", Shape("sphere", (FOREARM_RADIUS_M,)), -1.0),
                 ("wrist", Shape("sphere", (FOREARM_RADIUS_M,)), 1.0))
        arm = tuple(MovingObstacle(name, shape, R, p0 + k * half, p1 + k * half, t0, speed)
                    for name, shape, k in parts)
        if way_out is None or q_path is None or way_out(arm, duration_s, q_path):
            return arm
    return ()


def _lead_in_m(p_from_shoulder: Array, d: Array, reach_m: float) -> float:
    """m, how far back along the unit direction d (3,) from the point ``p_from_shoulder``
    (3,) m from the arm's first joint the forearm sets out: at least half a sweep
    (:data:`SWEEP_M`), and far enough that no part of it is within the arm's reach
    (``reach_m``, of its end-effector frame, plus :data:`REACH_MARGIN_M` for the hand and
    the forearm's half length and radius): where it appears, no arm can be, whatever route
    the arm has taken."""
    r = reach_m + REACH_MARGIN_M + FOREARM_LENGTH_M / 2 + FOREARM_RADIUS_M
    w_d = float(p_from_shoulder @ d)
    disc = w_d * w_d - float(p_from_shoulder @ p_from_shoulder) + r * r
    return max(SWEEP_M / 2, w_d + float(np.sqrt(disc)) if disc > 0.0 else 0.0)


def _arm_distance(world: World, q_path: Array, u: float, a: Array, b: Array) -> float:
    """m, from the forearm's axis (the segment a-b, (3,) each: the whole of it, not its
    centre, which had let a forearm appear 5 cm from the arm's surface, 90 ms from contact,
    before any frame of it could arrive) to the arm at fraction u of ``q_path`` (points along
    the segments between its joint origins and the end effector)."""
    q = q_path[min(int(u * len(q_path)), len(q_path) - 1)]
    pts = np.vstack([world.robot.compute_joint_placements(q)[:, :3, 3],
                     world.robot.compute_ee_pose(q)[:3, 3]])
    f = np.linspace(0.0, 1.0, 6)[:, None, None]
    along = (pts[:-1][None] * (1 - f) + pts[1:][None] * f).reshape(-1, 3)
    return float(np.linalg.norm(to_segment(along, a, b), axis=1).min())


def _goal_change(world: World, rng: np.random.Generator, duration_s: float, label: str
                 ) -> GoalChange | None:
    targets = [t for t in task_targets(world).pregrasps if t.label != label]
    if not targets:
        return None
    t = targets[int(rng.integers(len(targets)))]
    return GoalChange(float(rng.uniform(0.2, 0.6) * duration_s), Goal.pose(t.T), t.label)


def _horizontal_distance(c: Array, p0: Array, p1: Array) -> float:
    """m, the distance in the xy plane from point c to the segment p0-p1."""
    return float(np.linalg.norm(to_segment(c[None, :2], p0[:2], p1[:2])))


def _axis_rotation(z: Array) -> Array:
    """A rotation whose z axis is the unit vector z."""
    z = z / np.linalg.norm(z)
    x = np.cross([0.0, 0.0, 1.0], z)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else np.array([1.0, 0.0, 0.0])
    return np.column_stack([x, np.cross(z, x), z])
