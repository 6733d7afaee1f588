"""Drawing one case (private; import from :mod:`chekhov.cases`).

This module holds what both case families draw with: :func:`case_rng` (the random stream of
case ``index`` and its replacements), :func:`sample_free` (collision-free configurations,
uniform within the joint limits), :func:`sample_case` (a case of the random family) and
:class:`DrawnCase` (one case as drawn, of either family).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from chekhov.errors import ChekhovError
from chekhov.world import World

Array = NDArray[np.float64]


# --- generation -------------------------------------------------------------------------
def sample_free(world: World, rng: np.random.Generator, n: int, batch: int = 16,
                max_draws: int = 1_000_000) -> Array:
    """n configurations (n, K), uniform within the joint limits, collision-free by both
    checkers (fast first, in batches, then exact). Deterministic for the generator's state."""
    out: list[Array] = []
    drawn = 0
    while len(out) < n:
        if drawn >= max_draws:
            raise ChekhovError(f"scene '{world.scene.name}': only {len(out)} collision-free "
                               f"configurations in {drawn} uniform samples")
        Q = world.robot.sample_uniform(rng, batch)
        drawn += batch
        for q in Q[world.fast.valid(Q)]:
            if world.exact.is_valid(q):
                out.append(q)
                if len(out) == n:
                    break
    return np.array(out).reshape(n, world.robot.dof)


def case_rng(seed: int, index: int, attempt: int = 0) -> np.random.Generator:
    """The random stream of case ``index`` (attempt > 0: its replacements)."""
    key = [int(seed), int(index)] + ([int(attempt)] if attempt else [])
    return np.random.default_rng(key)


def sample_case(world: World, seed: int, index: int, attempt: int = 0) -> tuple[Array, Array]:
    """(q_start, q_goal) of case ``index``, replacement ``attempt`` (0: the original)."""
    Q = sample_free(world, case_rng(seed, index, attempt), 2)
    return Q[0], Q[1]


@dataclass(frozen=True, eq=False)
class DrawnCase:
    """One case as drawn: configurations (K,) rad, poses (4, 4) m, labels ("" for random)."""

    q_start: Array
    q_goal: Array
    T_start: Array
    T_goal: Array
    start_label: str = ""
    goal_label: str = ""
