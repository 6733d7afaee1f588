"""Numba forward and inverse kinematics of a serial revolute chain, for hot loops
(roadmap and planners).

``chekhov.robot.ik.solve_ik`` (pinocchio, Python loop) costs ~0.5 ms a seeded solve; the
roadmap solves IK for every semantic node at build time and for every pose goal at query time,
seeded from roadmap nodes, so this compiled version (~10-30 µs a solve) keeps a query under a
millisecond. Same damped least squares as ``solve_ik``, but with the pose error and Jacobian in
world-aligned coordinates at the end-effector origin. Results are checked against pinocchio in
the tests.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

from chekhov.errors import RobotError
from chekhov.robot.robot import Robot

Array = NDArray[np.float64]


class KinematicChain(NamedTuple):
    """A tree of revolute joints in the world frame, as the compiled kernels read it (numba
    takes a ``NamedTuple`` of arrays as a tuple with named fields).

    Attributes:
        parent: (K,) int64, index of each joint's parent joint, -1 for a joint on the world
            (a serial chain: -1, 0, 1, …, K-2).
        R_parent_joint, p_parent_joint: (K, 3, 3), (K, 3) placement of each joint in its
            parent joint's frame (in the world for a root joint), m.
        axis: (K, 3) rotation axis of each joint in its own frame (unit).
    """

    parent: NDArray[np.int64]
    R_parent_joint: Array
    p_parent_joint: Array
    axis: Array


def kinematic_chain(robot: Robot) -> KinematicChain:
    """The robot's planning group (any tree of revolute joints) for :func:`chain_fk`; raises
    :class:`RobotError` for a joint that is not revolute."""
    m = robot.model
    K = robot.dof
    return KinematicChain(
        parent=np.array([m.parents[k] - 1 for k in range(1, K + 1)], dtype=np.int64),
        R_parent_joint=np.array([m.jointPlacements[k].rotation for k in range(1, K + 1)],
                                dtype=float).reshape(K, 3, 3),
        p_parent_joint=np.array([m.jointPlacements[k].translation for k in range(1, K + 1)],
                                dtype=float).reshape(K, 3),
        axis=robot.compute_joint_axes())


@dataclass(frozen=True, eq=False)
class ChainKinematics:
    """A serial revolute chain in the world frame with its end effector, for the kernels.

    Attributes:
        chain: the joints (:class:`KinematicChain`, parent k - 1 for joint k).
        R_last_ee, p_last_ee: (3, 3), (3,) end-effector frame in the last joint's frame.
        lower, upper: (K,) joint limits, rad.
    """

    chain: KinematicChain
    R_last_ee: Array
    p_last_ee: Array
    lower: Array
    upper: Array

    @classmethod
    def from_robot(cls, robot: Robot) -> ChainKinematics:
        """The robot's planning group; raises :class:`RobotError` for a non-serial chain or
        a non-revolute joint, or an end effector not on the last joint."""
        m = robot.model
        K = robot.dof
        for k in range(1, K + 1):
            if m.parents[k] != k - 1:
                raise RobotError(f"robot '{robot.name}': chain kinematics need a serial "
                                 f"chain; joint '{m.names[k]}' has parent {m.parents[k]}")
        frame = m.frames[robot.ee_frame_id]
        if frame.parentJoint != K:
            raise RobotError(f"robot '{robot.name}': end-effector frame is on joint "
                             f"{frame.parentJoint}, expected the last joint {K}")
        return cls(
            chain=kinematic_chain(robot),
            R_last_ee=np.array(frame.placement.rotation), p_last_ee=np.array(
                frame.placement.translation),
            lower=robot.lower.astype(float).copy(), upper=robot.upper.astype(float).copy())

    def ee_poses(self, Q: Array) -> tuple[Array, Array]:
        """End-effector rotation (N, 3, 3) and position (N, 3), world, for each row of Q."""
        Q = np.ascontiguousarray(np.atleast_2d(np.asarray(Q, dtype=float)))
        R = np.empty((len(Q), 3, 3))
        p = np.empty((len(Q), 3))
        ee_batch(Q, self.chain, self.R_last_ee, self.p_last_ee, R, p)
        return R, p

    def solve(self, T_world_ee: Array, Q_seed: Array, max_iterations: int = 60,
              position_tolerance: float = 1e-4, rotation_tolerance: float = 1e-3,
              damping: float = 1e-6, stop_after: int | None = None
              ) -> tuple[Array, NDArray[np.bool_]]:
        """Damped least squares from each seed (M, K): solutions (M, K) within limits and a
        converged flag (M,) (position error ≤ ``position_tolerance`` m and rotation error ≤
        ``rotation_tolerance`` rad). With ``stop_after``, seeds after that many converged
        ones are not tried (flag False)."""
        Q0 = np.ascontiguousarray(np.atleast_2d(np.asarray(Q_seed, dtype=float)))
        T = np.asarray(T_world_ee, dtype=float)
        out = np.empty_like(Q0)
        ok = np.empty(len(Q0), dtype=np.bool_)
        ik_batch(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]), Q0,
                 self.chain, self.R_last_ee, self.p_last_ee, self.lower, self.upper,
                 max_iterations, position_tolerance, rotation_tolerance, damping,
                 len(Q0) if stop_after is None else int(stop_after), out, ok)
        return out, ok


# sin and cos on [-pi/4, pi/4]: fdlibm's kernels (__kernel_sin, __kernel_cos; error < 1 ulp
# there), after reduction by the nearest multiple k of pi/2 with pi/2 in three parts
# (Cody-Waite; exact products for |k| < 2**20)
_S1, _S2, _S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_S4, _S5, _S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_C1, _C2, _C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_C4, _C5, _C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11
_INV_PIO2 = 6.36619772367581382433e-01
_PIO2_1, _PIO2_2, _PIO2_3 = 1.57079632673412561417e+00, 6.07710050630396597660e-11, \
    2.02226624871116645580e-21
SINCOS_MAX_ABS = 1e5
"""rad: beyond it :func:`sincos` hands over to ``np.sin`` and ``np.cos``."""


@njit(cache=True, nogil=True, inline="always")
def sincos(x):  # pragma: no cover - compiled
    """(sin x, cos x), within 1-2 ulp of ``np.sin`` and ``np.cos`` (x in rad; NaN for NaN or
    infinite x), with no branch on the quadrant. Six times cheaper than the two calls in a
    loop of their own (39 against 230 ns for seven joints); in the forward kinematics of
    every compiled kernel, 3-5% off a fast check (``docs/history.md``)."""
    if not abs(x) <= SINCOS_MAX_ABS:   # NaN too
        return np.sin(x), np.cos(x)
    k = np.floor(x * _INV_PIO2 + 0.5)
    r = ((x - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_3
    z = r * r
    s = r + r * z * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    c = 1.0 - 0.5 * z + z * z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6)))))
    q = int(k)
    swap = (q & 1) == 1    # odd quadrants: sin x = ±cos r, cos x = ∓sin r
    a = c if swap else s
    b = s if swap else c
    return (-a if (q & 2) == 2 else a), (-b if ((q + 1) & 2) == 2 else b)


@njit(cache=True, nogil=True, inline="always")
def _mul3(A, B, out):  # pragma: no cover - compiled
    """out = A @ B for 3x3 matrices (out must not alias A or B)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


