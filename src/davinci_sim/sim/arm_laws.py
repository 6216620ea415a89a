"""The arm's laws of the 1 kHz tick, batch-capable: one implementation for the live arm and
the study's batch engine.

:class:`~davinci_sim.sim.arm.Arm` (and the snapshots of :mod:`davinci_sim.sim.handle`) call
them with one arm (a batch of one); :class:`~davinci_sim.study.batch.TrialBatch` with one row
per trial. Every function takes any leading batch axes and computes each row with the same
elementwise arithmetic whatever the batch size (no BLAS products, whose rounding depends on
the size), so a trial gives the same bits alone, in any batch, and on the live arm.

(Beside ``arm.py`` rather than in it: that module is already over 500 lines.)

Frames as in :mod:`davinci_sim.sim.arm`: ``T_ref_base`` is the arm's base frame in its
reference (PSM: camera, MTM: HRSV), ``T_base_tip`` the forward kinematics in the chain base.
"""

from __future__ import annotations

import math

import numpy as np

from davinci_sim.geometry import so3
from davinci_sim.geometry.so3 import rotate_pairs
from davinci_sim.kinematics import fk
from davinci_sim.kinematics.chain import DHChain
from davinci_sim.kinematics.fk_compiled import tip_pose_row
from davinci_sim.kinematics.jit import ENABLED as _COMPILED
from davinci_sim.kinematics.jit import helper, jit, kernel_array, warm
from davinci_sim.kinematics.scratch import local
from davinci_sim.sim.trajectory import step_towards_row

try:  # the gufunc behind np.linalg.solve (see _solve)
    from numpy.linalg import _umath_linalg

    _gesv = _umath_linalg.solve
except (ImportError, AttributeError):  # pragma: no cover - depends on numpy's internals
    _gesv = None

#: A joint whose position stays further than this from its setpoint (rad, m) for
#: ``TRACKING_FAULT_TIME`` s puts the arm in FAULT, as a PID tracking error does on the dVRK.
TRACKING_FAULT_TOLERANCE = {"revolute": 0.35, "prismatic": 0.03}
TRACKING_FAULT_TIME = 0.05
#: A servo step whose IK answer moves a joint of the PSM's wrist (roll, pitch, yaw) further
#: than this (rad) from where it is puts the wrist on another branch: the closed form has no
#: answer left on the branch the wrist is on (a goal past the wrist's reach, e.g. turned on
#: with the yaw at its limit). Such a step is refused and the tool held: taken, the setpoint
#: jumped up to 3 rad in one tick and the arm faulted on its tracking error (a trainee
#: holding a wrist key). The dVRK's IK, iterating from the measured joints, does not leave
#: the branch either. (A stream's steps are far smaller: past 0.35 rad the arm faults.)
OTHER_BRANCH = 1.0
#: Joint limits are checked with this slack (rad, m): a solver's answer on a limit passes.
LIMIT_SLACK = 1e-9
#: Joint velocities beyond this (rad/s, m/s) from a square solve mean a singular Jacobian.
_SINGULAR_QD = 1e6


