"""The simulated MTM's per-tick read and wrench as compiled calls (numba only: imported where
:data:`davinci_sim.kinematics.jit.ENABLED`).

:func:`hand_read_row` is ``SimulatedMTM._read`` after the handle's pose: the handle's twist
(``arm_laws.twist_row``, as ``measured_cv``), the hand's spring-damper
(``hand._hand_rows``, as ``hand_wrenches``) plus a push, and that wrench as MuJoCo's
``xfrc_applied`` on the handle body (``hand.handle_xfrc``'s float form). The same compiled
laws and the same float operations in the same order as the Python path, so the same bits
(``tests/devices/test_device_row.py``); the Python path stays the fallback and the oracle.

:func:`render_row` is the haptic wrench's way to the MTM's joints after the haptic loop
summed it: the device's clamp (``WrenchLimiter.limit_checked``) and ``spatial/servo_cf``'s
``Jᵀ·w`` (``arm_laws.wrench_effort_row``), one call instead of three layers of Python.
"""

from __future__ import annotations

import numba
import numpy as np

from davinci_sim.devices.hand import _hand_rows
from davinci_sim.devices.safety import _clamp_rows
from davinci_sim.kinematics.jit import helper
from davinci_sim.kinematics.scratch import local
from davinci_sim.sim.arm_laws import twist_row, wrench_effort_row

_twist = twist_row.dispatcher
_hand = _hand_rows.dispatcher
_clamp = _clamp_rows.dispatcher
_effort = wrench_effort_row.dispatcher


@numba.njit(cache=True, nogil=True)
def hand_read_row(
    T_hrsv_tip, R_hrsv_base, J, qd, hand_on, target, velocity, pull, hold, applied, impedance,
    push, R_world_hrsv, p_world_hrsv, p_world_com, twist_out, wrench_out, xfrc_out,
):  # fmt: skip
    """One tick of a simulated MTM's reading.

    ``T_hrsv_tip`` (4, 4) the handle's pose (``measured_cp``), ``R_hrsv_base`` the MTM base's
    orientation in HRSV, ``J`` (6, dof) the spatial Jacobian, ``qd`` (dof,) the joint
    velocities: ``twist_out`` (6,) the handle's twist in HRSV axes, m/s and rad/s.

    With ``hand_on`` (the hand holds the handle), a push (``push`` (6,) non-zero) or a wrench
    applied at the last tick (``applied``): ``wrench_out`` = ``push`` + the hand's wrench
    (towards ``target`` (4, 4) when ``pull``, holding its orientation when ``hold``, its
    damping on the handle's twist relative to the target's ``velocity`` (6,), HRSV, which
    the read uses up: zeroed, as ``SimulatedMTM._read`` does; ``impedance`` (6,): stiffness
    N/m, damping N·s/m, rotational stiffness and damping, maximum force N and torque N·m),
    HRSV axes, and ``xfrc_out`` (6,) that wrench moved to
    the handle body's centre of mass ``p_world_com``, world axes (HRSV placed by
    ``R_world_hrsv``, ``p_world_hrsv``). Returns whether the wrench was computed (else
    ``wrench_out`` and ``xfrc_out`` are untouched)."""
    _twist(R_hrsv_base, J, qd, twist_out)
    moving = local(6)  # (the target's velocity, used up by this read)
    for i in range(6):
        moving[i] = velocity[i]
        velocity[i] = 0.0
    pushing = False
    for i in range(6):
        pushing = pushing or push[i] != 0.0
    if not (hand_on or pushing or applied):
        return False
    for i in range(6):
        wrench_out[i] = push[i]
    if hand_on:
        tip, goal = local(1, 4, 4), local(1, 4, 4)  # (in the frame: every tick)
        for i in range(4):
            for m in range(4):
                tip[0, i, m] = T_hrsv_tip[i, m]
                goal[0, i, m] = target[i, m] if pull else T_hrsv_tip[i, m]
        twist = local(1, 6)
        for i in range(6):
            twist[0, i] = twist_out[i] - moving[i]  # (relative to the hand's motion)
        w = local(1, 6)
        _hand(goal, pull, hold, tip, twist, impedance[0:1], impedance[1:2], impedance[2],
              impedance[3], impedance[4], impedance[5], w)  # fmt: skip
        for i in range(6):
            wrench_out[i] = wrench_out[i] + w[0, i]
    _xfrc_into(wrench_out, T_hrsv_tip, R_world_hrsv, p_world_hrsv, p_world_com, xfrc_out)
    return True


@helper
def _xfrc_into(wrench, T_hrsv_tip, R_world_hrsv, p_world_hrsv, p_world_com, xfrc_out):
    """``hand.handle_xfrc`` of one hand on floats: the wrench's force and torque in world
    axes, the force's moment about the centre of mass ``p_world_com`` (lever × f) added."""
    R = R_world_hrsv
    f, lever = local(3), local(3)
    x, y, z = wrench[0], wrench[1], wrench[2]
    px, py, pz = T_hrsv_tip[0, 3], T_hrsv_tip[1, 3], T_hrsv_tip[2, 3]
    u, v, s = wrench[3], wrench[4], wrench[5]
    for i in range(3):
        f[i] = x * R[i, 0] + y * R[i, 1] + z * R[i, 2]
        lever[i] = (px * R[i, 0] + py * R[i, 1] + pz * R[i, 2]) + p_world_hrsv[i] - p_world_com[i]
        xfrc_out[3 + i] = u * R[i, 0] + v * R[i, 1] + s * R[i, 2]
        xfrc_out[i] = f[i]
    xfrc_out[3] = xfrc_out[3] + (lever[1] * f[2] - lever[2] * f[1])
    xfrc_out[4] = xfrc_out[4] + (lever[2] * f[0] - lever[0] * f[2])
    xfrc_out[5] = xfrc_out[5] + (lever[0] * f[1] - lever[1] * f[0])


