"""The executive's last resort when the arm is in the obstacles' predicted way and neither a
dodge nor a brake is safe of it (:class:`Escaper`, on an
:class:`~chekhov.execute.evade.Evader`): of random escapes, the one that meets the obstacles'
predicted motion *latest* — when that is later than the motion the arm has. The predicted
motion is a worst case (the obstacles' sweeps over time windows, see
:meth:`Evader.safe_in_time <chekhov.execute.evade.Evader.safe_in_time>`); when every motion
meets it, the one that meets it latest leaves the most sensor frames in which to find a
better one, where braking along the path had run the arm into the forearm: kitchen, seed 1,
episode 0 collided in 4 of 4 runs while an escape was free of the forearm's true motion.

Units: s, rad, m.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.packed import PackedWorld
from chekhov.execute.evade import (
    COARSE,
    DODGE_CHUNK,
    ESCAPE_TRIES,
    Evader,
    Samples,
    past,
    window_edges,
)
from chekhov.execute.motion import Motion, State

Array = NDArray[np.float64]

FINE_WINDOW_S = 0.02
"""s, the windows of the sweeps escapes are judged against. The evader's windows (0.1 s) smear
the forearm 10 cm along its path, and a move that passes before it comes is judged to meet it
as early as one that waits for it."""
ESCAPE_CHUNK = 2 * DODGE_CHUNK
"""Escapes made and judged at a time (until one never meets the obstacles)."""
SLOWER = 0.5
"""Of the speed bound: how fast a track seen once is taken to grow when every escape meets
its worst case as early as the motion does (:meth:`Escaper._slower_tie`)."""


class Escaper:
    """Escapes judged by when they meet the obstacles' predicted motion."""

    def __init__(self, evader: Evader) -> None:
        self.evader = evader

    def latest(self, motion: Motion, t0: float, t_e: float,
               deadline: float | None = None, *, start: State | None = None
               ) -> tuple[Motion | None, float, float]:
        """When ``motion`` (from clock time t0, s; within the joint limits) meets the
        obstacles' predicted motion (no margin, windows of :data:`FINE_WINDOW_S` from t0)
        after t_e (s), to its end (after the horizon, against the last window's sweep and
        the static scene): of escapes from its state at t_e
        (:meth:`Evader.escape_moves <chekhov.execute.evade.Evader.escape_moves>`, made
        :data:`ESCAPE_CHUNK` at a time until one never meets it, :data:`ESCAPE_TRIES` at
        most, or ``deadline`` — a ``time.perf_counter()`` time — is past), the one within the
        limits to its end that meets it latest — unless none meets it a judging window
        later than ``motion`` and a track is new (:meth:`_slower_tie`, whose pass runs even
        when ``deadline`` is past: 3-4 ms more on shelf_boxes; its times are then those
        against the slower sphere). Returns (that escape, from t_e, or None; the time it
        meets it; the time ``motion`` does), s, inf: never, -inf: ``motion`` leaves the
        limits."""
        edges = window_edges(self.evader.settings.horizon_s, FINE_WINDOW_S)
        packs = self.evader.windows(t0, 0.0, FINE_WINDOW_S)
        _, t_motion = self._latest([motion], t0, packs, edges)
        if not t_e < t_motion < np.inf:
            return None, -np.inf, t_motion
        now = motion.sample(t_e) if start is None else start
        best: Motion | None = None
        t_best = -np.inf
        made: list[Motion] = []
        for c0 in range(0, ESCAPE_TRIES, ESCAPE_CHUNK):
            if c0 and past(deadline):
                break
            moves = self.evader.escape_moves(now, t_e, ESCAPE_CHUNK)
            made += moves
            i, t_i = self._latest(moves, t0, packs, edges, t_best)
            if i >= 0:
                best, t_best = moves[i], t_i
            if t_best == np.inf:
                break
        if t_best < t_motion + FINE_WINDOW_S:
            tie = self._slower_tie(motion, made, t0, t_motion, packs, edges)
            if tie is not None:
                return tie
        return best, t_best, t_motion

    def _slower_tie(self, motion: Motion, made: list[Motion], t0: float, t_motion: float,
                    packs: list[PackedWorld], edges: Array
                    ) -> tuple[Motion, float, float] | None:
        """No escape meets the worst-case prediction :data:`FINE_WINDOW_S` later than
        ``motion`` (from t0, s; it meets it at t_motion). When a track is new (seen once:
        a sphere growing at the speed bound, which every escape meets about as soon as the
        motion does), the escapes of ``made`` are judged against it growing at
        :data:`SLOWER` of the bound: the one that meets that latest, when
        :data:`FINE_WINDOW_S` later than ``motion`` does and no earlier than it against the
        worst case — the escape that gets farthest from where the track was seen. Returns
        (it, its time against the slower sphere, the motion's), s; or None. ``packs``:
        the worst case's windows (``edges``, s from t0), as :meth:`latest` judged them."""
        ev = self.evader
        if all(tr.velocity_known for tr in ev.tracks.tracks.values()) or not made:
            return None
        slower = ev.windows(t0, 0.0, FINE_WINDOW_S,
                            speed_bound_m_s=SLOWER * ev.settings.obstacle_speed_m_s)
        _, s_motion = self._latest([motion], t0, slower, edges)
        i, s_i = self._latest(made, t0, slower, edges, s_motion + FINE_WINDOW_S)
        if i < 0:
            return None
        if self._latest([made[i]], t0, packs, edges)[1] < t_motion - 1e-9:
            return None
        return made[i], s_i, s_motion

    def _latest(self, motions: list[Motion], t0: float, packs: list[PackedWorld],
                edges: Array, beat: float = -np.inf) -> tuple[int, float]:
        """The index of the one of ``motions`` (sampled from t0 or their start, s) that
        meets its window's sweep (``packs``, window ``edges`` s from t0; after the horizon
        the last window's, which holds the static scene too) latest, when later than
        ``beat`` (s; else -1), and that time (s; inf: never, to the motion's end); a motion
        that leaves the joint limits at any time is never taken (its time is -inf).
        Every :data:`COARSE`-th sample is checked first; then the motions, latest first by
        that, on all their samples before it, until no later one can beat the best."""
        if not motions:
            return -1, beat
        ev = self.evader
        flat = Samples.of([m.positions(max(m.t_start, t0), max(t0 + edges[-1], m.t_end),
                                       ev.settings.check_dt_s) for m in motions])
        win = np.clip(np.searchsorted(edges, flat.t - t0 + 1e-9, side="right") - 1,
                      0, len(packs) - 1)

        def first_bad(rows: NDArray[np.int64]) -> Array:
            """Per motion, the first time (s) among ``rows`` that is bad (inf: none)."""
            bad = np.zeros(len(rows), dtype=bool)
            for w in np.unique(win[rows]):
                sel = win[rows] == w
                bad[sel] = ~ev.world.fast.valid_in(packs[w], flat.Q[rows[sel]])
            out = np.full(len(motions), np.inf)
            np.minimum.at(out, flat.owner[rows[bad]], flat.t[rows[bad]])
            return out

        coarse = first_bad(np.flatnonzero(flat.step % COARSE == 0))
        coarse[flat.owner[~ev.world.robot.within_limits(flat.Q)]] = -np.inf
        best, t_best = -1, beat
        for i in np.argsort(-coarse, kind="stable"):
            if coarse[i] <= t_best:
                break
            mine = np.flatnonzero((flat.owner == i) & (flat.t < coarse[i]))
            t_i = min(float(first_bad(mine)[i]), float(coarse[i]))
            if t_i > t_best:
                best, t_best = int(i), t_i
        return best, t_best
