"""What a robot is for chekhov: URDF source, planning group, end effector, fixed joints, base."""

from __future__ import annotations

import sys
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from chekhov.errors import RobotError


@dataclass(frozen=True)
class SphereSettings:
    """How the fast checker's sphere model is generated from the URDF collision geometry.

    Attributes:
        max_excess: largest allowed relative radius excess of a covering sphere over the
            cylinder / box cross-section it covers (0.15 = spheres at most 15 % fatter).
        padding: metres added to every sphere radius, so rounding never lets a sphere
            under-cover its geometry.
        mesh_spheres: spheres used to cover one collision mesh (k-means on its triangles).
        mesh_split: before the clustering, a mesh's triangles are cut in halves until every
            edge is at most this fraction of the mesh's bounding-box diagonal (0: not cut), so
            that a cluster is a patch of surface rather than a few long triangles spanning the
            link (``spheres.split_triangles``).
    """

    max_excess: float = 0.15
    padding: float = 0.002
    mesh_spheres: int = 12
    mesh_split: float = 1.0 / 32.0

    def __post_init__(self) -> None:
        """A :class:`RobotError` naming the first setting out of its range."""
        if isinstance(self.mesh_spheres, bool) or not isinstance(self.mesh_spheres, int) \
                or self.mesh_spheres < 1:
            raise RobotError(f"'mesh_spheres' must be an integer >= 1, got "
                             f"{self.mesh_spheres!r}")
        for key, low, need in (("max_excess", None, "a finite number > 0"),
                               ("padding", 0.0, "a finite number >= 0"),
                               ("mesh_split", 0.0, "a finite number >= 0")):
            v = getattr(self, key)
            number = isinstance(v, int | float) and not isinstance(v, bool)
            if not (number and abs(v) < float("inf") and (v > 0 if low is None else v >= low)):
                raise RobotError(f"'{key}' must be {need}, got {v!r}")


def _sphere_settings(d: object, where: str) -> SphereSettings:
    """The :class:`SphereSettings` of a description file's ``spheres`` mapping; a located
    :class:`RobotError` (``where``: the file and field) for an unknown key or a bad value."""
    if not isinstance(d, dict):
        raise RobotError(f"{where}: expected a mapping of sphere settings, got {d!r}")
    known = sorted(SphereSettings.__dataclass_fields__)
    unknown = sorted(set(map(str, d)) - set(known))
    if unknown:
        raise RobotError(f"{where}: unknown key(s) {unknown}; known: {known}")
    try:
        return SphereSettings(**d)
    except RobotError as e:
        raise RobotError(f"{where}: {e}") from None


