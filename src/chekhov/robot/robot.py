"""The planning robot: a pinocchio model reduced to the planning group, expressed in the world."""

from __future__ import annotations

import hashlib
import logging
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from functools import cached_property
from pathlib import Path

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from chekhov.errors import RobotError
from chekhov.robot._urdf import (
    adjacent_links,
    bounded_continuous,
    read_urdf,
    rename_shadowing_joints,
)
from chekhov.robot.description import RobotDescription, SphereSettings, example_robot_data_dir
from chekhov.robot.self_pairs import ALWAYS_SAMPLES, always_colliding
from chekhov.transforms import make_transform, rpy_to_matrix

Array = NDArray[np.float64]
_log = logging.getLogger(__name__)
_AXES = {"RX": (1.0, 0.0, 0.0), "RY": (0.0, 1.0, 0.0), "RZ": (0.0, 0.0, 1.0)}


def joint_axis(joint: pin.JointModel) -> Array | None:
    """Unit rotation axis of a revolute joint in its own frame; None for any other joint (the
    one table of joint axes: the compiled kinematics and the exact checker's motion bounds)."""
    name = joint.shortname()
    if name.startswith("JointModelR") and name[-2:] in _AXES:
        return np.array(_AXES[name[-2:]], dtype=float)
    if name == "JointModelRevoluteUnaligned":
        ax = np.array(joint.extract().axis, dtype=float)
        return ax / np.linalg.norm(ax)
    return None


