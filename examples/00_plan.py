"""Plan in a built-in scene with Roadmap + TrajOpt: a certified answer in milliseconds.

    python examples/00_plan.py
"""

import numpy as np

import chekhov

world = chekhov.World.load("shelf_boxes")                       # Baxter's left arm, a shelf
planner = chekhov.RoadmapTrajOpt(world, chekhov.load_or_build_roadmap(world))  # cached on disk
planner.warmup()                                                 # compile before timing
rng = np.random.default_rng(0)
Q = world.robot.sample_uniform(rng, 200)
q_start, q_reach = Q[world.fast.valid(Q)][:2]                    # two free configurations, rad
goal = chekhov.Goal.pose(world.robot.compute_ee_pose(q_reach))   # T_world_ee, 5 mm / 0.05 rad
result = planner.plan(q_start, goal, time_limit_s=0.5)
print(result.status, f"{result.time_s * 1e3:.1f} ms", result.info.get("certificate"),
      [f"{s.stage}:{s.status}" for s in result.stages])
