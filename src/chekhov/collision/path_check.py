"""The exact checker's decision on a whole path — its samples and the motion between them — fast,
and the certificate it leaves.

Samples: the waypoints and ``substeps`` interpolated configurations per segment (the order of
:func:`exact.densify`). Checking only them is not enough: a Panda answer collided by 2 µm
between two samples 0.0016 rad apart that were 40 and 80 µm clear. So the straight motion
between adjacent samples is proved free too, each sample answering for its *cell*, the
half-steps on either side of it:

* Motion bound. Along a straight joint step Δq (rad) no point of collision pair p's two
  geometries moves, relative to the other, by more than L_p = Σ_k |Δq_k| W_pk metres
  (:attr:`ExactChecker.motion_weights`, from ``advance.pair_weights``, computed once per
  robot and obstacle set): W_pk bounds the distance from joint k's axis of any point of the
  geometry joint k moves, over every configuration (from the geometry's extent and the fixed
  joint-to-joint offsets, by the triangle inequality), and only the joints between the two
  geometries count. A point at distance r from a revolute axis moves at most r |Δq_k| when
  that joint turns by Δq_k, and the joints' contributions add up. So a sample whose pair p is
  at least L_p / 2 apart keeps it apart over its cell; a margin μ_p ≥ L_p / 2 (L_p of the
  path's largest step, rounded up, plus :data:`MARGIN_SLACK`) is asked of every sample.
* The fast checker screens every sample (its spheres contain the collision geometry: fast
  free ⇒ exact free) with each sphere group's confirmation margin (``GroupGeometry.pad``,
  0.1 mm) raised to the largest μ_p of the group's pairs and, where that exceeds the spheres'
  padding (2 mm on the Panda, 1 mm on the Baxter), its spheres grown by the difference
  (``dense_path.with_margin``): a sample it calls free then has each pair either cleared by
  the spheres, so at least padding + growth apart, or proved more than the margin apart on
  the covered geometry. Either way its cell is free.
* Where the screen alarms, coal decides, sample by sample over :data:`EXACT_WINDOW` samples.
  The path's first and last configurations by the boolean test alone: a start or goal may
  legitimately be very near an object (a grasp in contact-free proximity), so the half-steps
  next to them are not covered. Any other sample by coal's collision test with security
  margin μ_p plus :data:`LOOKAHEAD` steps' motion bound (:meth:`ExactChecker.pairs_within`);
  the pairs within it get coal's distance; a distance within :data:`MARGIN_SLACK` of contact
  fails the path; a pair nearer than its cell's own bound, but not touching, gets its cell
  refined (:func:`_motion_free`): each half-step is bisected, with coal distances, until the
  distances at the ends of every piece exceed the piece's motion bound, at most
  :data:`REFINE_POINTS` distances per half-step — so a path that passes close but free is
  still certified, down to a few µm. Passed pairs keep certificates (:class:`_Coal`), so that
  along a stretch near contact coal only looks at the pairs near contact again, and pairs
  whose bounding spheres are far apart need no coal (:meth:`ExactChecker.pair_bounds`).

With no motion bound (a joint that is not revolute) the coal checks are the boolean ones on
the samples alone. The fast checker walks :data:`CHUNK_SEGMENTS` segments at a time with
clearance certificates (``dense_path.py``); near the deadline a compiled call looks at as
many configurations as half the time left allows (``walk_runs.visit_budget``), and the clock
is looked at between calls.
A passed check returns a :class:`PathCertificate` bound to the path's bytes, the substeps
and the checkers' obstacle version, so that a later certification of the very same path in
the very same world (``chekhov.planners.certify``) need not run it again.
"""

from __future__ import annotations

import hashlib
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from chekhov.collision import dense_path, walk_runs
from chekhov.collision.codes import NONE
from chekhov.collision.exact import ExactChecker, densify
from chekhov.collision.fast import FastChecker
from chekhov.collision.motion_bounds import decision_margins
from chekhov.paths import resample_path

Array = NDArray[np.float64]

