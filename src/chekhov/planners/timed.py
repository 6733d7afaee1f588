"""A certified path as a timed trajectory that is certified too: :func:`timed_trajectory`."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.path_check import exact_path_decision
from chekhov.errors import TrajectoryError
from chekhov.paths import segment_runs
from chekhov.timing import (
    Timed,
    TimingConfig,
    joint_limits,
    polyline_offsets,
    time_parameterize,
)

if TYPE_CHECKING:
    from chekhov.world import World

Array = NDArray[np.float64]

CHECK_STEP_RAD = 1.6e-3
"""rad, the largest joint-space step between the configurations of a timed trajectory's exact
check (a planner's certified path: ≤ 0.16 rad segments at 100 substeps)."""
ON_POLYLINE_RAD = 1e-9
"""rad: a knot this close to a segment of the certified polyline lies on it (toppra's knots
on the straight parts are there to rounding)."""


def timed_trajectory(world: World, path: Array, config: TimingConfig | None = None) -> Timed:
    """``path`` (T, K) rad, certified collision-free, timed under the robot's velocity limits
    and ``config``. A trajectory that leaves the path's polyline (toppra's rounded corners) is
    kept only when its knots stay within the joint limits and the chords between them that
    leave the polyline (:func:`off_polyline_runs`: the corners' arcs; a chord between two knots
    on one segment lies on that certified segment) are collision-free by the exact decision at
    steps of at most :data:`CHECK_STEP_RAD`; otherwise the polyline itself is timed with ruckig
    (at rest at each waypoint), which needs no new check — as it is when toppra fails.
    Raises :class:`TrajectoryError` only when ruckig fails too."""
    config = config if config is not None else TimingConfig()
    robot = world.robot
    limits = joint_limits(robot.velocity_limit, config)
    ruckig = replace(config, method="ruckig")
    try:
        timed = time_parameterize(path, robot.joint_names, limits, config)
    except TrajectoryError:
        if config.method == "ruckig":
            raise
        return time_parameterize(path, robot.joint_names, limits, ruckig)
    if timed.max_deviation_rad <= ON_POLYLINE_RAD:
        return timed
    Q = timed.trajectory.positions
    if robot.within_limits(Q).all() and all(
            _exactly_free(world, Q[a:b + 1]) for a, b in off_polyline_runs(Q, path)):
        return timed
    return time_parameterize(path, robot.joint_names, limits, ruckig)


def off_polyline_runs(Q: Array, path: Array) -> list[tuple[int, int]]:
    """The knots of a trajectory Q (N, K) rad to check against the polyline ``path`` (T, K):
    maximal runs (a, b) (Q[a:b + 1], b > a) of chords k → k + 1 whose two knots are not both
    within :data:`ON_POLYLINE_RAD` of one segment of ``path``."""
    seg, dist = polyline_offsets(Q, path)
    on = dist <= ON_POLYLINE_RAD
    leaves = ~(on[:-1] & on[1:] & (seg[:-1] == seg[1:]))           # (N - 1,) chords
    return segment_runs(leaves)


def _exactly_free(world: World, Q: Array) -> bool:
    """The exact decision on the chords of Q (M, K) rad, at steps of at most
    :data:`CHECK_STEP_RAD`."""
    step = float(np.linalg.norm(np.diff(Q, axis=0), axis=1).max(initial=0.0))
    substeps = max(1, math.ceil(step / CHECK_STEP_RAD))
    return bool(exact_path_decision(world.fast, world.exact, Q, substeps).valid)
