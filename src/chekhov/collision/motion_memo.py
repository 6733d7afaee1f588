"""Straight motions already decided in the world as it is: :class:`MotionMemo`.

A query asks about the same motion more than once: the routes to several goal IK solutions
share their start's connection and first nodes, so the greedy shortcuts of the routes stage
try the same jumps from the same waypoints. On 60 task cases a scene, 20% (shelf_boxes) and
17% (panda_cage) of the configurations the motion checks looked at were of motions checked
before in the same query. The fast checker's answer on a motion is a function of its ends,
its resolution, its clearance and the obstacles, so it is kept until the obstacles change.
"""

from __future__ import annotations

from typing import cast

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

MOTIONS_KEPT = 50_000
"""Decisions kept at most (about 200 bytes each for a 7-DOF arm); all are forgotten when it
is reached (a query looks at a few hundred)."""


class MotionMemo:
    """Free / blocked decisions of straight motions, by the check's resolution and clearance
    and the bytes of the motion's end configurations, for one ``obstacles_version`` of a fast
    checker."""

    def __init__(self, capacity: int = MOTIONS_KEPT) -> None:
        self.capacity = capacity
        self._version = -1
        self._kept: dict[tuple[float, float], dict[bytes, bool]] = {}
        self._size = 0
        self.hits = 0

    def lookup(self, Q0: Array, Q1: Array, resolution: float, clearance_m: float,
               version: int) -> tuple[list[bytes], NDArray[np.int8]]:
        """(keys, decisions) of the motions Q0[i] → Q1[i] (N, K) rad checked at
        ``resolution`` rad with ``clearance_m`` m: per motion 1 free, 0 blocked, -1 not
        decided yet. The memo is emptied first when ``version`` (the checker's
        ``obstacles_version``) is not the one it holds."""
        if version != self._version:
            self._kept.clear()
            self._size = 0
            self._version = version
        both = np.concatenate([Q0, Q1], axis=1)
        rows = both.view(np.dtype((np.void, both.shape[1] * both.itemsize))).ravel()
        keys = cast(list[bytes], rows.tolist())   # each row's bytes (7 µs for 20 motions)
        kept = self._kept.get((resolution, clearance_m), {})
        known = np.array([kept.get(k, -1) for k in keys], dtype=np.int8)
        self.hits += int((known >= 0).sum())
        return keys, known

    def store(self, resolution: float, clearance_m: float, keys: list[bytes],
              free: NDArray[np.bool_]) -> None:
        """Keep each key's decision (``free`` (len(keys),)), made at ``resolution`` and
        ``clearance_m`` in the version of the last :meth:`lookup`."""
        if self._size + len(keys) > self.capacity:
            self._kept.clear()
            self._size = 0
        kept = self._kept.setdefault((resolution, clearance_m), {})
        before = len(kept)
        kept.update(zip(keys, free.tolist(), strict=True))
        self._size += len(kept) - before