@njit(cache=True, nogil=True, inline="always")
def chain_fk_arrays(q, parent, R0, p0, axis, R_out, p_out):  # pragma: no cover - compiled
    """World rotation R_out (K, 3, 3) and origin p_out (K, 3) of each joint at q, the chain
    given by its arrays (those of :class:`KinematicChain`: parent, R_parent_joint,
    p_parent_joint, axis): T_k = T_parent(k) · placement_k · Rot(axis_k, q_k). The one forward
    kinematics of the compiled code (IK here, the collision kernels, the distance terms);
    parents come before their children. Hot kernels take the arrays out of the chain once and
    call this; others call :func:`chain_fk`.

    Written with scalars, row by row, and no work arrays: the two 3 × 3 arrays it allocated
    on every call were a third of its time (the Panda's chain: 414 → 266 ns, the same
    poses to the bit; measured in one run)."""
    for k in range(q.shape[0]):
        x, y, z = axis[k, 0], axis[k, 1], axis[k, 2]
        s, c = sincos(q[k])
        t = 1.0 - c
        # Rot(axis_k, q_k) (Rodrigues: about the unit axis (x, y, z))
        r00, r01, r02 = t * x * x + c, t * x * y - s * z, t * x * z + s * y
        r10, r11, r12 = t * x * y + s * z, t * y * y + c, t * y * z - s * x
        r20, r21, r22 = t * x * z - s * y, t * y * z + s * x, t * z * z + c
        pk = parent[k]
        for a in range(3):   # row a of R_parent · R0_k, then of it · Rot
            if pk < 0:
                a0, a1, a2 = R0[k, a, 0], R0[k, a, 1], R0[k, a, 2]
                p_out[k, a] = p0[k, a]
            else:
                u0, u1, u2 = R_out[pk, a, 0], R_out[pk, a, 1], R_out[pk, a, 2]
                p_out[k, a] = u0 * p0[k, 0] + u1 * p0[k, 1] + u2 * p0[k, 2] + p_out[pk, a]
                a0 = u0 * R0[k, 0, 0] + u1 * R0[k, 1, 0] + u2 * R0[k, 2, 0]
                a1 = u0 * R0[k, 0, 1] + u1 * R0[k, 1, 1] + u2 * R0[k, 2, 1]
                a2 = u0 * R0[k, 0, 2] + u1 * R0[k, 1, 2] + u2 * R0[k, 2, 2]
            R_out[k, a, 0] = a0 * r00 + a1 * r10 + a2 * r20
            R_out[k, a, 1] = a0 * r01 + a1 * r11 + a2 * r21
            R_out[k, a, 2] = a0 * r02 + a1 * r12 + a2 * r22


