"""The integer codes and sentinel values of the collision layer, in one place.

Every compiled kernel and every Python caller imports these names rather than spelling the
numbers (numba reads module-level integers as compile-time constants, so a name costs nothing
in compiled code). Values that are stored (the roadmap's validity arrays) keep their numbers.
"""

from __future__ import annotations

# --- shape kinds: ``Primitive.kind`` and every packed ``kind`` array ---------------------
SPHERE = 0
"""A sphere: size (radius, 0, 0)."""
BOX = 1
"""A box: size = its half extents."""
CYLINDER = 2
"""A cylinder along its z axis: size (radius, half length, 0)."""
HULL = 3
"""A convex polytope given by support points (``gjk``): a mesh part, or a box around one."""
NO_GEOMETRY = -1
"""A sphere group whose covered geometry is none of the above: its sphere hits are collisions."""

# --- sources: what a sphere or group is tested against ----------------------------------
STATIC = 0
"""A static scene obstacle (index into ``PackedWorld.static``)."""
DYNAMIC = 1
"""A dynamic scene obstacle (index into ``PackedWorld.dynamic``)."""
FIXED = 2
"""A fixed robot part (index into ``PackedWorld.fixed``)."""
SELF = 3
"""Another sphere (contacts, distance terms) or sphere group (validity) of the robot."""
OBSTACLE = 4
"""Any scene obstacle, static or dynamic (index into ``PackedWorld.obstacles``, the order of
``FastChecker.obstacle_names``)."""

# --- validity states ------------------------------------------------------------------
UNKNOWN = -1
"""Not decided (yet): a grid that proves nothing there, a roadmap node or edge not checked."""
INVALID = 0
"""Colliding: certainly, for a grid lookup."""
VALID = 1
"""Free: proved, for a grid lookup."""

# --- sentinels ------------------------------------------------------------------------
NONE = -1
"""No index: no such grid, no colliding configuration, a parent joint that is the world."""
GRID_SATURATED = 255
"""Stored grid value meaning "at least ``grid.CAP`` away" (the uint8 maximum)."""
NO_TERM = 1e3
"""Distance (m) written to an unused distance-term slot: the optimiser's hinge is zero there."""
