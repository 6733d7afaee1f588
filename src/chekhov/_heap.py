"""Keeping Python's cyclic garbage collector out of timed calls: :func:`settle_heap`.

A process that has loaded a world, a roadmap and the compiled kernels holds about 145,000
objects the collector tracks (numba's types and dispatchers, pinocchio's and coal's bindings,
the modules' functions). A full collection over them took 33-53 ms on this machine, and it
runs inside whatever call crosses the collector's threshold: three of them fell inside
``plan()`` calls of ``benchmarks/deadline.py`` (six scenes, 2,400 calls), one of which, with a
10 ms limit, returned 48 ms late. Those objects live as long as the process; frozen
(``gc.freeze``) they are no longer traversed, and a full collection takes well under 1 ms.
Objects made afterwards are collected as usual.
"""

from __future__ import annotations

import gc


def settle_heap() -> None:
    """Collect what is garbage now, then freeze everything still alive out of the cyclic
    collector's traversals (process-wide; idempotent). Called by the warm-ups
    (``PlannerBase.warmup``, ``Executor.warmup``, the bench workers') once the long-lived
    state is loaded: a later full collection then costs what the objects made since cost."""
    gc.collect()
    gc.freeze()