def tip_kinematics(chain: DHChain, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(T_base_tip, J_spatial)`` of joints ``q`` (..., dof): pose (..., 4, 4), m, and the
    spatial Jacobian (..., 6, dof) in the chain base (``measured_cp``/``measured_cv``)."""
    return fk.forward_kinematics_and_jacobian(chain, q)


def tip_pose(chain: DHChain, q: np.ndarray) -> np.ndarray:
    """``T_base_tip`` (..., 4, 4), m, of joints ``q`` (..., dof) (``setpoint_cp``)."""
    return fk.forward_kinematics(chain, q)


def pose_in_reference(T_ref_base: np.ndarray, T_base_tip: np.ndarray) -> np.ndarray:
    """``measured_cp``/``setpoint_cp``: the tip in the base frame's reference, (..., 4, 4)."""
    return T_ref_base @ T_base_tip


def twist_in_reference(R_ref_base: np.ndarray, J: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """``measured_cv``: ``J·q̇`` (linear m/s, angular rad/s) rotated into the reference's
    orientation; ``J`` (..., 6, dof) spatial in the chain base, ``qd`` (..., dof). One arm
    (devices and haptics read it every tick): the compiled :func:`twist_row`, the same bits."""
    if J.ndim == 2 and np.ndim(qd) == 1 and _COMPILED:
        out = np.empty(6)
        twist_row(_row(R_ref_base), _row(J), _row(qd), out)
        return out
    v = np.sum(J * qd[..., None, :], axis=-1)
    return rotate_pairs(R_ref_base, v)


def joint_velocity(J: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """Joint velocities (..., dof) giving ``twist`` (..., 6) in the Jacobian's frame
    (``servo_cp``'s velocity feed-forward): a solve where ``J`` is square and regular, least
    squares otherwise (each singular row on its own)."""
    if J.shape[-1] != J.shape[-2]:
        if J.ndim == 2:
            return np.linalg.lstsq(J, twist, rcond=None)[0]
        return np.stack([joint_velocity(j, w) for j, w in zip(J, twist, strict=True)])
    qd = _solve(J, twist)
    ok = np.isfinite(qd).all(axis=-1) & (np.abs(qd).max(axis=-1) < _SINGULAR_QD)
    if J.ndim == 2:
        return qd if ok else np.linalg.lstsq(J, twist, rcond=None)[0]
    for i in np.flatnonzero(~ok):
        qd[i] = np.linalg.lstsq(J[i], twist[i], rcond=None)[0]
    return qd


def _solve(J: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """``J⁻¹·twist`` by LAPACK's ``gesv``, nan where ``J`` is singular: the gufunc behind
    ``np.linalg.solve`` (the same call, so the same bits), without its Python checks (4x the
    solve's cost at 1 kHz) and without raising for a singular row of a batch."""
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        if _gesv is None:  # pragma: no cover - numpy without the private module
            try:
                return np.linalg.solve(J, twist[..., None])[..., 0]
            except np.linalg.LinAlgError:
                return np.full(twist.shape, np.nan)
        return _gesv(J, twist[..., None], signature="dd->d")[..., 0]


def wrench_effort(
    J: np.ndarray, R_base_wrench: np.ndarray, wrench: np.ndarray, ftmax: np.ndarray
) -> np.ndarray:
    """Joint efforts (..., dof) (N·m, N) rendering ``wrench`` (..., 6: force N then torque
    N·m at the tip, in axes ``R_base_wrench`` (3, 3) gives in the chain base): ``Jᵀ·w``
    with the spatial Jacobian, clamped to the joints' ``ftmax`` (``body``/``spatial``
    ``servo_cf``). One arm (the live MTM's haptic wrench, every tick): the compiled
    :func:`wrench_effort_row`, the same bits."""
    if J.ndim == 2 and np.ndim(wrench) == 1 and _COMPILED:
        out = np.empty(J.shape[1])
        wrench_effort_row(
            _row(J),
            _row(R_base_wrench),
            _row(wrench),
            _row(ftmax),
            out,
        )
        return out
    w_base = rotate_pairs(R_base_wrench, wrench)
    tau = np.sum(np.swapaxes(J, -1, -2) * w_base[..., None, :], axis=-1)
    return np.minimum(np.maximum(tau, -ftmax), ftmax)


def tracking_bad(
    q: np.ndarray, q_ref: np.ndarray, tolerance: np.ndarray, effort_mode: np.ndarray
) -> np.ndarray:
    """Per joint (..., dof): position-servoed and further from its setpoint than the
    tracking tolerance."""
    return (np.abs(q - q_ref) > tolerance) & ~effort_mode


def _row(a) -> np.ndarray:
    """``a`` as a new C-ordered, writable float array: the argument types a compiled row's
    warm-up compiled (a transposed or read-only view would compile a second signature inside
    the 1 kHz loop)."""
    return np.array(a, dtype=float, order="C")


@jit
def twist_row(R, J, qd, out):
    """:func:`twist_in_reference` of one arm into ``out`` (6,): ``J·q̇`` row by row summed
    left to right from 0 (as numpy sums a row of six or seven), both halves rotated by
    ``R`` as :func:`~davinci_sim.geometry.so3.rotate_pairs` rotates one 6-vector."""
    v = local(6)  # (in the frame: every tick)
    for k in range(6):
        t = 0.0
        for j in range(J.shape[1]):
            t = t + J[k, j] * qd[j]
        v[k] = t
    for h in range(2):
        x, y, z = v[3 * h], v[3 * h + 1], v[3 * h + 2]
        out[3 * h] = x * R[0, 0] + y * R[0, 1] + z * R[0, 2]
        out[3 * h + 1] = x * R[1, 0] + y * R[1, 1] + z * R[1, 2]
        out[3 * h + 2] = x * R[2, 0] + y * R[2, 1] + z * R[2, 2]


@jit
def wrench_effort_row(J, R, w, ftmax, out):
    """:func:`wrench_effort` of one arm into ``out`` (dof,): the wrench's halves rotated as
    :func:`~davinci_sim.geometry.so3.rotate_pairs` rotates one 6-vector, ``Jᵀ·w`` summed
    over the six rows left to right from 0 (as numpy sums one arm's), then ``np.maximum``/
    ``np.minimum`` against ``∓ftmax`` (NaN kept)."""
    x, y, z, u, v, s = w[0], w[1], w[2], w[3], w[4], w[5]
    wb = (
        x * R[0, 0] + y * R[0, 1] + z * R[0, 2],
        x * R[1, 0] + y * R[1, 1] + z * R[1, 2],
        x * R[2, 0] + y * R[2, 1] + z * R[2, 2],
        u * R[0, 0] + v * R[0, 1] + s * R[0, 2],
        u * R[1, 0] + v * R[1, 1] + s * R[1, 2],
        u * R[2, 0] + v * R[2, 1] + s * R[2, 2],
    )
    for j in range(J.shape[1]):
        t = 0.0  # numpy's sum over the (strided) row starts from 0: the same signed zeros
        for k in range(6):
            t = t + J[k, j] * wb[k]
        lo, hi = -ftmax[j], ftmax[j]
        if t == t and lo == lo:  # np.maximum(t, lo)
            t = t if t >= lo else lo
        elif lo != lo:
            t = lo
        if t == t and hi == hi:  # np.minimum(t, hi)
            t = t if t <= hi else hi
        elif hi != hi:
            t = hi
        out[j] = t


_rotation_vector = helper(so3.rotation_vector_floats)


@jit
def locked_wrist_goal(links, modified, tool, identity, q, first, R_base_goal, steps, damping,
                      lo, hi, T, J, F, A, x, goal) -> bool:  # fmt: skip
    """The MTM's orientation lock (``MTM._locked_wrist_goal``): ``steps`` damped least squares
    steps of the wrist joints ``q[first:]`` (rad, seeded with ``q``, which is updated)
    towards the tip orientation ``R_base_goal`` (3, 3, in the chain base): each step the
    spatial rotation error ``rotvec(R_base_goal·R_base_tipᵀ)`` and
    ``Δq = Jwᵀ (Jw Jwᵀ + damping·I)⁻¹ err`` with ``Jw`` the wrist's angular Jacobian
    (the tip's rows 3-5 of the spatial Jacobian; ``damping``, rad²). Then the wrist clipped
    to [``lo``, ``hi``] into ``goal``. ``links``…``identity``: the chain's packed FK;
    ``T`` (4, 4), ``J`` (6, n), ``F`` (n, 12), ``A`` (3, 3), ``x`` (3,) scratch. False (``goal``
    not written) if a solve fails (not for a proper chain: the damped matrix is positive
    definite)."""
    n = q.shape[0]
    err, M = local(3), local(3, 3)  # (in the frame: every tick, on each MTM)
    for _ in range(steps):
        tip_pose_row(links, modified, tool, identity, q, T, J, True, F)
        for i in range(3):  # R_base_goal · R_base_tipᵀ
            for m in range(3):
                M[i, m] = (R_base_goal[i, 0] * T[m, 0] + R_base_goal[i, 1] * T[m, 1]) + (
                    R_base_goal[i, 2] * T[m, 2]
                )
        err[0], err[1], err[2] = _rotation_vector(
            M[0, 0], M[0, 1], M[0, 2], M[1, 0], M[1, 1], M[1, 2], M[2, 0], M[2, 1], M[2, 2]
        )
        for i in range(3):  # Jw·Jwᵀ + damping·I
            for m in range(3):
                t = damping if i == m else 0.0
                for k in range(first, n):
                    t = t + J[3 + i, k] * J[3 + m, k]
                M[i, m] = t
        if not solve_square_into(M, err, A, x):
            return False
        for k in range(first, n):
            q[k] = q[k] + ((J[3, k] * x[0] + J[4, k] * x[1]) + J[5, k] * x[2])
    for k in range(first, n):
        goal[k - first] = min(max(q[k], lo[k - first]), hi[k - first])
    return True


_locked_wrist_goal = getattr(locked_wrist_goal, "dispatcher", locked_wrist_goal)


@jit
def wrist_lock_step(links, modified, tool, identity, q, first, R_base_goal, steps, damping,
                    lo, hi, T, J, F, A, x, goal, traj_q, traj_qd, v_max, a_max, ratio, dt,
                    q_out, qd_out) -> bool:  # fmt: skip
    """One tick of the MTM's orientation lock (``MTM._pre_step``): the wrist's goal
    (:func:`locked_wrist_goal`, arguments as there), then one step of the wrist's online
    trajectory from ``(traj_q, traj_qd)`` towards it within ``v_max·ratio`` and
    ``a_max·ratio`` (``trajectory.step_towards``) into ``q_out``, ``qd_out`` (rad, rad/s).
    False (nothing written but ``q``) when the goal's solve fails."""
    if not _locked_wrist_goal(links, modified, tool, identity, q, first, R_base_goal, steps,
                              damping, lo, hi, T, J, F, A, x, goal):  # fmt: skip
        return False
    step_towards_row(traj_q, traj_qd, goal, v_max, a_max, ratio, dt, q_out, qd_out)
    return True


@helper
def tracking_watch_row(qpos, qposadr, q_ref, idx, tolerance, effort_mode, starts, watched,
                       bad_since, t, first_bad, fault) -> bool:  # fmt: skip
    """:func:`tracking_bad` and :func:`tracking_fault_scalar` of many arms in one call (the
    live simulation's watch over all its arms at 1 kHz, ``sim/tracking_watch.py``, and the
    compiled control period of :mod:`davinci_sim.sim.live_kernel`):
    arm ``k`` owns entries ``starts[k]:starts[k + 1]`` of ``qposadr``, ``idx`` and
    ``tolerance``; only arms with ``watched[k]`` are checked. Writes ``bad_since[k]`` (s,
    nan: none bad), ``first_bad[k]`` (the arm's first bad joint, -1: none) and ``fault[k]``
    (FAULT now); returns whether any arm faults now."""
    any_fault = False
    for k in range(watched.shape[0]):
        fault[k] = False
        first_bad[k] = -1
        if not watched[k]:
            continue
        for m in range(starts[k], starts[k + 1]):
            j = idx[m]
            if abs(qpos[qposadr[m]] - q_ref[j]) > tolerance[m] and not effort_mode[j]:
                first_bad[k] = m - starts[k]
                break
        since, now = tracking_fault_scalar(first_bad[k] >= 0, bad_since[k], t)
        bad_since[k] = since
        fault[k] = now
        any_fault = any_fault or now
    return any_fault


tracking_watch = jit(tracking_watch_row)
""":func:`tracking_watch_row` compiled, for Python callers (:class:`TrackingWatch`)."""


def tracking_fault(bad, bad_since, t: float):
    """One tick of the tracking watch: ``bad`` (...) any joint of the arm is bad now;
    ``bad_since`` (...) when it became bad, s (nan: it is not). Returns the new
    ``(bad_since, fault)``: FAULT once bad for ``TRACKING_FAULT_TIME`` s."""
    if isinstance(bad, bool | np.bool_):  # one arm: the same rule on floats, faster
        return tracking_fault_scalar(bool(bad), float(bad_since), float(t))
    since = np.where(bad, np.fmin(bad_since, t), np.nan)
    return since, bad & (t - since >= TRACKING_FAULT_TIME)


@helper
def tracking_fault_scalar(bad: bool, bad_since: float, t: float) -> tuple[float, bool]:
    """:func:`tracking_fault` of one arm on floats (the live arm, and the compiled rows of
    :mod:`davinci_sim.sim.chunk_kernel`)."""
    if not bad:
        return math.nan, False
    since = t if math.isnan(bad_since) else min(bad_since, t)
    return since, t - since >= TRACKING_FAULT_TIME


@helper
def solve_square_into(J, b, A, out) -> bool:
    """:func:`joint_velocity`'s square solve for one arm, compiled: ``J⁻¹·b`` (J (n, n),
    b (n,)) into ``out`` by Gaussian elimination with partial pivoting (LAPACK's ``gesv``
    algorithm; the same result to rounding, not the same bits), ``A`` (n, n) scratch.
    False where the batch law would fall back to least squares: a zero pivot, a
    non-finite answer or one of magnitude ``_SINGULAR_QD`` or more (the caller then runs
    :func:`joint_velocity`)."""
    n = J.shape[0]
    for i in range(n):
        out[i] = b[i]
        for j in range(n):
            A[i, j] = J[i, j]
    for c in range(n):
        p, big = c, abs(A[c, c])
        for i in range(c + 1, n):
            if abs(A[i, c]) > big:
                p, big = i, abs(A[i, c])
        if big == 0.0:
            return False
        if p != c:
            for j in range(n):
                A[c, j], A[p, j] = A[p, j], A[c, j]
            out[c], out[p] = out[p], out[c]
        for i in range(c + 1, n):
            f = A[i, c] / A[c, c]
            for j in range(c + 1, n):
                A[i, j] = A[i, j] - f * A[c, j]
            out[i] = out[i] - f * out[c]
    for i in range(n - 1, -1, -1):
        t = out[i]
        for j in range(i + 1, n):
            t = t - A[i, j] * out[j]
        out[i] = t / A[i, i]
    for i in range(n):
        if not (abs(out[i]) < _SINGULAR_QD):  # (also false for NaN)
            return False
    return True


def within_limits(q: np.ndarray, qmin: np.ndarray, qmax: np.ndarray) -> np.ndarray:
    """(...) all joints of ``q`` (..., dof) within [qmin, qmax] (with ``LIMIT_SLACK``)."""
    return np.all((q >= qmin - LIMIT_SLACK) & (q <= qmax + LIMIT_SLACK), axis=-1)


@helper
def other_branch(q_ik, q_measured) -> bool:
    """Whether the PSM IK answer ``q_ik`` (6,) moves a wrist joint (roll, wrist pitch, wrist
    yaw: joints 3-5, dvrk.md 1.2) more than :data:`OTHER_BRANCH` rad from ``q_measured``
    (6,): a servo goal on the wrist's other branch, refused (the live servo, its compiled
    rows and :func:`other_branch_rows`)."""
    for i in range(3, 6):
        if abs(q_ik[i] - q_measured[i]) > OTHER_BRANCH:
            return True
    return False


@jit
def _other_branch_into(q_ik, q_measured, out) -> None:
    for r in range(q_ik.shape[0]):
        out[r] = other_branch(q_ik[r], q_measured[r])


def other_branch_rows(q_ik: np.ndarray, q_measured: np.ndarray) -> np.ndarray:
    """(n,) bool: :func:`other_branch` of each row of ``q_ik`` and ``q_measured`` (n, 6)."""
    out = np.empty(len(q_ik), dtype=bool)
    _other_branch_into(kernel_array(q_ik), kernel_array(q_measured), out)
    return out


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import, with the live arm's argument types,
    never in the 1 kHz loop (:mod:`davinci_sim.kinematics.jit`)."""
    i = np.zeros(1, dtype=np.int64)
    wrench_effort_row(np.zeros((6, 2)), np.eye(3), np.zeros(6), np.ones(2), np.empty(2))
    twist_row(np.eye(3), np.zeros((6, 2)), np.zeros(2), np.empty(6))
    b = np.zeros(1, dtype=bool)
    tracking_watch(np.zeros(1), i, np.zeros(1), i, np.ones(1), b, np.zeros(2, dtype=np.int64),
                   b, np.zeros(1), 0.0, i.copy(), b.copy())  # fmt: skip
    from davinci_sim.kinematics.arms import load_arm

    mtm = load_arm("MTMR").chain
    n = mtm.dof
    scratch = (np.empty((4, 4)), np.empty((6, n)), np.empty((n, 12)), np.empty((3, 3)))
    lo, hi = mtm.qmin[3:], mtm.qmax[3:]
    locked_wrist_goal(*fk._consts(mtm).packed, np.zeros(n), 3, np.eye(3), 1, 1e-4, lo, hi,
                      *scratch, np.empty(3), np.empty(n - 3))  # fmt: skip
    v, a = mtm.qmax[3:].copy(), mtm.qmax[3:].copy()  # (any positive limits)
    args = (*fk._consts(mtm).packed, np.zeros(n), 3, np.eye(3), 1, 1e-4, lo, hi, *scratch,
            np.empty(3), np.empty(n - 3), np.zeros(n - 3), np.zeros(n - 3), v, a, 1.0, 0.001,
            np.empty(n - 3), np.empty(n - 3))  # fmt: skip
    wrist_lock_step(*args)
    other_branch_rows(np.zeros((1, 6)), np.zeros((1, 6)))


warm(_warm_up)
