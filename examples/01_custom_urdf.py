"""Plan for any arm given by its URDF: here the Franka Panda, loaded by path, on a built-in
table scene; the answer is certified (goal, limits, exact collision check at 100 substeps).

    python examples/01_custom_urdf.py
"""

import numpy as np

import chekhov
from chekhov.robot.description import example_robot_data_dir

share = example_robot_data_dir()   # any folder with a URDF (and its meshes) will do
robot = chekhov.Robot.from_urdf(
    share / "robots/panda_description/urdf/panda.urdf", srdf=share /
    "robots/panda_description/srdf/panda.srdf", package_dirs=[share.parent],
    joints=[f"panda_joint{i}" for i in range(1, 8)], ee_frame="panda_hand_tcp",
    locked={"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04},
    T_world_base=chekhov.transforms.make_transform([0.35, 0.25, 0.75]))  # on the table (m)
world = chekhov.World(chekhov.load_scene("tabletop_pole"), robot)
ready, reach = [0, -0.785, 0, -2.356, 0, 1.571, 0.785], [-1.0, 0.3, 0, -1.5, 0, 1.9, 0.8]
planner = chekhov.OmplPlanner(world, "RRTConnect", simplify=True, seed=0)
result = planner.plan(np.array(ready), chekhov.Goal.configuration(np.array(reach)), 2.0)
print(result.status, result.info.get("certificate"), f"{result.time_s * 1e3:.1f} ms")
