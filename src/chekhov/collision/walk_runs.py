"""How the dense walk (:mod:`chekhov.collision.dense_path`) goes along a path: several short
segments as one run (:func:`run_end`), and how many configurations one compiled call may look
at before its deadline (:func:`visit_budget`).

A timed trajectory's arcs are polylines of short segments (5-10 configurations each at the
check's step), whose certificates would outlive every segment: there the walk takes several
consecutive, similar segments as one run (:func:`run_end`) and counts its certificates in
substeps of the run's largest joint steps — the walk's motion bounds (:mod:`dense_path`'s
certificates) need no more of a substep than that each joint turns by at most δq_i, so they
hold across the run's knots. On the arcs of 40 shelf_boxes task answers this took the exact
check 0.48 → 0.29 ms a run of arcs (A/B in alternating processes, twice); on the
certification's long segments runs are not formed.
"""

from __future__ import annotations

from numba import njit

from chekhov.collision.validity import NO_BUDGET

RUN_SLACK = 1.5
"""How much a run of segments (:func:`run_end`) may raise the per-substep joint bound that
its certificates count in over that of its shortest segment (joint steps summed)."""
RUN_SAMPLES = 64
"""The most configurations a run of segments (:func:`run_end`) may hold (n a segment)."""


@njit(cache=True, nogil=True)
def run_end(P, t0, last, n, span):  # pragma: no cover - compiled
    """t1 > t0: the segments t0 … t1 - 1 of P (T, K), n configurations a segment, that the
    walk takes as one run, t1 ≤ ``last``. Within a run certificates outlive the segments,
    but they run out one at a time, each costing a configuration looked at, where at a
    run's start they are all renewed by one; so a run joins short segments only — a timed
    trajectory's knots along an arc, 5-10 configurations a segment, whose certificates
    outlive several — at most :data:`RUN_SAMPLES` configurations, and while the sum over
    the joints of the run's largest steps max_t |P[t + 1, i] - P[t, i]| (rad) stays within
    :data:`RUN_SLACK` times the shortest segment's summed joint steps. (Runs without the
    cap, on the certification's 101-configuration segments: 2-3 times the configurations
    looked at, and no faster.) ``span`` (K,): work space."""
    K = P.shape[1]
    shortest = 0.0
    for i in range(K):
        span[i] = abs(P[t0 + 1, i] - P[t0, i])
        shortest += span[i]
    t = t0 + 1
    while t < last and (t + 1 - t0) * n <= RUN_SAMPLES:
        total = 0.0
        own = 0.0
        for i in range(K):
            d = abs(P[t + 1, i] - P[t, i])
            own += d
            total += max(span[i], d)
        shortest = min(shortest, own)
        if total > RUN_SLACK * shortest:
            break
        for i in range(K):
            span[i] = max(span[i], abs(P[t + 1, i] - P[t, i]))
        t += 1
    return t


VISIT_COST_S = 5e-5
"""s: what the fast walk may take per configuration it looks at (one not covered by
certificates), for its budget (:func:`visit_budget`): measured 25-65 µs on the Panda near
contact with the certification's margins, where two segments of a path took up to 13 ms in one
call (a compiled call cannot look at the clock)."""
MIN_VISITS = 8
"""Configurations a walk's call may look at however near the deadline (each call sets up its
work arrays again and loses its certificates)."""


def visit_budget(left_s: float) -> int:
    """Configurations one call of the walk may look at with ``left_s`` (s) before its
    deadline: those that take half of it at :data:`VISIT_COST_S` each, at least
    :data:`MIN_VISITS`, so that the calls shrink as the deadline nears and the last overruns it
    by little (``NO_BUDGET`` when the deadline is far)."""
    if left_s >= NO_BUDGET * VISIT_COST_S:
        return NO_BUDGET
    return max(MIN_VISITS, int(0.5 * left_s / VISIT_COST_S))
