"""Scenes with semantics: primitives, poses, classes, grasps, articulations, regions."""
