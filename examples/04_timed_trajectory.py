"""A timed trajectory: plan, time-parameterise under the robot's velocity limits and an
acceleration limit (toppra along the path with rounded corners; ruckig if that is refused), and plot
joint positions and velocities against their limits.

    python examples/04_timed_trajectory.py [out.png]
"""

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import chekhov

world = chekhov.World.load("tabletop_pole")
planner = chekhov.RoadmapTrajOpt(world, chekhov.load_or_build_roadmap(world))
planner.timing = chekhov.TimingConfig(acceleration_limit=3.0)    # rad/s², every joint
rng = np.random.default_rng(2)
Q = world.robot.sample_uniform(rng, 200)
q_start, q_reach = Q[world.fast.valid(Q)][:2]
result = planner.plan(q_start, chekhov.Goal.pose(world.robot.compute_ee_pose(q_reach)), 2.0)
traj = result.trajectory
assert traj is not None, result.status
print(f"{result.status}: {traj.duration:.2f} s, {traj.length:.2f} rad, timed by "
      f"{result.info['timing_method']} in {result.info['time_parameterize_s'] * 1e3:.1f} ms")

t = np.linspace(0.0, traj.duration, 1000)
q, qd, _ = traj.sample(t)
fig, (ax_q, ax_v) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
for k, name in enumerate(traj.joint_names):
    ax_q.plot(t, q[:, k], label=name)
    line, = ax_v.plot(t, qd[:, k])
    v_max = world.robot.velocity_limit[k]
    ax_v.axhline(v_max, color=line.get_color(), ls=":", lw=0.8)
    ax_v.axhline(-v_max, color=line.get_color(), ls=":", lw=0.8)
ax_q.set_ylabel("position (rad)")
ax_v.set_ylabel("velocity (rad/s); dotted: limits")
ax_v.set_xlabel("time (s)")
ax_q.legend(ncol=4, fontsize=7)
fig.suptitle(f"Roadmap + TrajOpt in tabletop_pole, timed by {result.info['timing_method']}")
fig.tight_layout()
out = sys.argv[1] if len(sys.argv) > 1 else "timed_trajectory.png"
fig.savefig(out, dpi=100)
print("wrote", out)
