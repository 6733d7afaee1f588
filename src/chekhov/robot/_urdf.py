"""What chekhov reads from a URDF's text besides pinocchio's model: continuous joints made
bounded revolute ones, and which links are adjacent."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

from chekhov.errors import RobotError


def read_urdf(urdf: Path, robot: str) -> ET.Element:
    """The URDF's root element; a located error when it cannot be read."""
    try:
        return ET.parse(urdf).getroot()
    except (ET.ParseError, OSError) as e:
        raise RobotError(f"robot '{robot}': cannot read {urdf}: {e}") from e


CONTINUOUS_RANGE_RAD = (-math.pi, math.pi)
"""rad: the range a continuous joint is planned over when its URDF gives it no position limits
(MoveIt's bounds for one)."""


def bounded_continuous(root: ET.Element) -> list[str] | None:
    """Make every ``continuous`` joint of the URDF ``root`` a ``revolute`` one, in place: the
    names of those that had no ``<limit>`` (their velocity and effort limits are to be made
    infinite, as pinocchio makes them), or None when there was none to change (the file is
    then loaded as it is).

    The planners work in a bounded, flat joint space: a continuous joint (pinocchio: two
    coordinates, cos and sin) is planned as a revolute joint over the ``lower`` / ``upper`` its
    ``<limit>`` gives (Kinova's URDFs give ±2π), else :data:`CONTINUOUS_RANGE_RAD`; its
    velocity and effort limits stay. Motions do not wrap around: a move from 3 to -3 rad goes
    back through 0 (state a goal in the branch you want)."""
    joints = [j for j in root.findall("joint") if j.get("type") == "continuous"]
    if not joints:
        return None
    unlimited = []
    for joint in joints:
        joint.set("type", "revolute")
        limit = joint.find("limit")
        if limit is None:   # urdfdom wants numbers: set to inf once the model is built
            limit = ET.SubElement(joint, "limit", {"effort": "0", "velocity": "0"})
            unlimited.append(str(joint.get("name")))
        lower, upper = (_float_or_none(limit.get(k)) for k in ("lower", "upper"))
        if lower is None or upper is None or not lower < upper:
            lower, upper = CONTINUOUS_RANGE_RAD
        limit.set("lower", repr(lower))
        limit.set("upper", repr(upper))
    return unlimited


def rename_shadowing_joints(root: ET.Element, keep: set[str]) -> bool:
    """Rename, in place, each joint of the URDF ``root`` that has a link's name and is not in
    ``keep`` (the joints a description names), to ``<name>__joint``; True when one was.
    pinocchio refuses to lock such a joint (its frame and the link's share the name: the SO-100
    arm's "gripper"); a joint outside the group is locked, never looked up by name again."""
    links = {link.get("name") for link in root.findall("link")}
    taken = links | {j.get("name") for j in root.findall("joint")}
    renamed = False
    for joint in root.findall("joint"):
        name = joint.get("name")
        if name in links and name not in keep:
            new = f"{name}__joint"
            while new in taken:
                new += "_"
            joint.set("name", new)
            taken.add(new)
            renamed = True
    return renamed


def _float_or_none(text: str | None) -> float | None:
    try:
        x = float(text) if text is not None else None
    except ValueError:
        return None
    return x if x is not None and math.isfinite(x) else None


def adjacent_links(root: ET.Element) -> frozenset[frozenset[str]]:
    """Pairs of links whose self-collision is never checked, as MoveIt's setup assistant
    disables them ("Adjacent"): a link with collision geometry and its nearest ancestor with
    collision geometry (joined by one joint, or through links without any). Their meshes meet
    at the joint, so such a pair would collide in every configuration (a Kinova Jaco's URDF
    ships no SRDF entries for them)."""
    parent = {}
    for j in root.findall("joint"):
        p, c = j.find("parent"), j.find("child")
        if p is not None and c is not None:
            parent[str(c.get("link"))] = str(p.get("link"))
    solid = {str(link.get("name")) for link in root.findall("link")
             if link.find("collision") is not None}
    pairs = set()
    for link in solid:
        up = parent.get(link)
        while up is not None and up not in solid:
            up = parent.get(up)
        if up is not None:
            pairs.add(frozenset((link, up)))
    return frozenset(pairs)