@numba.njit(cache=True, nogil=True)
def hand_rows(
    T_target, T_tip, twist, K, D, impedance, push, R_world_hrsv, p_world_hrsv, p_world_com,
    xfrc_out,
):  # fmt: skip
    """The study's hands on their handles, every row: each hand's spring-damper towards its
    target pose ``T_target`` (n, 4, 4) holding its orientation (``hand._hand_rows``, as
    ``hand_wrenches``; ``K``, ``D`` (n,) the limbs' stiffness and damping, ``impedance``
    (4,): rotational stiffness and damping, maximum force and torque), plus ``push`` (n, 3)
    on the force, moved to the handle bodies' centres of mass (``p_world_com`` (n, 3)) as
    ``xfrc_out`` (n, 6), world axes: ``handle_xfrc``'s floats, row by row."""
    n = T_tip.shape[0]
    w = np.empty((n, 6))
    _hand(T_target, True, True, T_tip, twist, K, D, impedance[0], impedance[1], impedance[2],
          impedance[3], w)  # fmt: skip
    for r in range(n):
        for i in range(3):
            w[r, i] = w[r, i] + push[r, i]
        _xfrc_into(w[r], T_tip[r], R_world_hrsv, p_world_hrsv, p_world_com[r], xfrc_out[r])


@numba.njit(cache=True, nogil=True)
def render_row(wrench, previous, steps, T_ref_base, J, ftmax, wrench_out, tau_out):
    """One tick of a simulated MTM rendering a checked wrench (``spatial/servo_cf``).

    ``wrench`` (6,) finite, N and N·m in HRSV axes, clamped as the device's limiter does
    from the last wrench let through ``previous`` (6,) with ``steps`` (4,): the maximum
    force N and torque N·m, and the largest force and torque change over one tick (rate ×
    dt), into ``wrench_out`` (6,); then ``tau_out`` (dof,) the joint efforts (N·m, N) that
    render it: ``Jᵀ·w`` with the spatial Jacobian ``J`` (6, dof) in the MTM's base, the
    wrench's axes turned from HRSV by the base frame ``T_ref_base`` (4, 4, the base in
    HRSV), clamped to ``ftmax`` (dof,). Returns whether the clamp changed the wrench (by
    more than 1e-12 in a component: the limiter's ``active``)."""
    _clamp(wrench.reshape(1, 6), previous.reshape(1, 6), steps[0], steps[1], steps[2],
           steps[3], wrench_out.reshape(1, 6))  # fmt: skip
    active = False
    for i in range(6):
        active = active or abs(wrench_out[i] - wrench[i]) > 1e-12
    R_base_ref = local(3, 3)  # (the wrench's axes in the base: T_ref_base's rotation ᵀ)
    for i in range(3):
        for j in range(3):
            R_base_ref[i, j] = T_ref_base[j, i]
    _effort(J, R_base_ref, wrench_out, ftmax, tau_out)
    return active


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import with the live device's one signature:
    the pose, Jacobian and joint velocities read-only or new (``Arm._measured_T``,
    ``_measured_kinematics``, ``_qd``), the base rotation a view of the base frame."""

    def readonly(a: np.ndarray) -> np.ndarray:
        a.setflags(write=False)
        return a

    # (the base frame read-only as the simulation caches it, or writable as a user's)
    for T_ref_base in (readonly(np.eye(4)), np.eye(4)):
        hand_read_row(readonly(np.eye(4)), T_ref_base[:3, :3], readonly(np.zeros((6, 7))),
                      np.zeros(7), True, np.eye(4), np.zeros(6), True, True, False, np.ones(6),
                      np.zeros(6), np.eye(3), np.zeros(3), np.zeros(3), np.empty(6),
                      np.empty(6), np.empty(6))  # fmt: skip
    e2, e3, e4 = np.zeros((0, 3)), np.zeros((0, 6)), np.zeros((0, 4, 4))
    hand_rows(e4, e4, e3, np.zeros(0), np.zeros(0), np.ones(4), e2, np.eye(3), np.zeros(3), e2,
              np.empty((0, 6)))  # fmt: skip
    # (the MTM's base frame and the chain's joint limits read-only or not)
    for T_ref_base in (readonly(np.eye(4)), np.eye(4)):
        for ftmax in (readonly(np.ones(7)), np.ones(7)):
            render_row(np.zeros(6), np.zeros(6), np.ones(4), T_ref_base,
                       readonly(np.zeros((6, 7))), ftmax, np.empty(6), np.empty(7))  # fmt: skip