class Robot:
    """A robot reduced to its planning group (K joints), every frame expressed in the world.

    Joints outside the group are locked at ``description.fixed_joints``; their links stay in the
    collision model as fixed geometry. Configurations are arrays of shape (K,) in radians, in the
    order of ``description.group_joints``.
    """

    def __init__(self, description: RobotDescription, T_world_base: Array | None = None) -> None:
        self.description = description
        if T_world_base is None:
            T_world_base = make_transform(description.xyz_world_base,
                                          rpy_to_matrix(description.rpy_world_base))
        self.T_world_base = np.asarray(T_world_base, dtype=float).copy()
        if self.T_world_base.shape != (4, 4) or not np.all(np.isfinite(self.T_world_base)):
            raise RobotError(f"robot '{description.name}': T_world_base must be a finite 4x4 "
                             f"matrix, got shape {self.T_world_base.shape}")
        urdf = description.resolve(description.urdf)
        if not urdf.is_file():
            raise RobotError(f"robot '{description.name}': URDF not found at {urdf}")
        self._urdf = urdf
        self.caches: dict[str, object] = {}
        """Data derived from this robot alone, kept by the layers above (the fast checker's
        fixed-part distance grids: ``collision.packed.GridCache``)."""
        self._package_dirs = [*description.package_dirs, *_default_package_dirs()]
        urdf_root = read_urdf(urdf, description.name)
        unlimited = bounded_continuous(urdf_root)
        named = {*description.group_joints, *dict(description.fixed_joints)}
        renamed = rename_shadowing_joints(urdf_root, named)
        self._urdf_text = ET.tostring(urdf_root, encoding="unicode") \
            if unlimited is not None or renamed else None
        self._adjacent = adjacent_links(urdf_root)
        try:
            full = self._build_model()
            for name in unlimited or ():   # as pinocchio leaves a continuous joint without <limit>
                j = full.joints[full.getJointId(name)]
                full.velocityLimit[j.idx_v] = full.effortLimit[j.idx_v] = np.inf
            col = self._build_geometry(full, pin.COLLISION)
        except (RuntimeError, ValueError) as e:
            raise RobotError(f"robot '{description.name}': cannot load {urdf}: {e}") from e
        self._lock, self._q_ref = _locking(full, description, urdf)
        try:
            model, col = pin.buildReducedModel(full, col, self._lock, self._q_ref)
        except ValueError as e:   # e.g. a named joint that shares its link's name
            raise RobotError(f"robot '{description.name}': cannot lock the joints outside "
                             f"the group in {urdf}: {e}") from e
        self._full = full
        _move_base(model, [col], pin.SE3(self.T_world_base))
        _check_group(model, description, urdf)
        self.model = model
        self.data = model.createData()
        self.collision_model = col
        self.ee_frame_id = frame_named(model, description.ee_frame)
        self.lower = model.lowerPositionLimit.copy()
        self.upper = model.upperPositionLimit.copy()
        self.velocity_limit = model.velocityLimit.copy()
        self.effort_limit = model.effortLimit.copy()
        self._srdf_disabled = _read_disabled_pairs(
            description.resolve(description.srdf) if description.srdf else None
        )

    @cached_property
    def visual_model(self) -> pin.GeometryModel:
        """The URDF's visual geometry, reduced and placed like the collision model (loaded on
        first use: planning never needs it)."""
        vis = self._build_geometry(self._full, pin.VISUAL)
        _, vis = pin.buildReducedModel(self._full, vis, self._lock, self._q_ref)
        T = pin.SE3(self.T_world_base)
        for g in vis.geometryObjects:   # the model's joints were moved at construction
            if g.parentJoint == 0:
                g.placement = T * g.placement
        return vis

    def _build_model(self) -> pin.Model:
        if self._urdf_text is None:
            return pin.buildModelFromUrdf(str(self._urdf))
        return pin.buildModelFromXML(self._urdf_text)

    def _build_geometry(self, full: pin.Model, kind: pin.GeometryType) -> pin.GeometryModel:
        if self._urdf_text is None:
            return pin.buildGeomFromUrdf(full, str(self._urdf), kind,
                                         package_dirs=self._package_dirs)
        return pin.buildGeomFromUrdfString(full, self._urdf_text, kind,
                                           package_dirs=self._package_dirs)

    def content_hash(self) -> str:
        """SHA-256 (hex) of everything that decides this robot's geometry and kinematics: the
        URDF and SRDF bytes, the group, the end-effector frame, the locked joint values, the
        sphere settings and the base pose. Caches (roadmaps) are keyed on it."""
        d = self.description
        h = hashlib.sha256()
        h.update(self._urdf.read_bytes())
        if d.srdf:
            h.update(d.resolve(d.srdf).read_bytes())
        h.update(repr((d.group_joints, d.ee_frame, d.fixed_joints, d.spheres,
                       np.round(self.T_world_base, 12).tolist())).encode())
        if self.always_colliding_pairs:   # (no change for the robots that have none)
            h.update(repr(("always", self.always_colliding_pairs)).encode())
        return h.hexdigest()

    # --- construction -------------------------------------------------------------------
    @classmethod
    def load(cls, name: str = "baxter_left", T_world_base: Array | None = None,
             locked: dict[str, float] | None = None) -> Robot:
        """A built-in robot (``baxter_left`` or ``panda``) or a robot description file (a
        ``.yaml`` path, :meth:`RobotDescription.from_yaml`), optionally at another base pose
        (T_world_base (4, 4), m) and with some locked joints at other values (rad or m)."""
        desc = (RobotDescription.from_yaml(name) if name.endswith((".yaml", ".yml"))
                else RobotDescription.builtin(name))
        return cls(desc.with_locked(locked or {}), T_world_base)

    @classmethod
    def from_urdf(cls, urdf: str | Path, *, joints: Sequence[str], ee_frame: str,
                  srdf: str | Path | None = None, package_dirs: Sequence[str | Path] = (),
                  locked: dict[str, float] | None = None, name: str | None = None,
                  T_world_base: Array | None = None, proximal_joints: int | None = None,
                  roadmap_fixed: Sequence[float] = (),
                  spheres: SphereSettings | None = None) -> Robot:
        """Any serial arm from its URDF.

        Args:
            urdf: path of the URDF file.
            joints: the planned joints, in kinematic order (the configuration's order).
            ee_frame: the end-effector frame (its z axis is the approach direction).
            srdf: an SRDF whose ``disable_collisions`` pairs prune self-collision checks.
            package_dirs: folders that ``package://`` mesh URIs resolve against.
            locked: values of joints outside the group (rad or m; unnamed ones: 0).
            name: the robot's name (default: the URDF's file stem).
            T_world_base: (4, 4) base pose in the world (m); identity by default.
            proximal_joints, roadmap_fixed: roadmap sampling (default: all joints sampled).
            spheres: how the fast checker's sphere cover is made.
        """
        urdf = Path(urdf).expanduser().resolve()
        joints = tuple(str(j) for j in joints)
        desc = RobotDescription(
            name=name or urdf.stem, urdf=str(urdf),
            srdf=str(Path(srdf).expanduser().resolve()) if srdf is not None else None,
            group_joints=joints, ee_frame=ee_frame,
            proximal_joints=len(joints) if proximal_joints is None else int(proximal_joints),
            roadmap_fixed=tuple(float(x) for x in roadmap_fixed),
            spheres=spheres if spheres is not None else SphereSettings(),
            package_dirs=tuple(str(Path(p).expanduser()) for p in package_dirs))
        n_distal = desc.dof - desc.proximal_joints
        if not 0 <= n_distal <= desc.dof or (desc.roadmap_fixed and
                                              len(desc.roadmap_fixed) != n_distal):
            raise RobotError(f"robot '{desc.name}': proximal_joints {desc.proximal_joints} and "
                             f"{len(desc.roadmap_fixed)} roadmap_fixed values do not fit "
                             f"{desc.dof} joints")
        return cls(desc.with_locked(locked or {}),
                   np.eye(4) if T_world_base is None else T_world_base)

    @classmethod
    def from_yaml(cls, path: str | Path, T_world_base: Array | None = None) -> Robot:
        return cls(RobotDescription.from_yaml(path), T_world_base)

    # --- basic facts --------------------------------------------------------------------
    @property
    def name(self) -> str:
        return self.description.name

    @property
    def dof(self) -> int:
        return int(self.model.nq)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.description.group_joints

    def check_configuration(self, q: Array, what: str = "configuration") -> Array:
        """q as a float array of shape (K,); a clear error for a wrong size or NaN."""
        arr = np.asarray(q, dtype=float)
        if arr.shape != (self.dof,):
            raise RobotError(
                f"{what}: expected {self.dof} joint values for {self.joint_names}, "
                f"got shape {arr.shape}"
            )
        if not np.all(np.isfinite(arr)):
            raise RobotError(f"{what}: contains NaN or inf: {arr}")
        return arr

    def within_limits(self, Q: Array, tol: float = 1e-9) -> NDArray[np.bool_]:
        """Whether each row of Q (N, K) lies within the joint limits."""
        Q = np.atleast_2d(Q)
        return np.all((self.lower - tol <= Q) & (self.upper + tol >= Q), axis=1)

    def sample_uniform(self, rng: np.random.Generator, n: int) -> Array:
        """n configurations drawn uniformly within the joint limits, shape (n, K)."""
        return rng.uniform(self.lower, self.upper, size=(n, self.dof))

    # --- kinematics ---------------------------------------------------------------------
    def compute_frame_pose(self, q: Array, frame: str | int | None = None) -> Array:
        """T_world_frame (4, 4) at q; the end-effector frame by default."""
        fid = self._frame_id(frame)
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return self.data.oMf[fid].homogeneous.copy()

    def compute_ee_pose(self, q: Array) -> Array:
        """T_world_ee (4, 4) at q."""
        return self.compute_frame_pose(q, self.ee_frame_id)

    def compute_ee_poses(self, Q: Array) -> Array:
        """T_world_ee for each row of Q (N, K): shape (N, 4, 4)."""
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        out = np.empty((len(Q), 4, 4))
        for i, q in enumerate(Q):
            pin.framesForwardKinematics(self.model, self.data, q)
            out[i] = self.data.oMf[self.ee_frame_id].homogeneous
        return out

    def compute_frame_jacobian(self, q: Array, frame: str | int | None = None) -> Array:
        """Jacobian (6, K) of the frame's velocity, world-aligned at the frame origin.

        Rows 0-2 map joint rates (rad/s) to linear velocity (m/s), rows 3-5 to angular (rad/s).
        """
        fid = self._frame_id(frame)
        return pin.computeFrameJacobian(
            self.model, self.data, np.asarray(q, dtype=float), fid, pin.LOCAL_WORLD_ALIGNED
        ).copy()

    def compute_joint_placements(self, q: Array) -> Array:
        """T_world_joint of every group joint at q, shape (K, 4, 4)."""
        pin.forwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return np.stack([self.data.oMi[j].homogeneous for j in range(1, self.model.njoints)])

    def compute_joint_axes(self) -> Array:
        """Rotation axis (K, 3) of each group joint in its own frame (unit vectors); a clear
        error for a joint that is not revolute."""
        m = self.model
        axes = []
        for k in range(1, self.dof + 1):
            axis = joint_axis(m.joints[k])
            if axis is None:
                raise RobotError(f"robot '{self.name}': joint '{m.names[k]}' is "
                                 f"{m.joints[k].shortname()}; only revolute joints are "
                                 "supported by the compiled kinematics")
            axes.append(axis)
        return np.array(axes, dtype=float)

    def _frame_id(self, frame: str | int | None) -> int:
        if frame is None:
            return self.ee_frame_id
        if isinstance(frame, str):
            if not self.model.existFrame(frame):
                raise RobotError(f"robot '{self.name}': no frame '{frame}'")
            return frame_named(self.model, frame)
        return int(frame)

    @cached_property
    def reach(self) -> tuple[Array, float]:
        """(origin of the first group joint in the world, an upper bound on how far the
        end-effector frame gets from it, m)."""
        base = self.compute_joint_placements(np.zeros(self.dof))[0][:3, 3]
        Q = self.sample_uniform(np.random.default_rng(0), 2000)
        d = np.linalg.norm(self.compute_ee_poses(Q)[:, :3, 3] - base, axis=1)
        return base, float(d.max() * 1.05 + 0.02)

    # --- collision structure ------------------------------------------------------------
    def geometry_link(self, index: int) -> str:
        """Name of the link that carries collision geometry ``index``."""
        g = self.collision_model.geometryObjects[int(index)]
        return str(self.model.frames[g.parentFrame].name)

    @cached_property
    def moving_geometries(self) -> tuple[int, ...]:
        """Collision geometries that move with the group joints."""
        return tuple(
            i for i, g in enumerate(self.collision_model.geometryObjects) if g.parentJoint > 0
        )

    @cached_property
    def self_collision_pairs(self) -> tuple[tuple[int, int], ...]:
        """Pairs of collision geometries checked for self-collision.

        A pair is checked when at least one geometry moves, the two are on different joints,
        their links are not adjacent (:func:`~chekhov.robot._urdf.adjacent_links`: joined by
        a joint, or through links without collision geometry — MoveIt's "Adjacent"), the
        SRDF does not disable them (never in collision), and they do not collide in every
        configuration (:attr:`always_colliding_pairs`, MoveIt's "Always").
        """
        always = set(self.always_colliding_pairs)
        return tuple(p for p in self._candidate_self_pairs if p not in always)

    @cached_property
    def always_colliding_pairs(self) -> tuple[tuple[int, int], ...]:
        """Geometry pairs left out of :attr:`self_collision_pairs` because they collide in
        every one of 1000 random configurations (:mod:`chekhov.robot.self_pairs`): meshes that
        overlap by design, which no SRDF entry disables. Logged as a warning when found."""
        found = always_colliding(self.model, self.collision_model, self._candidate_self_pairs,
                                 self.lower, self.upper)
        if found:
            names = sorted({tuple(sorted((self.geometry_link(i), self.geometry_link(j))))
                            for i, j in found})
            _log.warning("robot '%s': %d self-collision pair(s) collide in every one of %d "
                         "random configurations and are not checked (MoveIt's \"Always\"; "
                         "an SRDF's disable_collisions says so explicitly): %s", self.name,
                         len(found), ALWAYS_SAMPLES, names)
        return found

    @cached_property
    def _candidate_self_pairs(self) -> tuple[tuple[int, int], ...]:
        """The pairs the URDF's adjacency and the SRDF leave (:attr:`self_collision_pairs`
        before the "Always" rule)."""
        geoms = self.collision_model.geometryObjects
        moving = set(self.moving_geometries)
        disabled = self._srdf_disabled | self._adjacent
        pairs = []
        for i in range(len(geoms)):
            for j in range(i + 1, len(geoms)):
                if i not in moving and j not in moving:
                    continue
                if geoms[i].parentJoint == geoms[j].parentJoint:
                    continue
                a, b = self.geometry_link(i), self.geometry_link(j)
                if a == b or frozenset((a, b)) in disabled:
                    continue
                pairs.append((i, j))
        return tuple(pairs)


