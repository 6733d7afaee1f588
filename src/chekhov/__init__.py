"""chekhov: fast, reactive motion planning for robot arms (roadmap + trajectory optimisation).

The public API is flat::

    import chekhov
    world = chekhov.World.load("shelf_boxes")
    ok = world.fast.valid(Q)            # (N, 7) -> (N,) bool, numba-compiled
    ok = world.exact.path_valid(path)   # pinocchio + coal, 100 substeps per segment
"""

from chekhov.collision.exact import ExactChecker, densify
from chekhov.collision.fast import Contacts, FastChecker
from chekhov.errors import ChekhovError, IKError, RobotError, SceneError
from chekhov.robot.description import RobotDescription, SphereSettings
from chekhov.robot.ik import IKConfig, solve_ik
from chekhov.robot.robot import Robot
from chekhov.robot.spheres import SphereModel, build_sphere_model
from chekhov.scene.io import builtin_scenes, load_scene, save_scene, scene_from_dict
from chekhov.scene.model import Articulation, Grasp, Pose, Region, Scene, SceneObject, Shape
from chekhov.world import World

__all__ = [
    "Articulation", "ChekhovError", "Contacts", "ExactChecker", "FastChecker", "Grasp",
    "IKConfig", "IKError", "Pose", "Region", "Robot", "RobotDescription", "RobotError", "Scene",
    "SceneError", "SceneObject", "Shape", "SphereModel", "SphereSettings", "World",
    "build_sphere_model", "builtin_scenes", "densify", "load_scene", "save_scene",
    "scene_from_dict", "solve_ik",
]
__version__ = "0.1.0"
