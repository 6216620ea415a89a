"""ECM closed-form inverse kinematics (dvrk.md 1.8, ``robManipulatorECM``).

The goal ``T_rcm_tip`` is the endoscope tip in the RCM frame (ECM chain base, dvrk.md 1.4).
Steps, as the dVRK does them: remove the endoscope tooltip offset to get the goal of frame 4;
the shaft points from the RCM to the goal, so yaw and pitch follow from the direction and the
insertion from the distance (q₃ = |p| − 0.0007 for the Classic ECM); the goal orientation is
rotated (minimal rotation) so its z axis lies along the shaft; the roll is the remaining angle
about z. A 4-DOF arm cannot reach every orientation, so this projection is part of the answer.

The dVRK writes yaw and pitch as q₁ = asin(x/√(x²+z²)), q₂ = −asin(y/|p|), which assumes
exact ±90° twists. The JSON alphas are ±1.5708 (3.7e-6 rad off), so here yaw and pitch come
from :func:`~davinci_sim.kinematics.rcm.shaft_angles`, exact for any twist; they agree with
the dVRK formulas to ~4e-6 rad and round-trip through FK to machine precision.

Failure conditions (dVRK): goal above the RCM (z > 0, Classic check), goal within 0.1 mm of
the RCM, a joint limit hit (the clamped values are returned). After solving, the insertion is
raised to at least 40 mm (dvrk.md 1.7).
"""

from __future__ import annotations

import math

from davinci_sim.geometry.so3 import mat3_mul as _mul
from davinci_sim.kinematics.chain import DHChain
from davinci_sim.kinematics.fk import fk_tuple
from davinci_sim.kinematics.ik_base import (
    LIMIT_SLACK,
    POSITION_TOLERANCE,
    ROTATION_TOLERANCE,
    IKResult,
    failed_result,
    goal_and_seed,
    make_result,
    pose_errors,
    wrap_angle,
)
from davinci_sim.kinematics.rcm import rxrz as _rxrz
from davinci_sim.kinematics.rcm import shaft_angles, tool_origin

#: dvrk.md 1.8: goals closer than this to the RCM fail (m).
MIN_GOAL_DISTANCE_FROM_RCM = 1e-4
#: dvrk.md 1.7: the ECM IK raises the insertion to at least this (m).
MIN_INSERTION = 0.04


def _check_ecm_chain(chain: DHChain) -> None:
    j = chain.joints
    types = tuple(x.joint_type for x in j)
    ok = (
        chain.convention == "modified"
        and types == ("revolute", "revolute", "prismatic", "revolute")
        and all(x.a == 0.0 for x in j)
        and j[0].d == 0.0
        and j[1].d == 0.0
        and j[3].alpha == 0.0
    )
    if not ok:
        raise ValueError(f"{chain.name}: not a Classic ECM geometry (modified DH R-R-P-R, RCM)")


def _align_z(R: tuple[float, ...], z: tuple[float, float, float]) -> tuple[float, ...]:
    """R pre-multiplied by the minimal rotation taking its z column onto unit vector ``z``."""
    gx, gy, gz = R[2], R[5], R[8]
    kx, ky, kz = gy * z[2] - gz * z[1], gz * z[0] - gx * z[2], gx * z[1] - gy * z[0]
    c = gx * z[0] + gy * z[1] + gz * z[2]
    if c <= -1.0 + 1e-12:
        # Opposite directions: turn by π about the goal's x axis (⟂ to both).
        ux, uy, uz = R[0], R[3], R[6]
        A = (
            2 * ux * ux - 1, 2 * ux * uy, 2 * ux * uz,
            2 * uy * ux, 2 * uy * uy - 1, 2 * uy * uz,
            2 * uz * ux, 2 * uz * uy, 2 * uz * uz - 1,
        )  # fmt: skip
        return _mul(A, R)
    # Rodrigues with k = g × z (|k| = sin φ): A = I + [k]× + [k]×² / (1 + cos φ).
    f = 1.0 / (1.0 + c)
    A = (
        1.0 - f * (ky * ky + kz * kz), -kz + f * kx * ky, ky + f * kx * kz,
        kz + f * kx * ky, 1.0 - f * (kx * kx + kz * kz), -kx + f * ky * kz,
        -ky + f * kx * kz, kx + f * ky * kz, 1.0 - f * (kx * kx + ky * ky),
    )  # fmt: skip
    return _mul(A, R)