@njit(cache=True, nogil=True, inline="always")
def chain_fk(q, chain, R_out, p_out):  # pragma: no cover - compiled
    """:func:`chain_fk_arrays` of ``chain`` (a :class:`KinematicChain`) at q."""
    chain_fk_arrays(q, chain.parent, chain.R_parent_joint, chain.p_parent_joint, chain.axis,
                    R_out, p_out)


@njit(cache=True, nogil=True)
def ee_batch(Q, chain, Rf, pf, R_out, p_out):  # pragma: no cover - compiled
    K = Q.shape[1]
    Rj = np.empty((K, 3, 3))
    pj = np.empty((K, 3))
    parent, R0, p0, axis = chain.parent, chain.R_parent_joint, chain.p_parent_joint, chain.axis
    for i in range(Q.shape[0]):
        chain_fk_arrays(Q[i], parent, R0, p0, axis, Rj, pj)
        R_out[i] = Rj[K - 1] @ Rf
        p_out[i] = pj[K - 1] + Rj[K - 1] @ pf


@njit(cache=True, nogil=True, inline="always")
def log3(R):  # pragma: no cover - compiled
    """Rotation vector (3,) of a rotation matrix, rad."""
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    c = min(1.0, max(-1.0, (tr - 1.0) / 2.0))
    theta = np.arccos(c)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if theta < 1e-6:
        return 0.5 * w
    if theta > np.pi - 1e-4:
        # near a half turn: the axis from the largest diagonal entry of (R + I) / 2
        B = 0.5 * (R + np.eye(3))
        k = 0
        if B[1, 1] > B[k, k]:
            k = 1
        if B[2, 2] > B[k, k]:
            k = 2
        a = B[:, k] / np.sqrt(max(B[k, k], 1e-12))
        a = a / np.linalg.norm(a)
        if a[0] * w[0] + a[1] * w[1] + a[2] * w[2] < 0:
            a = -a
        return theta * a
    return theta / (2.0 * np.sin(theta)) * w


@njit(cache=True, nogil=True, inline="always")
def _solve_spd6(A, b, x):  # pragma: no cover - compiled
    """x = A⁻¹ b for a symmetric positive definite 6x6 A (Cholesky; A is overwritten)."""
    n = 6
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d -= A[j, k] * A[j, k]
        d = np.sqrt(max(d, 1e-300))
        A[j, j] = d
        for i in range(j + 1, n):
            v = A[i, j]
            for k in range(j):
                v -= A[i, k] * A[j, k]
            A[i, j] = v / d
    for i in range(n):
        v = b[i]
        for k in range(i):
            v -= A[i, k] * x[k]
        x[i] = v / A[i, i]
    for i in range(n - 1, -1, -1):
        v = x[i]
        for k in range(i + 1, n):
            v -= A[k, i] * x[k]
        x[i] = v / A[i, i]


