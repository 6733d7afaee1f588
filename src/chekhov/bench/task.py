"""One benchmark run to do: a planner on one case of one scene."""

from __future__ import annotations

import hashlib
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class RunTask:
    """A planner on one case. Carries the case itself, so a worker (a process or a Ray actor
    on another machine) needs no case file.

    Attributes:
        scene: scene name (as given to ``World.load``).
        planner: registry name.
        case_index: index of the case in the scene's case set.
        q_start: (K,) start configuration, rad.
        T_world_ee_goal: (4, 4) goal end-effector pose in the world (m).
        time_limit_s: s, limit of the ``plan`` call.
        seed: per-run seed of the planner's random streams (reproducible wherever it runs).
        records_seed_run: for "X+TrajOpt": the seed stage of this run is also recorded as X's
            run on the case (X alone is the same planner, seeded the same way, so running it
            twice would only repeat the work; see ``BenchConfig.share_seed_runs``).
        family: the case family ("random" or "tasks"; :data:`chekhov.cases.FAMILIES`).
    """

    scene: str
    planner: str
    case_index: int
    q_start: Array
    T_world_ee_goal: Array
    time_limit_s: float
    seed: int
    records_seed_run: bool = False
    family: str = "random"

    @property
    def key(self) -> tuple[str, str, str, int]:
        return (self.scene, self.family, self.planner, self.case_index)

    @property
    def case_hash(self) -> str:
        """SHA-256 (hex, 16 chars) of the case's start and goal: ties a stored run to its case."""
        return case_hash(self.q_start, self.T_world_ee_goal)


def case_hash(q_start: Array, T_world_ee_goal: Array) -> str:
    """Short content hash of one case (start configuration and goal pose, float64 bytes)."""
    h = hashlib.sha256(np.ascontiguousarray(q_start, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(T_world_ee_goal, dtype=np.float64).tobytes())
    return h.hexdigest()[:16]


class TaskSource(Protocol):
    """Where an executor takes its tasks from, one at a time as a worker frees up (so that
    concurrent runners can claim runs as they start them; see :mod:`chekhov.bench.claims`)."""

    @property
    def exhausted(self) -> bool:
        """No task is left, now or later."""
        ...

    @property
    def left(self) -> int:
        """Tasks left to take, at most."""
        ...

    def take(self) -> RunTask | None:
        """The next task; None when none is available now (ask again later)."""
        ...

    def tick(self) -> None:
        """Called between results and while waiting (heartbeats)."""
        ...


class TaskList:
    """A fixed list of tasks as a :class:`TaskSource`."""

    def __init__(self, tasks: Sequence[RunTask]) -> None:
        self.tasks = deque(tasks)

    @property
    def exhausted(self) -> bool:
        return not self.tasks

    @property
    def left(self) -> int:
        return len(self.tasks)

    def take(self) -> RunTask | None:
        return self.tasks.popleft() if self.tasks else None

    def tick(self) -> None:
        pass
