"""The optimiser's view of the distance-term kernels (:mod:`chekhov.collision.distance_terms`):
:class:`TrajectoryDistances`, the discrete terms of a trajectory's waypoints and the swept terms
of its segments against a fast checker's current world, in compiled calls sized to keep a
deadline."""

from __future__ import annotations

import math
import time
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.distance_terms import SWEPT_ITERATIONS, segment_terms, waypoint_terms
from chekhov.errors import DeadlineError
from chekhov.robot.robot import Robot

Array = NDArray[np.float64]

DEADLINE_SHARE = 0.25
"""With a deadline to keep, one compiled call of the segment terms takes as many segments as,
at :data:`SEGMENT_COST_SPREAD` times the cost per segment seen so far, fit in this share of
the time left (at least one): far from the deadline a whole trajectory in one call, near it
one segment at a time, the clock looked at between calls."""
SEGMENT_COST_SPREAD = 30.0
"""How much more than the cost per segment seen so far one segment may cost: segments of one
path differ in cost by 30x and more (a segment far from everything skips every sphere with its
group's test; one near contact searches many swept spheres)."""
INITIAL_SEGMENT_S = 5e-5
"""s: the cost per segment assumed before the first call has measured one."""


class KernelRunner(Protocol):
    """What the distance terms need of a ``FastChecker`` (which warms them up, so this module
    does not import it): its robot, and ``run_kernel`` (a kernel called with its arguments and
    the checker's current packed world)."""

    robot: Robot

    def run_kernel(self, kernel: Any, *args: Any) -> Any: ...


class TrajectoryDistances:
    """Signed-distance terms of whole trajectories against a :class:`FastChecker`'s world.

    Reads the checker's packed world (``FastChecker.packed``) on every call, so its current
    obstacles (dynamic ones included). Fixed robot parts are grouped into spatial clusters
    with bounding spheres, so a link far from the torso skips all of its primitives with one
    test. The kernels compile (or load from numba's cache) on first use: :meth:`warm_up` (or
    ``FastChecker.warm_up``) does it ahead of a time limit.
    """

    def __init__(self, fast: KernelRunner) -> None:
        self.fast = fast
        self._segment_s = INITIAL_SEGMENT_S   # s, the recent cost per segment (segments())

    def warm_up(self) -> None:
        """Compile (or load) the distance-term kernels now."""
        q = 0.5 * (self.fast.robot.lower + self.fast.robot.upper)
        self.segments(np.vstack([q, q + 0.05]), 0.05, 1)
        self.waypoints(q[None], 0.05, 1)

    def waypoints(self, Q: Array, margin: float, C: int, with_obstacles: bool = True, *,
                  tabled_clear_m: float = math.inf) -> tuple[Array, Array]:
        """Discrete terms of Q (T, K): dist (T, C) m and grad (T, C, K) m/rad.

        A self pair of groups that one or two joints move relative to each other has a table
        of certified lower bounds on its geometries' gap (``self_table.py``); where that bound
        is at least ``tabled_clear_m`` (m) the pair is no term — its spheres may overlap
        (the Panda's link 5 and hand by up to 10 cm on a fifth of random configurations with
        spheres from whole mesh triangles, a UR5's wrist 2 and tool link by 14 mm on every
        one) while the links are apart."""
        Q = np.ascontiguousarray(Q, dtype=float)
        T, K = Q.shape
        dist, grad = np.empty((T, C)), np.empty((T, C, K))
        self.fast.run_kernel(waypoint_terms, Q, float(margin), float(tabled_clear_m), int(C),
                             bool(with_obstacles), dist, grad)
        return dist, grad

    def segments(self, Q: Array, margin: float, C: int, deadline: float = math.inf
                 ) -> tuple[Array, Array, Array]:
        """Continuous (swept) terms of the segments of Q (T, K): dist (T-1, C) m and grad0 /
        grad1 (T-1, C, K) m/rad with respect to each segment's first / second waypoint.
        With a finite ``deadline`` (``time.perf_counter()`` value, s) the segments go in
        compiled calls of as many segments as fit :data:`DEADLINE_SHARE` of the time left at
        the worst cost per segment (:data:`SEGMENT_COST_SPREAD` times the cost seen), and
        :class:`DeadlineError` is raised between two when it has passed. (A call's fixed
        cost, ~13 µs on shelf_boxes against ~8 µs a segment, is the Python side, the packed
        world's arrays passed in, the kernel's work arrays and the kinematics at the chunk's
        ends.)"""
        Q = np.ascontiguousarray(Q, dtype=float)
        T, K = Q.shape
        dist = np.empty((T - 1, C))
        g0, g1 = np.empty((T - 1, C, K)), np.empty((T - 1, C, K))
        a = 0
        while a < T - 1:
            left = deadline - time.perf_counter()
            if left < 0.0:
                raise DeadlineError("time limit reached while evaluating collision terms")
            worst = SEGMENT_COST_SPREAD * self._segment_s
            b = T - 1 if left > worst * (T - 1 - a) / DEADLINE_SHARE else \
                min(T - 1, a + max(1, int(DEADLINE_SHARE * left / worst)))
            t = time.perf_counter()
            self.fast.run_kernel(segment_terms, Q[a:b + 1], float(margin), int(C), dist[a:b],
                                 g0[a:b], g1[a:b], SWEPT_ITERATIONS)
            # the largest recent cost per segment (halved each call, so one slow call —
            # preempted, say — does not keep the chunks small for long)
            self._segment_s = max((time.perf_counter() - t) / (b - a), 0.5 * self._segment_s)
            a = b
        return dist, g0, g1
