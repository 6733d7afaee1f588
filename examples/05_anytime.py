"""Anytime answers: the first certified path arrives in milliseconds, improvements follow.

Roadmap + TrajOpt offers a path as soon as one is certified — the roadmap route itself, whose
edges were certified when the roadmap was built (only its ends' connections and its nodes'
cells are checked now), then the shortcut route (exact check at 100 substeps) — and shortens
it while time is left (more goal routes, TrajOpt).
``on_solution`` hears of each at once — a robot can start moving on the first.

    python examples/05_anytime.py
"""

import numpy as np

import chekhov

world = chekhov.World.load("shelf_boxes")
planner = chekhov.RoadmapTrajOpt(world, chekhov.load_or_build_roadmap(world))
planner.warmup()
rng = np.random.default_rng(3)
Q = world.robot.sample_uniform(rng, 200)
q_start, q_reach = Q[world.fast.valid(Q)][:2]
goal = chekhov.Goal.pose(world.robot.compute_ee_pose(q_reach))


def heard(s: chekhov.Solution) -> None:
    print(f"  {s.time_s * 1e3:6.1f} ms  {s.length_rad:5.2f} rad  from {s.stage}")


result = planner.plan(q_start, goal, time_limit_s=1.0, on_solution=heard)
print(f"{result.status}: first answer after {result.first_solution_s * 1e3:.1f} ms, final after "
      f"{result.time_s * 1e3:.1f} ms ({len(result.solutions)} solutions)")
