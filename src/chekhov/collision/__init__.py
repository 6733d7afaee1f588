"""Collision checking: a fast sphere checker for planning, an exact one for validation."""