def _default_package_dirs() -> list[str]:
    """example-robot-data's share folder's parent, when the package is installed."""
    try:
        return [str(example_robot_data_dir().parent)]
    except RobotError:
        return []


def _locking(full: pin.Model, description: RobotDescription, urdf: Path
             ) -> tuple[list[int], Array]:
    """The joints to lock (every one outside the group) and the full configuration holding
    them at their locked values."""
    names = list(full.names)
    missing = [j for j in description.group_joints if j not in names]
    if missing:
        raise RobotError(f"robot '{description.name}': group joints {missing} not in {urdf}; "
                         f"its joints: {names[1:]}")
    q_ref = pin.neutral(full)
    for jname, value in description.fixed_joints:
        if jname not in names:
            raise RobotError(f"robot '{description.name}': locked joint '{jname}' not in {urdf}")
        joint = full.joints[full.getJointId(jname)]
        if joint.nq != 1:
            raise RobotError(f"robot '{description.name}': locked joint '{jname}' has "
                             f"{joint.nq} coordinates; only 1-coordinate joints can be set")
        q_ref[joint.idx_q] = value
    lock = [full.getJointId(n) for n in names[1:] if n not in description.group_joints]
    return lock, q_ref


def _check_group(model: pin.Model, description: RobotDescription, urdf: Path) -> None:
    """The reduced model is the group: its joints in the given order, one coordinate each, and
    the end-effector frame exists."""
    reduced_names = list(model.names)[1:]
    if reduced_names != list(description.group_joints):
        raise RobotError(
            f"robot '{description.name}': group joints must be listed in kinematic order; "
            f"the model orders them {reduced_names}")
    for k in range(1, model.njoints):
        j = model.joints[k]
        if j.nq != 1 or j.nv != 1:
            raise RobotError(f"robot '{description.name}': joint '{model.names[k]}' "
                             f"({j.shortname()}) has {j.nq} coordinates; a planning group "
                             "is a chain of 1-DOF revolute or prismatic joints")
    if not model.existFrame(description.ee_frame):
        raise RobotError(f"robot '{description.name}': no end-effector frame "
                         f"'{description.ee_frame}' in {urdf}")