def ecm_ik_closed_form(
    chain: DHChain,
    T_rcm_tip,
    q_seed,
    *,
    position_tolerance: float = POSITION_TOLERANCE,
    rotation_tolerance: float = ROTATION_TOLERANCE,
) -> IKResult:
    """Closed-form ECM IK (module docstring), with the dVRK failure rules and 40 mm clamp.

    Args:
        chain: the ECM chain (yaw, pitch, insertion, roll + endoscope tooltip offset).
        T_rcm_tip: goal pose of the endoscope tip in the RCM frame, (4, 4), m.
        q_seed: current joints (4,), rad / m; picks the yaw/pitch branch when two exist.
        position_tolerance, rotation_tolerance: acceptance of the FK check (m, rad).

    Returns:
        IKResult. ``adjusted`` is set when the orientation had to be projected (its z axis was
        not along the shaft) or the insertion was raised to 40 mm; the errors then measure it.

    Raises:
        ValueError: on a badly shaped or non-finite goal or seed, or a non-ECM chain.
    """
    _check_ecm_chain(chain)
    goal, seed = goal_and_seed(chain, T_rcm_tip, q_seed)
    T = chain.T_last_tip
    Rt_T = tuple(float(T[c, r]) for r in range(3) for c in range(3))
    R4, px, py, pz = tool_origin(goal, Rt_T, [float(x) for x in T[:3, 3]])
    if pz > 0.0:
        return failed_result(chain, seed, goal, f"goal above the RCM (z = {pz:.4g} m > 0)")
    dist = math.sqrt(px * px + py * py + pz * pz)
    if dist < MIN_GOAL_DISTANCE_FROM_RCM:
        return failed_result(
            chain, seed, goal, f"goal {dist * 1e3:.3g} mm from the RCM, closer than 0.1 mm"
        )
    j = chain.joints
    ca = tuple(math.cos(x.alpha) for x in j)
    sa = tuple(math.sin(x.alpha) for x in j)
    t0 = tuple(float(x.theta + x.offset) if x.is_revolute else float(x.theta) for x in j)
    z3 = (px / dist, py / dist, pz / dist)
    q3 = dist - (j[2].d + j[2].offset + j[3].d)
    branches = shaft_angles(ca, sa, z3)
    if not branches:
        return failed_result(chain, seed, goal, "no yaw/pitch reaches the goal direction")

    def shaft_key(b: tuple[float, float]) -> tuple[bool, float]:
        q1, q2 = wrap_angle(b[0] - t0[0]), wrap_angle(b[1] - t0[1])
        out = not (j[0].qmin <= q1 <= j[0].qmax and j[1].qmin <= q2 <= j[1].qmax)
        return out, (q1 - seed[0]) ** 2 + (q2 - seed[1]) ** 2

    th1, th2 = min(branches, key=shaft_key)
    R3 = _mul(_mul(_rxrz(ca[0], sa[0], th1), _rxrz(ca[1], sa[1], th2)), _rxrz(ca[2], sa[2], t0[2]))
    R4a = _align_z(R4, z3)
    # R₃ᵀR₄ = Rz(θ₄) once the goal z is along the shaft (α₄ = 0).
    M00 = R3[0] * R4a[0] + R3[3] * R4a[3] + R3[6] * R4a[6]
    M10 = R3[1] * R4a[0] + R3[4] * R4a[3] + R3[7] * R4a[6]
    q = [
        wrap_angle(th1 - t0[0]),
        wrap_angle(th2 - t0[1]),
        q3,
        wrap_angle(math.atan2(M10, M00) - t0[3]),
    ]
    # Check the exact solution against the projected goal before any clamping.
    goal_a = (*_mul(R4a, tuple(float(T[r, c]) for r in range(3) for c in range(3))), *goal[9:])
    dp, dr = pose_errors(fk_tuple(chain, q), goal_a)
    reasons = []
    if dp > position_tolerance or dr > rotation_tolerance:
        reasons.append(f"pose not reached: position error {dp:.3g} m, rotation error {dr:.3g} rad")
    adjustments = []
    gx, gy, gz = R4[2], R4[5], R4[8]
    tilt = math.atan2(
        math.hypot(gy * z3[2] - gz * z3[1], gz * z3[0] - gx * z3[2], gx * z3[1] - gy * z3[0]),
        gx * z3[0] + gy * z3[1] + gz * z3[2],
    )
    if tilt > rotation_tolerance:
        adjustments.append(f"orientation projected: goal z axis {tilt:.3g} rad off the shaft")
    if q[2] < MIN_INSERTION:
        adjustments.append(f"insertion {q[2]:.4g} m raised to {MIN_INSERTION} m")
        q[2] = MIN_INSERTION
    clamped = []
    for i, x in enumerate(j):
        if not x.qmin - LIMIT_SLACK <= q[i] <= x.qmax + LIMIT_SLACK:
            clamped.append(f"{x.name}={q[i]:.6g} clamped to [{x.qmin:.6g}, {x.qmax:.6g}]")
            q[i] = min(max(q[i], x.qmin), x.qmax)
    if clamped:
        reasons.append("joint limits: " + ", ".join(clamped))
    return make_result(
        chain,
        q,
        goal,
        iterations=0,
        failure="; ".join(reasons) or None,
        adjusted="; ".join(adjustments) or None,
        position_tolerance=position_tolerance,
        rotation_tolerance=rotation_tolerance,
    )
