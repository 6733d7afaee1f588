"""Checks of a frozen config's fields (private), for its ``__post_init__``: each raises
:class:`~chekhov.errors.ChekhovError` as ``"Owner.field: must be …, got value"``, so a bad
setting is named where it was given."""

from __future__ import annotations

from chekhov.errors import ChekhovError


def int_at_least(owner: str, name: str, value: object, least: int) -> None:
    """``value`` is an ``int`` ≥ ``least``."""
    if not (isinstance(value, int) and value >= least):
        raise ChekhovError(f"{owner}.{name}: must be an integer >= {least}, got {value!r}")


def in_unit_interval(owner: str, name: str, value: float) -> None:
    """``value`` lies in (0, 1]."""
    if not 0 < value <= 1:
        raise ChekhovError(f"{owner}.{name}: must be in (0, 1], got {value!r}")


def positive(owner: str, name: str, value: float) -> None:
    """``value`` > 0."""
    if not value > 0:
        raise ChekhovError(f"{owner}.{name}: must be > 0, got {value!r}")
