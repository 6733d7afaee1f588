"""The reactive executive: an :class:`Executor` that keeps an arm moving to its goal while the
world changes — kicks, new goals, moving obstacles — one control tick at a time, and the
simulated robot, scripted episodes and after-the-fact checks of ``chekhov react``.

Layer 5: imports planners/ and below; bench/, viewer/ and cli/ import it."""

from chekhov.execute.benchmark import ReactConfig, executive_planner, react_scene
from chekhov.execute.evaluate import EpisodeCheck, evaluate_episode
from chekhov.execute.executor import Executor
from chekhov.execute.interface import Command, ExecutorConfig, Observation, Reaction
from chekhov.execute.motion import Motion, State
from chekhov.execute.obstacles import MovingObstacle, ObstacleTracks, obstacles_at
from chekhov.execute.script import EpisodeScript, GoalChange, Kick, make_script, start_and_goal
from chekhov.execute.simulate import EpisodeRecord, SimConfig, run_episode
from chekhov.execute.worker import InlineWorker, PlanReply, PlanRequest, ThreadWorker

__all__ = [
    "Command",
    "EpisodeCheck",
    "EpisodeRecord",
    "EpisodeScript",
    "Executor",
    "ExecutorConfig",
    "GoalChange",
    "InlineWorker",
    "Kick",
    "Motion",
    "MovingObstacle",
    "Observation",
    "ObstacleTracks",
    "PlanReply",
    "PlanRequest",
    "ReactConfig",
    "Reaction",
    "SimConfig",
    "State",
    "ThreadWorker",
    "evaluate_episode",
    "executive_planner",
    "make_script",
    "obstacles_at",
    "react_scene",
    "run_episode",
    "start_and_goal",
]
