"""Moving obstacles: their scripted true motion (:class:`MovingObstacle`), what the executive
makes of what its sensor saw (:class:`ObstacleTracks`: constant-velocity prediction), and the
obstacles it plans and monitors against (:func:`predicted_obstacles`: each obstacle now and
copies of it along its predicted motion over a horizon, inflated by a margin: a conservative
stand-in for the volume it sweeps).

Units: m, s; poses are (4, 4) homogeneous matrices in the world frame.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.primitives import Primitives, pack_primitives, shape_primitive
from chekhov.scene.model import Shape

Array = NDArray[np.float64]
Obstacles = Mapping[str, tuple[Shape, Array]]
"""name → (shape, T_world_obj (4, 4)): what a sensor frame holds and what checkers take."""


@dataclass(frozen=True)
class MovingObstacle:
    """A rigid shape moving in a straight line at constant speed while it is present.

    Attributes:
        name: its name. shape: its primitive (m).
        R_world_obj: (3, 3) its fixed orientation.
        p_start, p_end: (3,) m, where its sweep starts and ends.
        t_start: s, when it appears at ``p_start``; it moves at ``speed_mps`` (m/s) and is gone
            once it reaches ``p_end``.
    """

    name: str
    shape: Shape
    R_world_obj: Array
    p_start: Array
    p_end: Array
    t_start: float
    speed_mps: float

    @property
    def t_end(self) -> float:
        return self.t_start + float(np.linalg.norm(self.p_end - self.p_start)) / self.speed_mps

    def present(self, t: float) -> bool:
        return self.t_start <= t <= self.t_end

    def pose(self, t: float) -> Array:
        """T_world_obj (4, 4) at time t (s), clamped to the sweep."""
        u = 0.0 if self.t_end <= self.t_start else \
            min(max((t - self.t_start) / (self.t_end - self.t_start), 0.0), 1.0)
        T = np.eye(4)
        T[:3, :3] = self.R_world_obj
        T[:3, 3] = self.p_start + u * (self.p_end - self.p_start)
        return T


def obstacles_at(moving: tuple[MovingObstacle, ...], t: float) -> dict[str, tuple[Shape, Array]]:
    """The true obstacles present at time t (s)."""
    return {m.name: (m.shape, m.pose(t)) for m in moving if m.present(t)}


def to_segment(P: Array, a: Array, b: Array) -> Array:
    """(N, d) m: from the point of segment a-b ((d,) each) nearest each row of P (N, d) to it."""
    ab = b - a
    s = np.clip((P - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 1.0)
    return P - (a + s[:, None] * ab)


def inflate(shape: Shape, margin: float) -> Shape:
    """``shape`` grown by ``margin`` (m) on every side."""
    if shape.kind == "box":
        return Shape("box", tuple(s + 2 * margin for s in shape.size))
    if shape.kind == "cylinder":
        r, length = shape.size
        return Shape("cylinder", (r + margin, length + 2 * margin))
    return Shape("sphere", (shape.size[0] + margin,))


def inner_radius(shape: Shape) -> float:
    """m, the radius of a ball inside the shape around its centre (copies of the shape this
    far apart along a line leave no gap along it)."""
    if shape.kind == "box":
        return float(min(shape.size)) / 2
    return float(shape.size[0]) if shape.kind != "cylinder" else float(
        min(shape.size[0], shape.size[1] / 2))


@dataclass
class Track:
    """What the sensor saw of one obstacle: its shape, its last pose and that pose's time
    (s), and its velocity (m/s) from its last two poses — ``velocity_known`` False while it
    has been seen once (the velocity then reads 0 but may be anything)."""

    shape: Shape
    T_last: Array
    t_last: float
    velocity: Array = field(default_factory=lambda: np.zeros(3))
    velocity_known: bool = False


class ObstacleTracks:
    """Constant-velocity tracks of the obstacles a sensor reports (an obstacle missing from a
    frame is gone)."""

    def __init__(self) -> None:
        self.tracks: dict[str, Track] = {}

    def update(self, frame: Obstacles, stamp: float) -> None:
        """Take a sensor frame taken at time ``stamp`` (s)."""
        new: dict[str, Track] = {}
        for name, (shape, T) in frame.items():
            T = np.asarray(T, dtype=float)
            old = self.tracks.get(name)
            v = np.zeros(3)
            known = old is not None and stamp > old.t_last
            if old is not None and known:
                v = (T[:3, 3] - old.T_last[:3, 3]) / (stamp - old.t_last)
            new[name] = Track(shape, T, stamp, v, known)
        self.tracks = new

    def pose(self, name: str, t: float) -> Array:
        """The predicted pose of ``name`` at time t (s)."""
        tr = self.tracks[name]
        T = tr.T_last.copy()
        T[:3, 3] += tr.velocity * max(t - tr.t_last, 0.0)
        return T


class Sweep(NamedTuple):
    """One tracked obstacle's predicted sweep: copies of ``shape`` (inflated) at ``T``
    (4, 4) translated by each row of ``offsets`` (n, 3) m."""

    shape: Shape
    T: Array
    offsets: Array


def predicted_sweeps(tracks: ObstacleTracks, t0: float, horizon_s: float, margin_m: float,
                     max_copies: int = 24, *, speed_bound_m_s: float = 0.0
                     ) -> dict[str, Sweep]:
    """Each tracked obstacle, inflated by ``margin_m`` (m), at its predicted poses from t0 to
    t0 + horizon_s (s): copies at most one inner radius apart along the predicted line (at
    most ``max_copies``; the margin grows when the line is longer than they cover). An
    obstacle seen once (its velocity not known yet) may be moving at up to
    ``speed_bound_m_s`` (m/s) in any direction: with a bound, it is one copy where it was
    seen, inflated by the margin plus how far that speed takes it by t0 + horizon_s."""
    out: dict[str, Sweep] = {}
    for name, tr in tracks.tracks.items():
        if not tr.velocity_known and speed_bound_m_s > 0:
            reach = speed_bound_m_s * max(t0 + horizon_s - tr.t_last, 0.0)
            out[name] = Sweep(inflate(tr.shape, margin_m + reach), tr.T_last.copy(),
                              np.zeros((1, 3)))
            continue
        travel = float(np.linalg.norm(tr.velocity)) * horizon_s
        r = inner_radius(tr.shape) + margin_m
        n = min(max_copies, max(1, math.ceil(travel / max(r, 1e-3)) + 1))
        gap = travel / max(n - 1, 1)
        steps = horizon_s * np.arange(n) / max(n - 1, 1)
        out[name] = Sweep(inflate(tr.shape, margin_m + max(gap - r, 0.0) / 2),
                          tracks.pose(name, t0), steps[:, None] * tr.velocity)
    return out


def predicted_obstacles(tracks: ObstacleTracks, t0: float, horizon_s: float, margin_m: float,
                        max_copies: int = 24, *, speed_bound_m_s: float = 0.0
                        ) -> dict[str, tuple[Shape, Array]]:
    """:func:`predicted_sweeps` as obstacles a checker takes: copy i of obstacle ``name``
    is ``f"{name}#{i}"``."""
    out: dict[str, tuple[Shape, Array]] = {}
    for name, sweep in predicted_sweeps(tracks, t0, horizon_s, margin_m, max_copies,
                                        speed_bound_m_s=speed_bound_m_s).items():
        for i, d in enumerate(sweep.offsets):
            T = sweep.T.copy()
            T[:3, 3] += d
            out[f"{name}#{i}"] = (sweep.shape, T)
    return out


def predicted_primitives(tracks: ObstacleTracks, t0: float, horizon_s: float,
                         margin_m: float, *, speed_bound_m_s: float = 0.0) -> Primitives:
    """:func:`predicted_sweeps` packed as the fast checker's kernels read obstacles (the
    copies of :func:`predicted_obstacles`, in its order), with no obstacle objects made per
    copy: the executive packs several windows' sweeps every sensor frame."""
    sweeps = list(predicted_sweeps(tracks, t0, horizon_s, margin_m,
                                   speed_bound_m_s=speed_bound_m_s).values())
    one = pack_primitives([shape_primitive(w.shape, w.T) for w in sweeps])
    if not sweeps:
        return one
    counts = [len(w.offsets) for w in sweeps]
    return Primitives(np.repeat(one.kind, counts), np.repeat(one.R, counts, axis=0),
                      np.repeat(one.p, counts, axis=0) + np.vstack([w.offsets for w in sweeps]),
                      np.repeat(one.size, counts, axis=0), np.repeat(one.bound, counts))