@dataclass(frozen=True)
class RobotDescription:
    """A robot and its planning group.

    Attributes:
        name: short name, e.g. ``baxter_left``.
        urdf: URDF path, absolute or relative to the ``example-robot-data`` share folder.
        srdf: SRDF path (same rules) whose ``disable_collisions`` entries prune self-collision
            pairs, or ``None``.
        group_joints: the planned joints, in the order of every configuration vector.
        ee_frame: the end-effector frame (its z axis is the approach direction).
        fixed_joints: value (rad or m) of every joint outside the group; unnamed ones are 0.
        xyz_world_base, rpy_world_base: default base pose in the world (m, rad); a scene may
            override it.
        proximal_joints: how many leading group joints the roadmap samples (the rest stay at
            ``roadmap_fixed`` values).
        roadmap_fixed: values (rad) of the distal group joints for roadmap nodes.
        package_dirs: folders that ``package://`` mesh URIs resolve against (besides
            example-robot-data's).
    """

    name: str
    urdf: str
    srdf: str | None
    group_joints: tuple[str, ...]
    ee_frame: str
    fixed_joints: tuple[tuple[str, float], ...] = ()
    xyz_world_base: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy_world_base: tuple[float, float, float] = (0.0, 0.0, 0.0)
    proximal_joints: int = 4
    roadmap_fixed: tuple[float, ...] = ()
    spheres: SphereSettings = field(default_factory=SphereSettings)
    package_dirs: tuple[str, ...] = ()

    def with_locked(self, locked: dict[str, float]) -> RobotDescription:
        """This description with some locked (non-group) joints at other values (rad or m)."""
        if not locked:
            return self
        clash = sorted(set(locked) & set(self.group_joints))
        if clash:
            raise RobotError(f"robot '{self.name}': cannot lock planned joints {clash}")
        values = dict(self.fixed_joints)
        for name, value in locked.items():
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or value != value or abs(value) == float("inf"):
                raise RobotError(f"robot '{self.name}': locked joint '{name}': expected a "
                                 f"finite number, got {value!r}")
            values[str(name)] = float(value)
        return replace(self, fixed_joints=tuple(sorted(values.items())))

    @property
    def dof(self) -> int:
        return len(self.group_joints)

    def resolve(self, path: str) -> Path:
        """Absolute path of a URDF/SRDF entry."""
        p = Path(path)
        return p if p.is_absolute() else example_robot_data_dir() / p

    @classmethod
    def from_dict(cls, d: dict[str, Any], source: str = "<dict>") -> RobotDescription:
        known = {f for f in cls.__dataclass_fields__}
        unknown = set(d) - known
        if unknown:
            raise RobotError(
                f"{source}: unknown field(s) {sorted(unknown)}; known: {sorted(known)}")
        for req in ("name", "urdf", "group_joints", "ee_frame"):
            if req not in d:
                raise RobotError(f"{source}: missing field '{req}'")
        kw = dict(d)
        kw["group_joints"] = tuple(str(j) for j in d["group_joints"])
        kw["fixed_joints"] = tuple((str(k), float(v)) for k, v in d.get("fixed_joints", {}).items())
        for key in ("xyz_world_base", "rpy_world_base"):
            if key in d:
                v = d[key]
                if not (isinstance(v, list | tuple) and len(v) == 3):
                    raise RobotError(f"{source}: field '{key}' must be 3 numbers, got {v!r}")
                kw[key] = tuple(float(x) for x in v)
        kw["roadmap_fixed"] = tuple(float(x) for x in d.get("roadmap_fixed", ()))
        kw["spheres"] = _sphere_settings(d.get("spheres", {}), f"{source}: field 'spheres'")
        kw.setdefault("srdf", None)
        kw["package_dirs"] = tuple(str(x) for x in d.get("package_dirs", ()))
        desc = cls(**kw)
        n_distal = desc.dof - desc.proximal_joints
        if desc.roadmap_fixed and len(desc.roadmap_fixed) != n_distal:
            raise RobotError(
                f"{source}: roadmap_fixed has {len(desc.roadmap_fixed)} values, "
                f"expected {n_distal} (dof {desc.dof} - proximal_joints {desc.proximal_joints})"
            )
        return desc

    @classmethod
    def from_yaml(cls, path: str | Path) -> RobotDescription:
        """A description file. Its relative ``urdf``, ``srdf`` and ``package_dirs`` entries
        are taken from the file's folder when they exist there, else (as the built-in ones)
        from the ``example-robot-data`` share folder."""
        path = Path(path)
        try:
            d = yaml.safe_load(path.read_text())
        except (OSError, yaml.YAMLError) as e:
            raise RobotError(f"{path}: cannot read robot description: {e}") from e
        if not isinstance(d, dict):
            raise RobotError(f"{path}: expected a mapping at top level")
        return cls.from_dict(_beside(d, path.expanduser().resolve().parent), source=str(path))

    @classmethod
    def builtin(cls, name: str) -> RobotDescription:
        """A description shipped with chekhov (``baxter_left``, ``panda``)."""
        names = builtin_robots()
        if name not in names:  # never a path: "../x" must not reach outside the package
            raise RobotError(f"no built-in robot {name!r}; available: {names}")
        return cls.from_yaml(Path(str(resources.files("chekhov.robot") / "data" / f"{name}.yaml")))


def _beside(d: dict[str, Any], folder: Path) -> dict[str, Any]:
    """``d`` with its relative file entries made absolute where they exist in ``folder``."""
    def here(p: Any) -> Any:
        if isinstance(p, str) and not Path(p).is_absolute() and (folder / p).exists():
            return str(folder / p)
        return p
    out = dict(d)
    for key in ("urdf", "srdf"):
        if key in out:
            out[key] = here(out[key])
    if isinstance(out.get("package_dirs"), list):
        out["package_dirs"] = [here(p) for p in out["package_dirs"]]
    return out


def builtin_robots() -> list[str]:
    """Names of the robot descriptions shipped with chekhov."""
    files = resources.files("chekhov.robot") / "data"
    return sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".yaml"))


def example_robot_data_dir() -> Path:
    """The ``share/example-robot-data`` folder of the installed PyPI package."""
    for entry in sys.path:
        p = Path(entry) / "cmeel.prefix" / "share" / "example-robot-data"
        if p.is_dir():
            return p
    raise RobotError(
        "the example-robot-data package is not installed (pip install example-robot-data)"
    )
