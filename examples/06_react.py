"""06 — React while moving: drive the executive from your own 100 Hz loop.

A pick-and-place move in tabletop_pole; while the arm moves, a person's forearm sweeps across
its way (seen by a 30 Hz sensor with 40 ms latency), the goal changes to another object's
pre-grasp, and the arm is bumped. Each tick the loop hands the executive what the robot and the
sensor report and sends the robot the command it returns. Afterwards the executed motion is
checked against the forearm's true poses, and a plot shows joint velocities, clearance and the
disturbances.

    python examples/06_react.py [PLOT.png] [EPISODE]
"""

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from chekhov import World
from chekhov.execute import (
    EpisodeScript,
    Executor,
    ExecutorConfig,
    InlineWorker,
    Observation,
    evaluate_episode,
    executive_planner,
    make_script,
    obstacles_at,
    run_episode,
    start_and_goal,
)
from chekhov.execute.simulate import EpisodeRecord
from chekhov.timing import joint_limits

out = sys.argv[1] if len(sys.argv) > 1 else "react_episode.png"
index = int(sys.argv[2]) if len(sys.argv) > 2 else 1
world = World.load("tabletop_pole")
planner = executive_planner("Roadmap+TrajOpt", world)
config = ExecutorConfig()

# The episode's script is timed against the same move undisturbed.
q0, goal = start_and_goal(world, 0, index)
plain_executor = Executor(world, InlineWorker(world, planner, config.timing), goal, config)
plain = run_episode(world, plain_executor, EpisodeScript(index, q0, goal, ""), 20.0)
ee = world.robot.compute_ee_poses(plain.q)[:, :3, 3]
script = make_script(world, 0, index, plain.t_reached, ee, plain.q)

# Your own loop: the robot tracks each command; here it is simulated, tick by tick.
executor = Executor(world, InlineWorker(world, planner, config.timing), script.goal, config)
executor.warmup()   # the kernels a reaction uses, loaded before the first tick
dt, period, latency = config.control_dt_s, 1 / 30, 0.04
q, qd = script.q_start.copy(), np.zeros_like(script.q_start)
rows, frame_no = [], 0
for tick in range(int(20 / dt)):
    t = tick * dt
    kicked = bool(script.kicks and abs(script.kicks[0].t - t) < dt / 2)
    if kicked:
        q = q + script.kicks[0].dq * 0.5                # a bump of up to 0.05 rad per joint
    goal_now = next((g.goal for g in script.goal_changes if abs(g.t - t) < dt / 2), None)
    frame = stamp = None
    if frame_no * period + latency <= t:                 # a sensor frame arrives
        stamp = frame_no * period
        frame = obstacles_at(script.obstacles, stamp)
        frame_no += 1
    command = executor.step(Observation(t, q, qd, frame, stamp, goal_now))
    rows.append((t, q.copy(), qd.copy(), command.qdd, kicked, command.mode))
    q, qd = command.q, command.qd
    if executor.done and t > script.last_event_s:
        break

record = EpisodeRecord(
    np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
    np.array([r[2] for r in rows]), np.array([r[3] for r in rows]),
    np.array([r[4] for r in rows]), tuple(r[5] for r in rows), script.obstacles,
    executor.goal, executor.done, rows[-1][0] if executor.done else None,
    tuple(executor.reactions), executor.counters, ())
limits = joint_limits(world.robot.velocity_limit, config.timing)
check = evaluate_episode(world, record, limits, period + latency + config.planning_budget_s)

fig, (ax_v, ax_c) = plt.subplots(2, 1, sharex=True, figsize=(9, 6))
ax_v.plot(record.times, record.qd)
ax_v.set_ylabel("joint velocity (rad/s)")
shown = np.where(np.isfinite(check.clearances), check.clearances, np.nan)
ax_c.plot(record.times, shown, color="k")
ax_c.axhline(0.0, color="r", lw=0.8)
ax_c.set_ylabel("clearance to the forearm (m)")
ax_c.set_xlabel("time (s)")
colours = {"obstacle": "tab:red", "goal": "tab:green", "kick": "tab:purple"}
for r in executor.reactions:
    for ax in (ax_v, ax_c):
        ax.axvline(r.t_observed, color=colours[r.kind], ls="--", lw=0.8)
ax_v.set_title("dashed: disturbance observed (red forearm conflict, green new goal, "
               "purple kick)", fontsize=9)
fig.tight_layout()
fig.savefig(out, dpi=110)

latencies = [round(1000 * (r.t_reacted - r.t_observed)) for r in executor.reactions
             if r.t_reacted is not None]
print(f"reached: {executor.done} after {rows[-1][0]:.2f} s (undisturbed {plain.t_reached:.2f} s); "
      f"collision: {check.collision}; min clearance {check.min_clearance_m:.3f} m; "
      f"limit violations: {check.limit_violations}; reactions "
      f"{[r.kind for r in executor.reactions]} answered after {latencies} ms; plot: {out}")
