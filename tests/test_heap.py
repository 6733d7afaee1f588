"""The warm-ups take the long-lived heap out of the garbage collector's way (chekhov._heap)."""

import gc
import weakref

from chekhov._heap import settle_heap
from chekhov.execute.executor import Executor
from chekhov.execute.worker import InlineWorker
from chekhov.planners.trajopt_planner import TrajOptPlanner
from chekhov.robot.goal import Goal
from chekhov.timing import TimingConfig


class _Node:
    def __init__(self) -> None:
        self.me = self                # a cycle: only the cyclic collector frees it


def test_settle_heap_collects_the_garbage_then_freezes_what_is_alive():
    gc.unfreeze()
    garbage = _Node()
    dead = weakref.ref(garbage)
    kept = _Node()
    alive = weakref.ref(kept)
    del garbage
    before = gc.get_freeze_count()
    settle_heap()
    assert dead() is None                         # collected, not frozen
    assert alive() is kept                        # frozen with the rest of what is alive
    assert gc.get_freeze_count() > before
    del kept
    assert gc.collect() == 0 and alive() is not None   # frozen: the collector skips it
    gc.unfreeze()
    gc.collect()
    assert alive() is None                        # unfrozen, it is collected again


def test_planner_and_executor_warmups_settle_the_heap(world_of, monkeypatch):
    """Both warm-ups end by freezing the heap: a full collection over a loaded world took
    33-53 ms, inside whichever timed call crossed the collector's threshold."""
    calls = []
    import chekhov.execute.executor as executor_module
    import chekhov.planners.base as base_module

    monkeypatch.setattr(base_module, "settle_heap", lambda: calls.append("planner"))
    monkeypatch.setattr(executor_module, "settle_heap", lambda: calls.append("executor"))
    world = world_of("tabletop_pole")
    planner = TrajOptPlanner(world)
    planner.warmup(time_limit_s=0.05)
    assert calls == ["planner"]
    goal = Goal.configuration(0.5 * (world.robot.lower + world.robot.upper))
    Executor(world, InlineWorker(world, planner, TimingConfig()), goal).warmup()
    assert calls == ["planner", "executor"]
