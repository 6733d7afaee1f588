"""Roadmap errors."""

from __future__ import annotations

from chekhov.errors import ChekhovError


class RoadmapError(ChekhovError):
    """A roadmap cannot be built, loaded or queried (the message says which file and why)."""


class RoadmapMismatchError(RoadmapError):
    """A roadmap file belongs to another scene, robot or format version than asked for."""