CHUNK_SEGMENTS = 64
"""Segments screened per fast-checker call (each sets up its work arrays and margins, and
its certificates start afresh; near the deadline the calls are cut shorter by their visit
budget). 8 against 2, in one process: the first answer's median 9.3 → 7.6 ms (kitchen
tasks), 5.5 → 4.7 (panda_cage), 3.5 → 3.2 (tabletop_pole); the exact check of a timed
answer's arcs 21.6 → 16.0, 12.4 → 9.1, 13.7 → 8.5 ms. 64 against 8, with the walk's runs of
short segments (``walk_runs.run_end``), alternating in one process on the arcs of 40 task
cases' timed answers: 0.287 → 0.209 ms a run of arcs (shelf_boxes), 0.89 → 0.79
(panda_cage); the first answers' certification (``benchmarks/certify_walk.py``) 2-7% less
on the mean (shelf_boxes, panda_cage, kitchen, twice each)."""
EXACT_WINDOW = 4
"""Configurations coal checks from an alarm before the fast walk resumes (and the deadline is
looked at again)."""
MARGIN_SLACK = 2e-6
"""m: added to every clearance margin and taken from every coal distance, for coal's own
tolerance (its GJK stops within about 1e-6 m)."""
LOOKAHEAD = 8
"""Samples a pair stays certified after coal's screening test passes it: the test's margin is
the pair's margin plus its motion bound over that many samples."""
BOUND_PAIRS = 16
"""With more pairs than this to look at in a sample, bounding spheres clear the far ones
first (:meth:`ExactChecker.pair_bounds`, ~50 µs); fewer go to coal directly."""
PAIRS_PER_CALL = 400
"""Collision pairs coal's screening test takes at a time, the deadline looked at between
(1493 of the kitchen's took 3.1 ms in one call)."""
REFINE_POINTS = 48
"""Coal distance evaluations at most per half-step refined by :func:`_motion_free`; a motion
that needs more (closer than about L_p / 48, a few µm on the Panda) is not certified."""
_GRID = 2 ** (1 / 8)
"""Margins are rounded up to powers of this (≤ 9 % stricter), so that the same values recur
from path to path and coal's requests are seldom set again."""


@dataclass(frozen=True)
class PathCertificate:
    """Proof that :func:`exact_path_decision` passed a path.

    Attributes:
        digest: SHA-1 of the path's float64 bytes and shape.
        substeps: interpolated configurations per segment that were checked.
        obstacles_version: the fast checker's ``obstacles_version`` at the check.
        resampled_from: SHA-1 of the path whose resampling (``resample_path`` at
            :data:`CERTIFY_MAX_SEGMENT_RAD`) was checked, when the caller that resampled it
            says so (``chekhov.planners.certify``, ``route_check``, TrajOpt's validation).
    """

    digest: bytes
    substeps: int
    obstacles_version: int
    resampled_from: bytes | None = None

    def covers(self, path: Array, substeps: int, fast: FastChecker) -> bool:
        """Whether this certificate is for ``path`` at exactly ``substeps`` (a denser check
        does not contain a sparser one's configurations) in ``fast``'s world as it is now."""
        return (self.substeps == substeps and self.obstacles_version == fast.obstacles_version
                and self.digest == path_digest(path))

    def covers_resampled(self, path: Array, substeps: int, fast: FastChecker) -> bool:
        """:meth:`covers` for the resampling of ``path`` that ``resampled_from`` names,
        without resampling it again."""
        return (self.resampled_from is not None and self.substeps == substeps
                and self.obstacles_version == fast.obstacles_version
                and self.resampled_from == path_digest(path))


class PathDecision(NamedTuple):
    """valid: True / False, or None when the deadline passed first; certificate when True."""

    valid: bool | None
    certificate: PathCertificate | None


def path_digest(path: Array) -> bytes:
    P = np.ascontiguousarray(path, dtype=np.float64)
    return hashlib.sha1(P.tobytes() + str(P.shape).encode()).digest()


CERTIFY_SUBSTEPS = 100
"""Interpolated configurations per segment of a certified path (the paper's 100)."""

