"""The reactive executive in real time, for the viewer (``chekhov view SCENE --react``).

:class:`LiveExecutive` runs a control loop on a thread of its own: at every tick of the wall
clock (100 Hz) it hands an :class:`~chekhov.execute.executor.Executor` what the robot and its
sensor report and makes the robot follow the command it returns, while a
:class:`~chekhov.execute.worker.ThreadWorker` replans beside it in a world of its own. It is
:func:`~chekhov.execute.simulate.run_episode` on the wall clock: the robot tracks each command
perfectly, a 30 Hz sensor delivers its frames 40 ms after it takes them (:class:`Sensor`), and
the episode's scripted forearm, goal change and kick happen on time; obstacles dragged in the
viewer (:meth:`LiveExecutive.set_dragged`) are in every frame too. An episode ends at rest at
its goal once its script is over, or at its deadline; then the next episode index starts.

The viewer reads the loop's :class:`LiveState` snapshots (a new one every tick); nothing here
imports viser. Units: s, rad, m.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from chekhov.errors import ChekhovError
from chekhov.execute.benchmark import (
    ReactConfig,
    executive_planner,
    run_one,
    script_way_out,
    task_runner,
)
from chekhov.execute.executor import Executor
from chekhov.execute.interface import Command, Observation, Reaction
from chekhov.execute.motion import Motion
from chekhov.execute.obstacles import MovingObstacle, Obstacles, obstacles_at
from chekhov.execute.script import EpisodeScript, make_script, start_and_goal
from chekhov.execute.simulate import SimConfig, shrunk_kick
from chekhov.execute.truth import TrueWorld
from chekhov.execute.worker import ThreadWorker
from chekhov.planners.base import Planner
from chekhov.robot.goal import Goal
from chekhov.robot.robot import Robot
from chekhov.scene.model import Shape
from chekhov.world import World

Array = NDArray[np.float64]
PlannerFactory = Callable[[str, World], Planner]
"""(planner name, world) → the planner the executive uses in that world."""


@dataclass(frozen=True)
class LiveConfig:
    """The real-time loop's settings.

    Attributes:
        react: as ``chekhov react`` has them: the episodes' stream (``seed``), the planner
            (``planners[0]``), the executive's settings (``executor``: 10 ms ticks), the
            simulated sensor's (``sim``) and each episode's deadline (``deadline_factor`` × its
            undisturbed duration + ``deadline_extra_s``, s).
        first_episode: the first episode's index; the next ones follow, without end.
        kicks, goal_changes: whether the scripts' kicks and goal changes happen (the forearm
            always moves).
        pause_s: s, at rest at the goal before the next episode.
    """

    react: ReactConfig = field(default_factory=ReactConfig)
    first_episode: int = 0
    kicks: bool = True
    goal_changes: bool = True
    pause_s: float = 0.5


@dataclass(frozen=True, eq=False)
class LiveState:
    """A snapshot of the loop, for display.

    Attributes:
        episode: the episode's index. t: s, the episode's clock.
        q: (K,) rad, where the robot is at t.
        mode: what the command does ("plan", "join", "brake", "dodge", "swerve", "rest"), or
            "setup" while the next episode is prepared, "error" when the loop failed.
        script: the episode's script (its forearm: ``obstacles_at(script.obstacles, t)``).
        goal: the goal now. motion: the commanded motion (replaced on each replan).
        reaction: a copy of the latest disturbance answered (``t_reacted`` set), or None.
        replans, safe_stops, dodges, failed_plans: this episode's counts.
        episodes, reached: episodes run to their end, and of those at their goal.
        ticks: control ticks so far (all episodes). late_ticks: ticks the loop came to more
            than a tick late (those in between were skipped).
    """

    episode: int
    t: float
    q: Array
    mode: str
    script: EpisodeScript | None = None
    goal: Goal | None = None
    motion: Motion | None = None
    reaction: Reaction | None = None
    replans: int = 0
    safe_stops: int = 0
    dodges: int = 0
    failed_plans: int = 0
    episodes: int = 0
    reached: int = 0
    ticks: int = 0
    late_ticks: int = 0


def prepare_episode(world: World, planner: Planner, config: LiveConfig, index: int
                    ) -> tuple[EpisodeScript, float] | None:
    """Episode ``index`` as ``chekhov react`` runs it: its undisturbed run on the simulated
    clock (an inline worker, ``world``) times its script (with goal changes, the forearm
    and the kick are aimed at the task with its goal change, run the same way). (script,
    deadline s), or None when the undisturbed run did not reach the goal."""
    rc = config.react
    q0, goal = start_and_goal(world, rc.seed, index)
    plain = run_one(world, planner, EpisodeScript(index, q0, goal, ""),
                    rc.undisturbed_limit_s, rc)
    if plain.t_reached is None:
        return None
    follow = task_runner(world, planner, rc.undisturbed_limit_s, rc)
    ee = world.robot.compute_ee_poses(plain.q)[:, :3, 3]
    script = make_script(world, rc.seed, index, plain.t_reached, ee, plain.q,
                         follow=follow if config.goal_changes else None,
                         way_out=script_way_out(world, rc))
    script = replace(script, kicks=script.kicks if config.kicks else (),
                     goal_changes=script.goal_changes if config.goal_changes else ())
    return script, rc.deadline_factor * plain.t_reached + rc.deadline_extra_s


class Sensor:
    """A sensor on the loop's clock: frame j is taken at j × ``period_s`` and delivered
    ``latency_s`` later (s). A frame holds the scripted obstacles at their true poses when it
    was taken and the dragged ones where they were when the loop took it (at a tick)."""

    def __init__(self, moving: tuple[MovingObstacle, ...], *, period_s: float,
                 latency_s: float) -> None:
        self.moving = moving
        self.period_s, self.latency_s = period_s, latency_s
        self._taken: deque[tuple[float, Obstacles]] = deque()
        self._next = 0

    def frame(self, t: float, dragged: Obstacles) -> tuple[Obstacles, float] | None:
        """(frame, when it was taken, s): the newest one delivered by time t (s; older ones
        not yet handed over are dropped), or None. Frames due by t are taken first, with
        ``dragged`` as it is now."""
        while self._next * self.period_s <= t + 1e-9:
            stamp = self._next * self.period_s
            self._taken.append((stamp, {**obstacles_at(self.moving, stamp), **dragged}))
            self._next += 1
        out = None
        while self._taken and self._taken[0][0] + self.latency_s <= t + 1e-9:
            out = self._taken.popleft()
        return None if out is None else (out[1], out[0])


class LiveEpisode:
    """One episode on the loop's clock: the robot (where the last command put it, unless a
    kick displaces it, shrunk as :func:`~chekhov.execute.simulate.run_episode` shrinks it), its
    sensor, and the script's goal changes and kicks still to come. ``kicks_applied``: the
    kicks that moved the arm (rad)."""

    def __init__(self, world: World, executor: Executor, script: EpisodeScript, *,
                 deadline_s: float, sim: SimConfig) -> None:
        self.world, self.executor, self.script = world, executor, script
        self.deadline_s, self.sim = deadline_s, sim
        self.q = np.array(script.q_start, dtype=float)
        self.qd = np.zeros_like(self.q)
        self.sensor = Sensor(script.obstacles, period_s=sim.sensor_period_s,
                             latency_s=sim.sensor_latency_s)
        self.kicks = list(script.kicks)
        self.changes = list(script.goal_changes)
        self.kicks_applied: list[Array] = []
        self._truth = TrueWorld(world, script.obstacles) if script.obstacles and self.kicks \
            else None

    def step(self, t: float, dragged: Obstacles) -> Command:
        """The executive's command for the tick at t (s), after what happened by then."""
        while self.kicks and self.kicks[0].t <= t + 1e-9:
            dq = shrunk_kick(self.world, self.q, self.qd, self.kicks.pop(0).dq,
                             self.sim.kick_halvings, self.executor.limits, self._truth, t)
            if dq is not None:
                self.q = self.q + dq
                self.kicks_applied.append(dq)
        goal = self.changes.pop(0).goal if self.changes and self.changes[0].t <= t + 1e-9 \
            else None
        frame = self.sensor.frame(t, dragged)
        obstacles, stamp = frame if frame is not None else (None, None)
        return self.executor.step(Observation(t, self.q, self.qd, obstacles, stamp, goal))

    def outcome(self, t: float) -> bool | None:
        """True: at rest at the goal with the script over; False: past the deadline; None:
        going on (after the tick at t, s)."""
        if self.executor.done and t >= self.script.last_event_s and not self.changes \
                and not self.kicks:
            return True
        return False if t >= self.deadline_s else None

    def follow(self, command: Command) -> None:
        """The robot tracks the command (perfectly)."""
        self.q, self.qd = np.array(command.q, dtype=float), np.array(command.qd, dtype=float)