def frame_named(model: pin.Model, name: str) -> int:
    """The id of ``model``'s frame ``name``. A URDF fixed joint may share its child link's
    name (Unitree's Z1: "gripperStator"), and pinocchio's lookup by name then refuses; both
    frames sit at the link's origin, so the link's (BODY) frame is taken."""
    ids = [i for i, f in enumerate(model.frames) if f.name == name]
    if len(ids) > 1:
        ids = [i for i in ids if model.frames[i].type == pin.FrameType.BODY] or ids[:1]
    if not ids:
        raise RobotError(f"no frame '{name}' in the model")
    return ids[0]


def _move_base(model: pin.Model, geometry_models: list[pin.GeometryModel], T: pin.SE3) -> None:
    """Re-express everything attached to the universe in the world: left-multiply by T."""
    for j in range(1, model.njoints):
        if model.parents[j] == 0:
            model.jointPlacements[j] = T * model.jointPlacements[j]
    for f in model.frames:
        if f.parentJoint == 0 and f.name != "universe":
            f.placement = T * f.placement
    for gm in geometry_models:
        for g in gm.geometryObjects:
            if g.parentJoint == 0:
                g.placement = T * g.placement


def _read_disabled_pairs(srdf: Path | None) -> frozenset[frozenset[str]]:
    if srdf is None:
        return frozenset()
    try:
        root = ET.parse(srdf).getroot()
    except (OSError, ET.ParseError) as e:
        raise RobotError(f"{srdf}: cannot read SRDF: {e}") from e
    return frozenset(
        frozenset((el.get("link1", ""), el.get("link2", "")))
        for el in root.iter("disable_collisions")
    )
