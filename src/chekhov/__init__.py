"""chekhov: fast, reactive motion planning for robot arms (roadmap + trajectory optimisation).

The public API is flat::

    import chekhov
    world = chekhov.World.load("shelf_boxes")
    ok = world.fast.valid(Q)            # (N, 7) -> (N,) bool, numba-compiled
    ok = world.exact.path_valid(path)   # pinocchio + coal, 100 substeps per segment
    planner = chekhov.RoadmapTrajOpt(world, chekhov.load_or_build_roadmap(world))
    result = planner.plan(q_start, chekhov.Goal.pose(T_world_ee))   # PlanResult
"""

from chekhov import _numba_cache  # noqa: F401  (first: the kernels' cache stamp, before any kernel)
from chekhov.collision.exact import ExactChecker, densify
from chekhov.collision.fast import Contacts, FastChecker
from chekhov.errors import (
    CaseFileError,
    ChekhovError,
    IKError,
    PlanningInputError,
    RobotError,
    SceneError,
    TrajectoryError,
)
from chekhov.planners.base import Planner, PlannerBase, PlanResult, path_length, resample_path
from chekhov.planners.lazy_prm import LazyPRM, LazyPRMConfig
from chekhov.planners.ompl_planner import OmplPlanner
from chekhov.planners.query import PlanQuery
from chekhov.planners.result import Solution
from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
from chekhov.planners.roadmap_trajopt_config import RoadmapTrajOptConfig
from chekhov.planners.status import PlanStatus, Stage, StageReport
from chekhov.planners.trajopt_planner import SeededTrajOpt, TrajOptPlanner
from chekhov.roadmap.build import build_roadmap
from chekhov.roadmap.config import RoadmapConfig
from chekhov.roadmap.errors import RoadmapError, RoadmapMismatchError
from chekhov.roadmap.graph import Roadmap
from chekhov.roadmap.io import load_or_build_roadmap, load_roadmap, save_roadmap
from chekhov.roadmap.seeder import RoadmapSeeder, SeederConfig, SeedResult
from chekhov.robot.description import RobotDescription, SphereSettings
from chekhov.robot.goal import Goal
from chekhov.robot.ik import IKConfig, solve_ik
from chekhov.robot.robot import Robot
from chekhov.robot.spheres import SphereModel, build_sphere_model
from chekhov.scene.io import builtin_scenes, load_scene, save_scene, scene_from_dict
from chekhov.scene.model import Articulation, Grasp, Pose, Region, Scene, SceneObject, Shape
from chekhov.timing import TimingConfig, time_parameterize
from chekhov.trajectory import JointTrajectory
from chekhov.trajopt.config import TrajOptConfig
from chekhov.trajopt.problem import TrajOptProblem, build_trajopt
from chekhov.trajopt.result import TrajOptResult
from chekhov.trajopt.solver import solve_trajopt
from chekhov.world import World

__all__ = [
    "Articulation",
    "CaseFileError",
    "ChekhovError",
    "Contacts",
    "ExactChecker",
    "FastChecker",
    "Goal",
    "Grasp",
    "IKConfig",
    "IKError",
    "JointTrajectory",
    "LazyPRM",
    "LazyPRMConfig",
    "OmplPlanner",
    "PlanQuery",
    "PlanResult",
    "PlanStatus",
    "Planner",
    "PlannerBase",
    "PlanningInputError",
    "Pose",
    "Region",
    "Roadmap",
    "RoadmapConfig",
    "RoadmapError",
    "RoadmapMismatchError",
    "RoadmapSeeder",
    "RoadmapTrajOpt",
    "RoadmapTrajOptConfig",
    "Robot",
    "RobotDescription",
    "RobotError",
    "Scene",
    "SceneError",
    "SceneObject",
    "SeedResult",
    "SeededTrajOpt",
    "SeederConfig",
    "Shape",
    "Solution",
    "SphereModel",
    "SphereSettings",
    "Stage",
    "StageReport",
    "TimingConfig",
    "TrajOptConfig",
    "TrajOptPlanner",
    "TrajOptProblem",
    "TrajOptResult",
    "TrajectoryError",
    "World",
    "build_roadmap",
    "build_sphere_model",
    "build_trajopt",
    "builtin_scenes",
    "densify",
    "load_or_build_roadmap",
    "load_roadmap",
    "load_scene",
    "path_length",
    "resample_path",
    "save_roadmap",
    "save_scene",
    "scene_from_dict",
    "solve_ik",
    "solve_trajopt",
    "time_parameterize",
]
__version__ = "0.1.0"
