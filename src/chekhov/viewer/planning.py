"""What the viewer plans with and shows about a plan: the planner menu, and a plan's seed and
trajectory as end-effector traces with a readable summary. No viser import here."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chekhov.errors import ChekhovError
from chekhov.planners.base import Planner, PlannerBase, PlanResult
from chekhov.planners.registry import GROUPS, canonical_planner_name, make_planner
from chekhov.planners.status import Stage
from chekhov.roadmap.graph import Roadmap
from chekhov.timing import TimingConfig
from chekhov.trajectory import JointTrajectory
from chekhov.world import World

Array = NDArray[np.float64]

ROADMAP_TRAJOPT = "Roadmap+TrajOpt"
# the planner menu: the registry's fast group (chekhov.planners.registry)
PLANNER_NAMES: tuple[str, ...] = GROUPS["fast"]


class PlannerPool:
    """One planner of each kind for a world, made on first use (they keep warm state)."""

    def __init__(self, world: World, roadmap: Roadmap | None) -> None:
        self.world = world
        self.roadmap = roadmap
        self._planners: dict[str, Planner] = {}

    def get(self, name: str) -> Planner:
        name = canonical_planner_name(name)
        if name not in PLANNER_NAMES:
            raise ChekhovError(f"planner '{name}' is not in the viewer's menu "
                               f"{list(PLANNER_NAMES)}")
        if name not in self._planners:
            planner = make_planner(name, self.world, self.roadmap)
            if isinstance(planner, PlannerBase):
                planner.timing = TimingConfig()   # the viewer plays timed trajectories
            self._planners[name] = planner
        return self._planners[name]


@dataclass(frozen=True)
class PlanView:
    """A plan as the viewer shows it.

    Attributes:
        planner: planner name. result: the planner's answer.
        path: the trajectory (T, K) rad, or None when planning failed.
        seed: the seed (T', K) rad: the path of the stage the final optimisation started from
            (the roadmap's own route, another planner's path, or TrajOpt's straight line);
            None when there was none.
        ee_path, ee_seed: end-effector positions (T, 3) / (T', 3) in the world, m.
        timed: the path timed (played in real time), when the planner timed it.
    """

    planner: str
    result: PlanResult
    path: Array | None
    seed: Array | None
    ee_path: Array | None
    ee_seed: Array | None
    timed: JointTrajectory | None = None

    @classmethod
    def of(cls, world: World, planner: str, result: PlanResult) -> PlanView:
        report = result.seed_report
        seed = report.path if report is not None and report.stage in (
            Stage.ROADMAP_SEED, Stage.SEED) and report.path is not None else result.seed
        seed_arr = None if seed is None else np.atleast_2d(np.asarray(seed, dtype=float))
        path = result.path if result.success else None
        ee = world.robot.compute_ee_poses
        return cls(planner, result, path, seed_arr,
                   None if path is None else ee(path)[:, :3, 3],
                   None if seed_arr is None else ee(seed_arr)[:, :3, 3],
                   result.trajectory if path is not None else None)

    def configuration_at(self, t: float) -> Array | None:
        """The configuration at fraction t in [0, 1] of the motion: of its duration when it
        is timed, else of the waypoints (uniform in index)."""
        if self.path is None:
            return None
        if self.timed is not None:
            q, _, _ = self.timed.sample(float(np.clip(t, 0.0, 1.0)) * self.timed.duration)
            return np.asarray(q)
        return interpolate_path(self.path, t)

    def summary_markdown(self) -> str:
        """Timing breakdown, path length and status as a Markdown table."""
        r = self.result
        seed_fallback = bool(r.fell_back_to_seed)
        rows = [("planner", self.planner),
                ("status", r.status + (" (seed fallback)" if seed_fallback else "")),
                ("total", f"{1e3 * r.time_s:.1f} ms")]
        rows += [(f"· {k}", f"{1e3 * v:.1f} ms") for k, v in r.timing_s.items()]
        if self.timed is not None:
            rows.append(("motion duration", f"{self.timed.duration:.2f} s "
                                            f"({r.info.get('timing_method', '')})"))
        if self.path is not None:
            rows.append(("path length", f"{r.path_length:.3f} rad"))
            rows.append(("end-effector travel", f"{ee_length(self.ee_path):.3f} m"))
            rows.append(("waypoints", str(len(self.path))))
        if self.seed is not None:
            from chekhov.planners.base import path_length
            rows.append(("seed length", f"{path_length(self.seed):.3f} rad"))
        body = "\n".join(f"| {a} | {b} |" for a, b in rows)
        return "| | |\n|---|---|\n" + body


def ee_length(points: Array | None) -> float:
    """Length (m) of a polyline (T, 3)."""
    if points is None or len(points) < 2:
        return 0.0
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def polyline_segments(points: Array) -> Array:
    """A polyline (T, 3) as line segments (T - 1, 2, 3) (one degenerate segment if T < 2)."""
    P = np.atleast_2d(np.asarray(points, dtype=float))
    if len(P) < 2:
        P = np.vstack([P, P])
    return np.stack([P[:-1], P[1:]], axis=1)


def interpolate_path(path: Array, t: float) -> Array:
    """Configuration at fraction t in [0, 1] of a path (T, K), linear between waypoints and
    uniform in waypoint index."""
    P = np.atleast_2d(path)
    s = float(np.clip(t, 0.0, 1.0)) * (len(P) - 1)
    i = min(int(np.floor(s)), len(P) - 2) if len(P) > 1 else 0
    if len(P) == 1:
        return P[0].copy()
    a = s - i
    return np.asarray((1 - a) * P[i] + a * P[i + 1], dtype=float)
