"""One planning call of an anytime planner: its stage reports, timing, and the certified
answers it offers as it goes (:class:`AnytimeRun`).

A stage that produces a path offers it; the offer is certified by the same function that
certifies every planner's answer (:func:`~chekhov.planners.certify.check_path`: start, joint
limits, goal tolerance, exact check at 100 substeps — a fast-free path with a conservative
sphere model needs no coal call), and when it passes and is shorter than the best so far it
becomes the answer: the caller's ``on_solution`` hears of it at once, and the result lists
every solution with the time it came.

Every certification must end by :data:`FINAL_CHECK_RESERVE_S` before the time limit, so that
the final check of the answer fits before it too: an answer that passed later would come back
after the limit. The first offer is always certified at once (it is the answer to fall back
on). When nobody listens (no ``on_solution``), a later offer without a certificate of its own
waits as the candidate instead, and the candidates still standing at the end are certified
shortest first until one passes: an intermediate path that a later stage beats is checked only
when every shorter one fails (the exact check is the largest cost of an improvement; measured:
29% of Roadmap + TrajOpt's time on the shelf), and a shorter candidate that fails does not
cost the answer the longer one it displaced. A planner may bound the certification of
improvements (:meth:`AnytimeRun.certify_improvements_by`): once there is an answer, an offer
that cannot be decided by then is dropped.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.path_check import PathCertificate
from chekhov.paths import path_length
from chekhov.planners.certify import check_path
from chekhov.planners.result import PlanResult, Solution
from chekhov.planners.status import PlanStatus, Stage, StageReport

if TYPE_CHECKING:
    from chekhov.planners.query import PlanQuery
    from chekhov.world import World

Array = NDArray[np.float64]

FINAL_CHECK_RESERVE_S = 5e-4
"""s: every offer is certified by this long before the time limit, so that the final check of
the answer fits before it (``certify`` with the offer's certificate, which names the path it
resampled: in ``plan()`` at a 20 ms limit 0.12 ms median, 0.22 p95, 0.32 max on the kitchen,
100 cases)."""


class _Candidate(NamedTuple):
    """An offer waiting for its certification: the path (T, K) rad, the stage that found it,
    its seed, its info and its length (rad)."""

    path: Array
    stage: Stage
    seed: Array | None
    info: dict[str, object]
    length: float


class AnytimeRun:
    """One call's query, timing breakdown (s), stage reports and certified solutions."""

    def __init__(self, world: World, query: PlanQuery) -> None:
        self.world = world
        self.query = query
        self.timing: dict[str, float] = {}
        self.stages: list[StageReport] = []
        self.solutions: list[Solution] = []
        self.best_certificate: PathCertificate | None = None
        self.best_seed: Array | None = None
        self.best_info: dict[str, object] = {}
        self.rejected: list[tuple[Stage, PlanStatus, str]] = []
        # paths (T, K) shortcut to the end in this query, by their bytes: the shortcut
        self.shortcuts: dict[bytes, Array] = {}
        self._candidates: list[_Candidate] = []
        # the query the offers are certified for (module docstring)
        self._offer_query = replace(query, time_limit_s=query.time_limit_s
                                    - FINAL_CHECK_RESERVE_S)
        self._improvement_query = self._offer_query

    def certify_improvements_by(self, deadline: float) -> None:
        """Once there is an answer, certify offers by ``deadline`` (``time.perf_counter()``
        value, s; never later than the offers' own): an improvement whose check takes longer
        is dropped, and the answer stands. (An xArm7's shortcut candidate passing near
        contact along half its length took coal 2 s to decide — the whole time limit.)"""
        limit = min(deadline, self._offer_query.deadline) - self.query.t0
        self._improvement_query = replace(self._offer_query, time_limit_s=limit)

    def _check_query(self) -> PlanQuery:
        """The query an offer is certified for now (:meth:`certify_improvements_by`)."""
        return self._improvement_query if self.solutions else self._offer_query

    @property
    def best(self) -> Solution | None:
        return self.solutions[-1] if self.solutions else None

    def report(self, stage: Stage, status: PlanStatus, time_s: float,
               path: Array | None = None, detail: dict[str, object] | None = None) -> None:
        self.stages.append(StageReport(stage, status, time_s, path, detail or {}))

    def offer(self, path: Array, stage: Stage, *, seed: Array | None = None,
              certificate: PathCertificate | None = None,
              info: dict[str, object] | None = None) -> bool:
        """Offer ``path`` (T, K): when it is shorter than the best so far, certify it and make
        it the answer (telling ``on_solution``) — or, unheard and uncertified, keep it as the
        candidate to certify at the end (module docstring). True when it became the answer
        or the candidate."""
        length = path_length(path)
        if length >= self._shortest() - 1e-9:
            return False
        if self.solutions and certificate is None and self.query.on_solution is None:
            self._candidates.append(_Candidate(np.asarray(path), stage, seed, dict(info or {}),
                                               length))
            return True
        if not self._certify(path, stage, seed, certificate, info, length):
            return False
        self._candidates = []   # longer than the new answer
        return True

    @property
    def offer_deadline(self) -> float:
        """``time.perf_counter()`` value (s) by which an offer's certification must end."""
        return self._offer_query.deadline

    @property
    def shortest_rad(self) -> float:
        """rad: the length an offer must beat (inf: none yet)."""
        return self._shortest()

    def _shortest(self) -> float:
        """rad: the shortest of the best solution and the waiting candidates (inf: none)."""
        best = self.best
        lengths = [best.length_rad] if best is not None else []
        lengths += [c.length for c in self._candidates]
        return min(lengths, default=float("inf"))

    def _certify(self, path: Array, stage: Stage, seed: Array | None,
                 certificate: PathCertificate | None, info: dict[str, object] | None,
                 length: float) -> bool:
        """Certify ``path`` by :data:`FINAL_CHECK_RESERVE_S` before the deadline and make it
        the answer when it passes."""
        t = time.perf_counter()
        query = self._check_query()
        why, certificate = check_path(self.world, query, path, certificate)
        self.timing["offers"] = self.timing.get("offers", 0.0) + time.perf_counter() - t
        if why is None and query.expired():   # its last step ran past the time
            why = (PlanStatus.TIMEOUT, "certified after the offers' deadline")
        if why is not None:
            self.rejected.append((stage, why[0], why[1]))
            return False
        found = Solution(np.asarray(path), time.perf_counter() - self.query.t0, stage, length)
        self.solutions.append(found)
        self.best_certificate, self.best_seed = certificate, seed
        self.best_info.update(info or {})
        if self.query.on_solution is not None:
            self.query.on_solution(found)
        return True

    def result(self, failure: PlanStatus, info: dict[str, object] | None = None,
               seed_from: Stage | None = None) -> PlanResult:
        """The best solution as a success, else a failure with status ``failure`` — or, when
        ``failure`` says SOLVED because a stage found paths that all failed their
        certification, the first failed check's status (the waiting candidates are certified
        first, shortest first, until one passes; none once the offers' deadline has passed)."""
        waiting, self._candidates = sorted(self._candidates, key=lambda c: c.length), []
        for c in waiting:
            if self._check_query().expired():   # a certification would fail ("timeout")
                self.rejected.append((c.stage, PlanStatus.TIMEOUT,
                                      "not certified: its deadline had passed"))
                continue
            if self._certify(c.path, c.stage, c.seed, None, c.info, c.length):
                break
        info = {**(info or {}), **self.best_info}
        if self.rejected:
            info["rejected_offers"] = "; ".join(f"{stage}: {status.value}: {why}"
                                                for stage, status, why in self.rejected)
        best = self.best
        elapsed = time.perf_counter() - self.query.t0
        if best is None:
            if failure is PlanStatus.SOLVED:
                failure = self.rejected[0][1] if self.rejected else PlanStatus.INFEASIBLE
            return PlanResult(False, None, failure, elapsed, self.timing, info=info,
                              stages=tuple(self.stages), seed_from=seed_from)
        return PlanResult(True, best.path, PlanStatus.SOLVED, elapsed, self.timing,
                          seed=self.best_seed, info=info, certificate=self.best_certificate,
                          stages=tuple(self.stages), seed_from=seed_from,
                          solutions=tuple(self.solutions))