@njit(cache=True, nogil=True)
def ik_descend(R_t, p_t, q0, chain, Rf, pf, lower, upper, max_iterations, pos_tol,
               rot_tol, damping, q_out):  # pragma: no cover - compiled
    """Damped least squares from q0 towards the target pose (R_t, p_t); writes q_out and
    returns (position error m, rotation error rad)."""
    K = q0.shape[0]
    parent, R0, p0, axis = chain.parent, chain.R_parent_joint, chain.p_parent_joint, chain.axis
    Rj = np.empty((K, 3, 3))
    pj = np.empty((K, 3))
    J = np.empty((6, K))
    A = np.empty((6, 6))
    e = np.empty(6)
    y = np.empty(6)
    R_e = np.empty((3, 3))
    R_err = np.empty((3, 3))
    p_e = np.empty(3)
    q = q_out
    for a in range(K):
        q[a] = min(upper[a], max(lower[a], q0[a]))
    pos_err = np.inf
    rot_err = np.inf
    for it in range(max_iterations + 1):
        chain_fk_arrays(q, parent, R0, p0, axis, Rj, pj)
        RK = Rj[K - 1]
        _mul3(RK, Rf, R_e)
        for i in range(3):
            p_e[i] = pj[K - 1, i] + RK[i, 0] * pf[0] + RK[i, 1] * pf[1] + RK[i, 2] * pf[2]
        for i in range(3):  # R_t @ R_e.T
            for j in range(3):
                R_err[i, j] = R_t[i, 0] * R_e[j, 0] + R_t[i, 1] * R_e[j, 1] + R_t[i, 2] * R_e[j, 2]
        w = log3(R_err)
        for a in range(3):
            e[a] = p_t[a] - p_e[a]
            e[3 + a] = w[a]
        pos_err = np.sqrt(e[0] ** 2 + e[1] ** 2 + e[2] ** 2)
        rot_err = np.sqrt(e[3] ** 2 + e[4] ** 2 + e[5] ** 2)
        if (pos_err < pos_tol * 0.5 and rot_err < rot_tol * 0.5) or it == max_iterations:
            break
        for k in range(K):
            Rk = Rj[k]
            ax = axis[k]
            a0 = Rk[0, 0] * ax[0] + Rk[0, 1] * ax[1] + Rk[0, 2] * ax[2]
            a1 = Rk[1, 0] * ax[0] + Rk[1, 1] * ax[1] + Rk[1, 2] * ax[2]
            a2 = Rk[2, 0] * ax[0] + Rk[2, 1] * ax[1] + Rk[2, 2] * ax[2]
            r0 = p_e[0] - pj[k, 0]
            r1 = p_e[1] - pj[k, 1]
            r2 = p_e[2] - pj[k, 2]
            J[0, k] = a1 * r2 - a2 * r1
            J[1, k] = a2 * r0 - a0 * r2
            J[2, k] = a0 * r1 - a1 * r0
            J[3, k] = a0
            J[4, k] = a1
            J[5, k] = a2
        lam = damping + 1e-3 * np.sqrt(pos_err ** 2 + rot_err ** 2)
        for i in range(6):
            for j in range(i + 1):
                v = 0.0
                for k in range(K):
                    v += J[i, k] * J[j, k]
                A[i, j] = v
                A[j, i] = v
            A[i, i] += lam
        _solve_spd6(A, e, y)
        for a in range(K):
            dq = 0.0
            for i in range(6):
                dq += J[i, a] * y[i]
            q[a] = min(upper[a], max(lower[a], q[a] + dq))
    return pos_err, rot_err


@njit(cache=True, nogil=True)
def ik_batch(R_t, p_t, Q0, chain, Rf, pf, lower, upper, max_iterations, pos_tol,
             rot_tol, damping, stop_after, Q_out, ok):  # pragma: no cover - compiled
    """IK from each seed row of Q0; after ``stop_after`` converged seeds the rest are skipped
    (ok False)."""
    found = 0
    for i in range(Q0.shape[0]):
        ok[i] = False
        if found >= stop_after:
            Q_out[i] = Q0[i]
            continue
        pe, re = ik_descend(R_t, p_t, Q0[i], chain, Rf, pf, lower, upper,
                            max_iterations, pos_tol, rot_tol, damping, Q_out[i])
        ok[i] = pe <= pos_tol and re <= rot_tol
        if ok[i]:
            found += 1