class LiveExecutive:
    """The executive at 100 Hz on the wall clock, episode after episode (see the module).

    Args:
        world: the world of the executive's checks and of the episodes' undisturbed runs
            (only the loop's thread uses it).
        plan_world: the replanning thread's world (another instance of the same scene).
        config: the loop's settings.
        planner_factory: the planner for a world (default: :func:`executive_planner`).
        clock: the wall clock, s (``time.monotonic``).

    Attributes:
        state: the latest :class:`LiveState` (replaced each tick; read it from any thread).
        executor: the current episode's executive. error: why the loop stopped, if it failed.
    """

    def __init__(self, *, world: World, plan_world: World, config: LiveConfig | None = None,
                 planner_factory: PlannerFactory = executive_planner,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if plan_world is world:
            raise ChekhovError("the real-time executive needs two World instances: one for "
                               "its checks, one for the replanning thread")
        self.world, self.plan_world = world, plan_world
        self.config = config if config is not None else LiveConfig()
        rc = self.config.react
        self.planner = planner_factory(rc.planners[0], world)
        self.worker = ThreadWorker(plan_world, planner_factory(rc.planners[0], plan_world),
                                   rc.executor.timing)
        self.clock = clock
        self.executor: Executor | None = None
        self.error: str | None = None
        self._dragged: dict[str, tuple[Shape, Array]] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        q0, goal = start_and_goal(world, rc.seed, self.config.first_episode)
        self.state = LiveState(self.config.first_episode, 0.0, q0, "setup", goal=goal)

    @classmethod
    def load(cls, scene: str | Path, *, config: LiveConfig | None = None) -> LiveExecutive:
        """The loop over two new worlds of ``scene`` (a built-in name or a YAML file)."""
        return cls(world=World.load(scene), plan_world=World.load(scene), config=config)

    # --- control ----------------------------------------------------------------------
    def start(self) -> None:
        """Start the loop's thread (once)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, daemon=True,
                                            name="chekhov-react-loop")
            self._thread.start()

    def close(self, timeout_s: float = 5.0) -> None:
        """Stop the loop (waiting up to ``timeout_s``, s) and the replanning thread (a plan
        running then finishes on its own; its reply is dropped)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
        self.worker.close()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def set_dragged(self, name: str, shape: Shape, T_world_obj: Array) -> None:
        """An obstacle the user placed (T_world_obj (4, 4), m): in every sensor frame from now
        on, where it is when the frame is taken."""
        with self._lock:
            self._dragged[name] = (shape, np.array(T_world_obj, dtype=float))

    def remove_dragged(self, name: str) -> None:
        with self._lock:
            self._dragged.pop(name, None)

    def dragged(self) -> dict[str, tuple[Shape, Array]]:
        """The dragged obstacles now (name → (shape, T_world_obj))."""
        with self._lock:
            return dict(self._dragged)

    # --- the loop's thread ------------------------------------------------------------
    def _run(self) -> None:
        index = self.config.first_episode
        try:
            while not self._stop.is_set():
                self.state = replace(self.state, episode=index, mode="setup")
                prepared = prepare_episode(self.world, self.planner, self.config, index)
                if prepared is not None:
                    self._run_episode(index, *prepared)
                    self.state = replace(self.state, mode="rest")
                    self._stop.wait(self.config.pause_s)
                index += 1
        except Exception as e:  # shown by the viewer, not lost with the thread
            self.error = f"{type(e).__name__}: {e}"
            self.state = replace(self.state, mode="error")

    def _run_episode(self, index: int, script: EpisodeScript, deadline_s: float) -> None:
        """Tick by tick until the episode's outcome (or :meth:`close`)."""
        rc = self.config.react
        dt = rc.executor.control_dt_s
        self.executor = Executor(self.world, self.worker, script.goal, rc.executor)
        self.executor.warmup()   # real time: the first reaction must not stall a tick
        episode = LiveEpisode(self.world, self.executor, script, deadline_s=deadline_s,
                              sim=rc.sim)
        t0, k = self.clock(), 0
        while not self._stop.is_set():
            k = self._wait_for_tick(t0, k, dt)
            if self._stop.is_set():
                return
            t = k * dt
            command = episode.step(t, self.dragged())
            outcome = episode.outcome(t)
            self._publish(index, t, episode, command.mode, outcome)
            if outcome is not None:
                return
            episode.follow(command)
            k += 1

    def _wait_for_tick(self, t0: float, k: int, dt: float) -> int:
        """Sleep until tick k (at t0 + k dt on the clock, s); when more than a tick late,
        the tick now due instead (counted in ``late_ticks``)."""
        now = self.clock()
        due = t0 + k * dt
        if now < due:
            self._stop.wait(due - now)
            return k
        if now - due > dt:
            self.state = replace(self.state, late_ticks=self.state.late_ticks + 1)
            return int((now - t0) / dt)
        return k

    def _publish(self, index: int, t: float, episode: LiveEpisode, mode: str,
                 outcome: bool | None) -> None:
        ex = episode.executor
        c = ex.counters
        answered = next((replace(r) for r in reversed(ex.reactions) if r.t_reacted is not None),
                        None)
        s = self.state
        self.state = LiveState(
            index, t, episode.q.copy(), mode, episode.script, ex.goal, ex.motion, answered,
            c.replans, c.safe_stops, c.dodges, c.failed_plans,
            s.episodes + int(outcome is not None), s.reached + int(bool(outcome)),
            s.ticks + 1, s.late_ticks)


class EeTrace:
    """End-effector positions along a motion, by forward kinematics with data of its own
    (``robot.model`` is only read: safe beside the loop's thread)."""

    def __init__(self, robot: Robot, *, dt_s: float = 0.02, max_points: int = 400) -> None:
        self.model, self.frame = robot.model, robot.ee_frame_id
        self.data = robot.model.createData()
        self.dt_s, self.max_points = dt_s, max_points

    def along(self, motion: Motion, t0: float) -> Array | None:
        """(N, 3) m: the end effector along ``motion`` from t0 to its end (every ``dt_s`` s,
        at most ``max_points``); None when it is at rest by t0."""
        if motion.t_end <= t0 + 1e-9:
            return None
        dt = max(self.dt_s, (motion.t_end - t0) / self.max_points)
        _, Q = motion.positions(t0, motion.t_end, dt)
        out = np.empty((len(Q), 3))
        for i, q in enumerate(Q):
            pin.framesForwardKinematics(self.model, self.data, q)
            out[i] = self.data.oMf[self.frame].translation
        return out


def latency_markdown(reaction: Reaction | None) -> str:
    """The latency of the last disturbance answered: to its first answer (t_reacted −
    t_observed) and to a motion to the goal that answers it (t_resolved − t_observed), ms."""
    if reaction is None:
        return "last reaction: none yet"
    assert reaction.t_reacted is not None
    reacted = 1000 * (reaction.t_reacted - reaction.t_observed)
    resolved = "…" if reaction.t_resolved is None else \
        f"**{1000 * (reaction.t_resolved - reaction.t_observed):.0f} ms**"
    return (f"last reaction: **{reaction.kind}** at {reaction.t_observed:.2f} s — reacted in "
            f"**{reacted:.0f} ms**, resolved in {resolved}")


def status_markdown(state: LiveState) -> str:
    """Episode, clock and mode."""
    return f"episode **{state.episode}** · t = {state.t:5.2f} s · mode **{state.mode}**"


def counters_markdown(state: LiveState) -> str:
    """This episode's replans, safe stops, dodges and failed plans; episodes, late ticks."""
    return (f"replans **{state.replans}** · safe stops **{state.safe_stops}** · dodges "
            f"**{state.dodges}** · failed plans {state.failed_plans}  \n"
            f"episodes {state.episodes} ({state.reached} at the goal) · late ticks "
            f"{state.late_ticks} of {state.ticks}")
