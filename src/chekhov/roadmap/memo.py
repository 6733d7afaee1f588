"""Answers kept while the world's obstacles stay as they are."""

from __future__ import annotations

from collections.abc import Hashable
from typing import Generic, TypeVar

from chekhov.collision.fast import FastChecker

V = TypeVar("V")


class ObstacleMemo(Generic[V]):
    """Answers that are a function of their key and of ``fast``'s obstacles, kept until the
    obstacles change (``FastChecker.obstacles_version``): all are dropped then, and when
    ``capacity`` are kept and another comes. The caller decides what may be kept (e.g. only
    an answer completed before its deadline)."""

    def __init__(self, fast: FastChecker, capacity: int) -> None:
        self.fast = fast
        self.capacity = capacity
        self._kept: dict[Hashable, V] = {}
        self._version = fast.obstacles_version

    def _current(self) -> dict[Hashable, V]:
        if self.fast.obstacles_version != self._version:
            self._kept, self._version = {}, self.fast.obstacles_version
        return self._kept

    def get(self, key: Hashable) -> V | None:
        """The answer kept for ``key`` in the world as it is now, or None."""
        return self._current().get(key)

    def put(self, key: Hashable, value: V) -> None:
        kept = self._current()
        if len(kept) >= self.capacity:
            kept.clear()
        kept[key] = value

    def clear(self) -> None:
        self._kept.clear()