CERTIFY_MAX_SEGMENT_RAD = 0.16
"""rad: a certified path's longer segments are split evenly first, so that its substeps are
never more than 0.0016 rad apart (TrajOpt's waypoint spacing, the paper's)."""

CERTIFICATION_ID = "exact_path_decision/substeps=100/max_segment=0.16/cells/2026-11-28"
"""Names what :func:`motion_certified` proves. A roadmap whose edges passed it records this
(``RoadmapMeta.notes["edges_certified_by"]``), and a path's certificate may then be composed
from those edges (``route_check.route_decision``): change it whenever the decision's meaning
changes, so that roadmaps built before are no longer taken at their word."""


def motion_certified(fast: FastChecker, exact: ExactChecker, q_a: Array, q_b: Array,
                     deadline: float = math.inf) -> bool:
    """Whether the straight motion q_a → q_b (K,) rad passes the check a certified path holding
    it as a segment passes (split at :data:`CERTIFY_MAX_SEGMENT_RAD`,
    :data:`CERTIFY_SUBSTEPS` substeps each, :func:`exact_path_decision`); False also when
    ``deadline`` (a ``time.perf_counter()`` value, s) passes first."""
    D = resample_path(np.stack([q_a, q_b]), CERTIFY_MAX_SEGMENT_RAD)
    if len(D) < 2:
        return True
    return exact_path_decision(fast, exact, D, CERTIFY_SUBSTEPS, deadline).valid is True


def exact_path_decision(fast: FastChecker, exact: ExactChecker, path: Array,
                        substeps: int = 100, deadline: float = math.inf) -> PathDecision:
    """Whether every waypoint of ``path`` (T, K) rad, ``substeps`` interpolated configurations
    per segment and the straight motions between them are collision-free by the exact
    checker's decision (module docstring), or None when ``deadline`` (a
    ``time.perf_counter()`` value, s) passed before the decision.

    The fast checker walks :data:`CHUNK_SEGMENTS` segments at a time with clearance
    certificates (near the deadline in calls of ``walk_runs.visit_budget`` configurations);
    from each configuration it flags, coal checks the next :data:`EXACT_WINDOW`
    configurations of that segment, and the fast walk resumes after them (or after those
    coal's own certificates cover).
    """
    P = np.ascontiguousarray(path, dtype=np.float64)
    if not P.flags.writeable:   # as FastChecker._run_in: no read-only kernel versions
        P = P.copy()
    coal_ = _Coal.make(fast, exact, P, int(substeps))
    coal_.deadline = deadline
    try:
        valid = _decide(fast, coal_, P)
    except _PastDeadlineError:
        return PathDecision(None, None)
    if not valid:
        return PathDecision(False, None)
    return PathDecision(True, PathCertificate(path_digest(P), int(substeps),
                                              fast.obstacles_version))


def cells_free(fast: FastChecker, exact: ExactChecker, cells: Array,
               deadline: float = math.inf) -> bool | None:
    """Whether each cell (M, 3, K) rad — a sample and the samples on either side of it —
    passes :func:`exact_path_decision` as a path of its own with no substeps, which proves
    the middle sample free and every collision pair apart over its cell (the half-steps
    towards its neighbours). Decided together: one screen of the middle samples with the
    margins of the largest of all the cells' steps (a pass there proves every cell), and
    each cell's own decision only where that screen alarms. None: ``deadline``
    (``time.perf_counter()`` value, s) passed first."""
    C = np.ascontiguousarray(cells, dtype=np.float64)
    if len(C) == 0:
        return True
    Q = np.ascontiguousarray(C[:, 1] if len(C) > 1 else C[[0, 0], 1])   # the walk's path
    steps = np.concatenate([C[:, 1] - C[:, 0], C[:, 2] - C[:, 1]])
    coal_ = _Coal.make(fast, exact, Q, 0, steps)
    coal_.deadline = deadline
    try:
        i = coal_.first_alarm(fast, Q, 0)
        while i is not None:
            valid = exact_path_decision(fast, exact, C[min(i, len(C) - 1)], 0, deadline).valid
            if valid is not True:
                return valid
            i = coal_.first_alarm(fast, Q, i + 1) if i + 1 < len(Q) else None
    except _PastDeadlineError:
        return None
    return True


