"""How a planning call ended, and what each of its stages did: :class:`PlanStatus`,
:class:`Stage` and :class:`StageReport`.

The values are the strings stored in benchmark databases and printed in reports, so a
:class:`PlanStatus` compares equal to its string (``PlanStatus.SOLVED == "solved"``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


class PlanStatus(StrEnum):
    """Why ``plan()`` returned. Only ``SOLVED`` comes with a path.

    The query: ``INVALID_START`` / ``INVALID_GOAL`` (an end in collision), ``NO_IK`` (no
    collision-free IK solution of the goal pose). The search: ``NO_CONNECTION`` (the roadmap
    could not connect the start or goal), ``NO_PATH`` (dynamic obstacles cut every route; a
    node-bounded tree search, ``RRTConnect(deterministic)``, used up its nodes),
    ``INFEASIBLE`` (TrajOpt could not meet its constraints), ``ABANDONED`` (an improvement
    stage stopped early: it was not going to beat the answer so far), ``COLLISION`` (the
    answer failed the exact check), ``BAD_PROBLEM`` (the optimisation problem could not be built),
    ``TIMEOUT``. The certification refused the planner's answer (``planners/certify.py``):
    ``BAD_PATH``, ``START_MISMATCH``, ``JOINT_LIMITS``, ``GOAL_UNMET`` (and ``COLLISION``,
    ``TIMEOUT``)."""

    SOLVED = "solved"
    INVALID_START = "invalid_start"
    INVALID_GOAL = "invalid_goal"
    NO_IK = "no_ik"
    NO_CONNECTION = "no_connection"
    NO_PATH = "no_path"
    INFEASIBLE = "infeasible"
    ABANDONED = "abandoned"
    COLLISION = "collision"
    BAD_PROBLEM = "bad_problem"
    TIMEOUT = "timeout"
    BAD_PATH = "bad_path"
    START_MISMATCH = "start_mismatch"
    JOINT_LIMITS = "joint_limits"
    GOAL_UNMET = "goal_unmet"

    @classmethod
    def of(cls, value: str) -> PlanStatus:
        """The status named ``value``; a ValueError listing the known ones otherwise."""
        try:
            return cls(value)
        except ValueError:
            raise ValueError(f"unknown plan status {value!r}; known: "
                             f"{[s.value for s in cls]}") from None


class Stage(StrEnum):
    """A stage of a planning call."""

    IK = "ik"                          # goal configurations from a pose goal
    STRAIGHT_LINE = "straight_line"    # TrajOpt from a straight line (Roadmap + TrajOpt's try)
    ROADMAP_SEED = "roadmap_seed"      # routes through the roadmap
    SEED = "seed"                      # another planner's path (X + TrajOpt)
    SHORTCUT = "shortcut"
    ROUTES = "routes"                  # more roadmap routes (other goal IK solutions), shortcut
    SIMPLIFY = "simplify"              # shortcuts between any two points of the path
    OPTIMISE = "optimise"              # TrajOpt from the seed
    RETRY = "retry"                    # TrajOpt again towards the seed's end configuration
    REPAIR = "repair"                  # a tree into the roadmap when it could not answer
    FALLBACK = "fallback"              # bounded straight-line TrajOpt when the roadmap failed
    SEARCH = "search"                  # a sampling planner's search


@dataclass(frozen=True, eq=False)
class StageReport:
    """What one stage did.

    Attributes:
        stage: which. status: its outcome (``SOLVED`` when it produced what it was for).
        time_s: s, its wall time. path: (T, K) rad, what it produced (a seed, an optimised
        trajectory), when it did. detail: anything else (iterations, routes found …).
    """

    stage: Stage
    status: PlanStatus
    time_s: float
    path: Array | None = None
    detail: dict[str, object] = field(default_factory=dict)


def scalar_items(info: dict[str, object]) -> dict[str, object]:
    """The JSON-able entries of an ``info`` dict: scalars (NumPy ones as Python's), None, and
    flat dicts of scalars; arrays, paths and nested structures dropped."""
    out: dict[str, object] = {}
    for k, v in info.items():
        if isinstance(v, bool | int | float | str) or v is None:
            out[k] = v
        elif isinstance(v, np.generic):
            out[k] = v.item()
        elif isinstance(v, dict) and all(isinstance(x, int | float | str | bool)
                                         for x in v.values()):
            out[k] = {str(a): (b.item() if isinstance(b, np.generic) else b)
                      for a, b in v.items()}
    return out
