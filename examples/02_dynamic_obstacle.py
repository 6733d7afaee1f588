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

# a forearm (radius 5 cm, 40 cm long) across the middle of the answer (half its joint-space
# length: the answer may be a single straight segment), end effector height
P = before.path
s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
q_middle = np.array([np.interp(s[-1] / 2, s, P[:, j]) for j in range(P.shape[1])])
T_world_arm = np.eye(4)
T_world_arm[:3, 3] = world.robot.compute_ee_pose(q_middle)[:3, 3]
world.add_obstacle("forearm", chekhov.Shape("cylinder", (0.05, 0.4)), T_world_arm)
blocked = not world.exact.path_valid(before.path, substeps=100)
after = planner.plan(q_start, goal, time_limit_s=0.5)
print(f"before: {before.status} {before.time_s * 1e3:.1f} ms; the forearm blocks it: {blocked}; "
      f"after: {after.status} {after.time_s * 1e3:.1f} ms, "
      f"{[str(s.stage) for s in after.stages]}")