def screen_margins(fast: FastChecker, exact: ExactChecker, path: Array, substeps: int
                   ) -> tuple[Array, Array]:
    """(pad, grow) (G,) m, per fast-checker group: the confirmation margins and sphere growth
    with which :func:`exact_path_decision` screens ``path`` (T, K) rad at ``substeps`` (the
    last two arguments of ``dense_path.first_dense_collision``; module docstring). Empty
    arrays: no motion bound, the screen as it is."""
    coal_ = _Coal.make(fast, exact, np.ascontiguousarray(path, dtype=np.float64), substeps)
    return coal_.pad, coal_.grow


class _PastDeadlineError(Exception):
    """The decision's deadline passed (looked at between chunks, windows and coal queries)."""


def _decide(fast: FastChecker, coal_: _Coal, P: Array) -> bool:
    """:func:`exact_path_decision`'s walk: whether P is free; raises :class:`_PastDeadlineError`."""
    last = len(P) - 1
    n = coal_.substeps + 1
    a = 0
    while a < max(last, 1):
        coal_.check_time()
        chunk = P[a:min(a + CHUNK_SEGMENTS, last) + 1]
        size = (len(chunk) - 1) * n + 1   # the chunk's samples
        i = coal_.first_alarm(fast, chunk, 0)
        while i is not None:
            coal_.check_time()
            # coal, configuration by configuration, over a window, at most to the segment's
            # far end (conservative advancement's first distances cost more than a few
            # collision tests: a window of 4 near contact took 4.7 ms that way on the Panda,
            # 0.4 ms so)
            end = min(size, (i // n + 1) * n + 1, i + EXACT_WINDOW)
            if not all(coal_.sample_free(a * n + j) for j in range(i, end)):
                return False
            end = max(end, coal_.certified_through() + 1 - a * n)
            i = coal_.first_alarm(fast, chunk, end) if end < size else None
        a += CHUNK_SEGMENTS
    return True


class _Coal:
    """Coal's part of one path's decision (module docstring), with certificates: a pair whose
    clearance at sample j exceeds its margin μ_p by e stays margin-clear for floor(e / L_p)
    samples (L_p: the pair's largest motion bound per sample on this path), so that along a
    stretch near contact only the pairs near contact are looked at again."""

    def __init__(self, exact: ExactChecker, P: Array, substeps: int,
                 weights: tuple[Array, NDArray[np.int64]] | None = None,
                 margins: tuple[Array, Array, Array, Array] | None = None) -> None:
        self.exact = exact
        self.P = P
        self.substeps = substeps
        self.weights = weights
        self.D: Array | None = None   # the densified path, when first needed
        self.deadline = math.inf      # time.perf_counter() value, s
        # per distinct weight row, m: L_row the largest motion bound of one step between
        # samples, mu_row the margin; per fast-checker group, m: the screen's confirmation
        # margins and sphere growth (empty: the screen as it is) — ``decision_margins``
        z = np.zeros(0)
        self.L_row, self.mu_row, self.pad, self.grow = margins if margins is not None else (
            z, z, z, z)
        # per pair (set when coal is first asked, :meth:`_pair_arrays`): the motion bound L,
        # margin mu, screening-test margin look and the sample each pair is certified through
        self.L = self.mu = self.look = z
        self.until: NDArray[np.int64] | None = None

    def _pair_arrays(self) -> NDArray[np.int64]:
        """``until`` (P,), with L, mu and look spread from their weight rows to the pairs on
        first use: most decisions never ask coal (a fast-free path), and the spread costs
        ~15 µs on the Baxter's 1000-1500 pairs."""
        if self.until is None:
            assert self.weights is not None
            row = self.weights[1]
            self.L, self.mu = self.L_row[row], self.mu_row[row]
            # the screening test's margins: a pass certifies the pair for LOOKAHEAD samples
            self.look = (self.mu_row + LOOKAHEAD * self.L_row)[row]
            self.until = np.full(len(row), -1, dtype=np.int64)
        return self.until

    @staticmethod
    def make(fast: FastChecker, exact: ExactChecker, P: Array, substeps: int,
             steps: Array | None = None) -> _Coal:
        """The checks for path P (T, K) at ``substeps``: margins from the path's largest
        steps (or from ``steps`` (M, K) rad, the steps between samples to answer for); each
        fast-checker group's confirmation margin the largest of its pairs', and its spheres
        grown by as much as that exceeds their padding (module docstring)."""
        weights = exact.motion_weights
        if weights is None or (len(P) < 2 and steps is None):
            return _Coal(exact, P, substeps)
        # per distinct weight row (the kitchen: 1493 pairs, 63 rows) the largest motion bound
        # of one step between samples (of the given ``steps`` instead, when there are) and
        # half of it rounded up; per group, the largest of its pairs' margins and as much as
        # that exceeds the spheres' padding; in one compiled call (~40 µs in numpy)
        W = weights[0]
        touches = _group_rows(fast, exact, weights)
        m = decision_margins(
            P if steps is None else np.ascontiguousarray(steps, dtype=np.float64),
            steps is None, W, 1.0 / (substeps + 1) if steps is None else 1.0, touches,
            fast.robot.description.spheres.padding, _GRID, MARGIN_SLACK)
        U, G = len(W), len(touches)
        return _Coal(exact, P, substeps, weights,
                     (m[:U], m[U:2 * U], m[2 * U:2 * U + G], m[2 * U + G:]))

    def first_alarm(self, fast: FastChecker, P: Array, start: int) -> int | None:
        """Index (>= ``start``) into ``densify(P, self.substeps)`` of the first configuration
        the screen flags, or None (``FastChecker.first_dense_collision`` with the margins):
        in calls of ``walk_runs.visit_budget`` configurations, the clock looked at between
        them."""
        while True:
            visits = walk_runs.visit_budget(self.deadline - time.perf_counter())
            i, resume = fast.run_kernel(dense_path.first_dense_collision, P, self.substeps,
                                        start, visits, self.pad, self.grow)
            if resume < 0:
                return None if i == NONE else int(i)
            self.check_time()
            start = int(resume)

    def check_time(self) -> None:
        """Raise :class:`_PastDeadlineError` once the deadline has passed."""
        if time.perf_counter() > self.deadline:
            raise _PastDeadlineError

    def certified_through(self) -> int:
        """The last sample through which coal's certificates cover every pair (-1: none)."""
        return -1 if self.until is None else int(self.until.min())

    def sample_free(self, j: int) -> bool:
        """Whether sample j of the densified path is free and, unless it is the first or the
        last, keeps every collision pair apart over its cell (module docstring)."""
        if self.D is None:
            self.D = densify(self.P, self.substeps)
        D, exact = self.D, self.exact
        if self.weights is None:
            return exact.is_valid(D[j])
        until = self._pair_arrays()
        todo = np.flatnonzero(until < j)
        if len(todo) == 0:
            return True
        if j == 0 or j == len(D) - 1:
            return exact.is_valid(D[j])
        q = D[j]
        if len(todo) > BOUND_PAIRS:   # those with bounding spheres far enough apart: no coal
            self.check_time()
            lb = exact.pair_bounds(q, todo)
            far = lb >= self.look[todo]
            until[todo[far]] = j + ((lb[far] - self.mu[todo[far]])
                                    // self.L[todo[far]]).astype(np.int64)
            todo = todo[~far]
            if len(todo) == 0:
                return True
        close = self._pairs_within(q, todo)
        until[todo] = j + LOOKAHEAD
        if len(close) == 0:
            return True
        self.check_time()
        d = exact.pair_distances(q, close)
        if d.min() <= MARGIN_SLACK:   # in contact, or too near it to prove anything
            return False
        spare = d - self.mu[close]
        until[close] = j + np.floor(np.maximum(spare, 0.0) / self.L[close]).astype(np.int64)
        if np.all(spare >= 0.0):
            return True
        # the bound of this very cell (the path's largest step's may be far larger)
        W, row = self.weights
        sides = (0.5 * (D[j - 1] + q), 0.5 * (q + D[j + 1]))   # the cell's ends
        Wc = W[row[close]]
        half = np.maximum(np.abs(sides[0] - q) @ Wc.T, np.abs(sides[1] - q) @ Wc.T)
        near = d < half + MARGIN_SLACK
        return not near.any() or all(
            _motion_free(exact, close[near], Wc[near], q, d[near], end, self.check_time)
            for end in sides)

    def _pairs_within(self, q: Array, todo: NDArray[np.int64]) -> NDArray[np.int64]:
        """``exact.pairs_within(q, self.look, todo)`` in parts of :data:`PAIRS_PER_CALL`, the
        deadline looked at before each."""
        parts = [todo[i:i + PAIRS_PER_CALL] for i in range(0, len(todo), PAIRS_PER_CALL)]
        close = [np.zeros(0, dtype=np.int64)]
        for part in parts:
            self.check_time()
            close.append(self.exact.pairs_within(q, self.look, part))
        return np.concatenate(close)


_GROUP_ROWS: dict[tuple[int, int], tuple[object, object, NDArray[np.bool_]]] = {}
"""(id(weights), id(spheres)) → (weights, spheres, incidence) for :func:`_group_rows`."""


def _group_rows(fast: FastChecker, exact: ExactChecker,
                weights: tuple[Array, NDArray[np.int64]]) -> NDArray[np.bool_]:
    """(G, U) bool: whether a collision pair of fast-checker group g's geometry (its first
    sphere's) has weight row u — so that a group's margin is the largest of its rows' margins,
    without going over the pairs (1000-1500 on the Baxter) in every decision. Kept per
    ``weights`` object (the exact checker makes a new one whenever its pairs change) and
    sphere model."""
    key = (id(weights), id(fast.spheres))
    kept = _GROUP_ROWS.get(key)
    if kept is not None and kept[0] is weights and kept[1] is fast.spheres:
        return kept[2]
    W, row = weights
    pairs = exact.collision_pairs
    touches = np.zeros((exact.geom_model.ngeoms, len(W)), dtype=bool)
    touches[pairs[:, 0], row] = True
    touches[pairs[:, 1], row] = True
    if len(_GROUP_ROWS) >= 16:
        _GROUP_ROWS.clear()
    group_rows = touches[fast.spheres.geometries[fast.packed.groups.start[:-1]]]
    _GROUP_ROWS[key] = (weights, fast.spheres, group_rows)
    return group_rows


def _motion_free(exact: ExactChecker, pairs: NDArray[np.int64], Wc: Array, qa: Array,
                 da: Array, qb: Array, check_time: Callable[[], None]) -> bool:
    """Whether the collision pairs ``pairs`` (C,) stay apart along the straight motion
    qa → qb (K,) rad, given their coal distances da (C,) m at qa; Wc (C, K) their motion
    weights (:attr:`ExactChecker.motion_weights`).

    A piece [a, b] is proved when d_a + d_b > L (both less :data:`MARGIN_SLACK`), L = |b - a|
    · W the motion bound of the piece: at a fraction t of the way the clearance is at least
    max(d_a - t L, d_b - (1 - t) L) ≥ (d_a + d_b - L) / 2. Unproved pieces are halved, with
    coal's distances at their midpoints, at most :data:`REFINE_POINTS` of them; a distance
    within the slack of contact ends the proof too (False). ``check_time`` is called before
    each coal query (it raises once the decision's deadline has passed)."""
    check_time()
    db = exact.pair_distances(qb, pairs)
    pieces = [(qa, da, qb, db)]
    points = 1
    while pieces:
        a, d0, b, d1 = pieces.pop()
        if np.all(d0 + d1 - 2 * MARGIN_SLACK > np.abs(b - a) @ Wc.T):
            continue
        if points >= REFINE_POINTS or d0.min() <= MARGIN_SLACK or d1.min() <= MARGIN_SLACK:
            return False
        c = 0.5 * (a + b)
        check_time()
        dc = exact.pair_distances(c, pairs)
        points += 1
        pieces += [(a, d0, c, dc), (c, dc, b, d1)]
    return True
