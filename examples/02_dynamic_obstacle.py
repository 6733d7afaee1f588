"""React to a dynamic obstacle: plan, put a person's forearm (a cylinder) where the answer
passes, and plan again from the same start; the roadmap stays, only its edges' validity changes.

    python examples/02_dynamic_obstacle.py
"""

import numpy as np

import chekhov

world = chekhov.World.load("tabletop_pole")
planner = chekhov.RoadmapTrajOpt(world, chekhov.load_or_build_roadmap(world))
planner.warmup()
rng = np.random.default_rng(4)
Q = world.robot.sample_uniform(rng, 200)
q_start, q_reach = Q[world.fast.valid(Q)][:2]
goal = chekhov.Goal.pose(world.robot.compute_ee_pose(q_reach))
before = planner.plan(q_start, goal, time_limit_s=0.5)
assert before.success, before.status

# a forearm (radius 5 cm, 40 cm long) across the middle of the answer, end effector height
T_world_arm = np.eye(4)
T_world_arm[:3, 3] = world.robot.compute_ee_pose(before.path[len(before.path) // 2])[:3, 3]
world.add_obstacle("forearm", chekhov.Shape("cylinder", (0.05, 0.4)), T_world_arm)
blocked = not world.exact.path_valid(before.path, substeps=100)
after = planner.plan(q_start, goal, time_limit_s=0.5)
print(f"before: {before.status} {before.time_s * 1e3:.1f} ms; the forearm blocks it: {blocked}; "
      f"after: {after.status} {after.time_s * 1e3:.1f} ms, "
      f"{[str(s.stage) for s in after.stages]}")
