"""Self-collision pairs that collide in every configuration: MoveIt's "Always" rule.

Some URDFs model two links that are not adjacent in the kinematic tree with collision meshes
that overlap by design: TIAGo's first arm link sits inside its torso column's mesh, and its
wrist force-torque sensor inside the sixth arm link's, in every configuration. Checking such
a pair makes every configuration a collision (no roadmap, no plan), and an SRDF that disables
it is what MoveIt's setup assistant would write: it samples random configurations and
disables the pairs found in collision in (nearly) all of them ("Always"). Here a pair is
disabled only when it collides in *every* one of :data:`ALWAYS_SAMPLES` random configurations
(drawn uniformly within the joint limits, seeded): the test keeps only the pairs that have
collided so far, so after the first sample it costs a few coal calls a sample.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

ALWAYS_SAMPLES = 1000
"""Random configurations a self-collision pair must collide in, every one, to be disabled."""
ALWAYS_SEED = 0
"""Seed of those configurations: the same robot gets the same pairs."""


def always_colliding(model: pin.Model, collision_model: pin.GeometryModel,
                     pairs: Sequence[tuple[int, int]], lower: NDArray[np.float64],
                     upper: NDArray[np.float64], samples: int = ALWAYS_SAMPLES
                     ) -> tuple[tuple[int, int], ...]:
    """The geometry pairs of ``pairs`` (indices into ``collision_model``) that coal finds in
    collision in every one of ``samples`` configurations drawn uniformly in [lower, upper]
    (K,) rad (seed :data:`ALWAYS_SEED`); ``collision_model`` is left as it is."""
    if not pairs:
        return ()
    gm = pin.GeometryModel()
    for g in collision_model.geometryObjects:
        gm.addGeometryObject(g)
    for i, j in pairs:
        gm.addCollisionPair(pin.CollisionPair(int(i), int(j)))
    gd = pin.GeometryData(gm)
    data = model.createData()
    rng = np.random.default_rng(ALWAYS_SEED)
    alive = list(range(len(pairs)))
    for q in rng.uniform(lower, upper, size=(samples, len(lower))):
        pin.updateGeometryPlacements(model, data, gm, gd, q)
        alive = [k for k in alive if pin.computeCollision(gm, gd, k)]
        if not alive:
            return ()
    return tuple((int(pairs[k][0]), int(pairs[k][1])) for k in alive)
