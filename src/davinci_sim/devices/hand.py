"""The operator's hand on a simulated MTM handle: a 6-D spring-damper towards a target pose.

Pure law (:func:`hand_wrenches`, one compiled kernel over rows: the live
:class:`~davinci_sim.devices.SimulatedMTM` is a batch of one, the study's batch engine a batch
of n trials); :class:`~davinci_sim.devices.SimulatedMTM` applies the result to the handle body
as an external force, so the MTM moves through its own dynamics and the
haptic wrench the MTM renders pushes back against the hand, as on the real console.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from davinci_sim.geometry import so3
from davinci_sim.geometry.so3 import rotate_rows
from davinci_sim.kinematics.jit import helper, jit, warm


@dataclass(frozen=True)
class HandImpedance:
    """Stiffness and damping of the simulated hand (our choices, see each field).

    The values keep the explicit 1 ms integration of the external force stable for the MTM's
    small wrist inertias and feel like a relaxed grip: 4 N moves the handle 1 cm off target.
    """

    stiffness: float = 400.0
    """Translational stiffness, N/m."""
    damping: float = 10.0
    """Translational damping, N·s/m."""
    rotational_stiffness: float = 0.3
    """Rotational stiffness, N·m/rad (only when the hand holds an orientation)."""
    rotational_damping: float = 0.004
    """Rotational damping, N·m·s/rad."""
    max_force: float = 20.0
    """A hand pushes at most this hard, N."""
    max_torque: float = 0.5
    """A hand twists at most this hard, N·m."""
    mass: float = 0.0
    """Endpoint mass of the hand and arm, kg, added to the handle while the hand holds it:
    a held handle moves with the limb's inertia, not only its own few grams (0: a hand
    without inertia, e.g. a scripted test hand)."""

    def __post_init__(self) -> None:
        for name in (
            "stiffness",
            "damping",
            "rotational_stiffness",
            "rotational_damping",
            "max_force",
            "max_torque",
            "mass",
        ):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise ValueError(
                    f"HandImpedance.{name} must be a finite number >= 0, got {value!r}"
                )


def hand_wrenches(
    T_target: np.ndarray | None,
    T_tip: np.ndarray,
    twist_tip: np.ndarray,
    stiffness,
    damping,
    impedance: HandImpedance,
    *,
    hold_orientation: bool = True,
) -> np.ndarray:
    """Wrenches (n, 6), force then torque, that n hands apply at their handle tips, in the
    frame of the poses (HRSV on the console).

    ``F = K·(p_target − p) − D·v`` and, if ``hold_orientation``,
    ``τ = K_r·rotvec(R_target·Rᵀ) − D_r·ω`` (else only ``−D_r·ω``), each clamped to the
    hand's maximum. ``T_target`` None means the hands rest on the handles without pulling:
    damping only. ``v`` and ``ω`` are the handle's motion relative to the hand's own: a hand
    whose target moves (the live rate input's, ``SimulatedMTM.move_hand``'s velocity)
    passes the handle's twist less the target's, so that its damping does not hold back a
    handle moving with it (a limb's impedance acts about its planned motion); the study's
    trainees pass the handle's twist, their hands' calibrated law.

    Args:
        T_target: target poses (n, 4, 4), m, or None.
        T_tip: handle tip poses (n, 4, 4), m.
        twist_tip: handle tip twists (n, 6), m/s then rad/s, relative to the hand's motion
            where it moves (see above).
        stiffness, damping: each hand's translational ``K`` (N/m) and ``D`` (N·s/m), (n,)
            (a study's trials differ; the live :class:`~davinci_sim.devices.SimulatedMTM`
            passes its ``impedance``'s, a batch of one).
        impedance: the rotational values and the limits.
        hold_orientation: False: no torque towards the target orientation.
    """
    # New C-ordered writable arrays: the kernel's one compiled signature, its warm-up's (a
    # read-only input, such as the arm's read-only pose, would compile another in the loop).
    tip = np.array(T_tip, dtype=float, order="C")
    n = tip.shape[0]
    target = tip if T_target is None else np.array(T_target, dtype=float, order="C")
    out = np.empty((n, 6))
    _hand_rows(
        target,
        T_target is not None,
        bool(hold_orientation),
        tip,
        np.array(twist_tip, dtype=float, order="C"),
        np.array(stiffness, dtype=float, order="C"),
        np.array(damping, dtype=float, order="C"),
        float(impedance.rotational_stiffness),
        float(impedance.rotational_damping),
        float(impedance.max_force),
        float(impedance.max_torque),
        out,
    )
    return out


@jit
def _hand_rows(target, pull, hold, tip, twist, K, D, kr, dr, max_force, max_torque, out):
    """Row by row: the spring-damper of :func:`hand_wrenches`, clamped. Elementwise, so a
    hand gets the same bits alone or in a batch."""
    for i in range(tip.shape[0]):
        k, d = K[i], D[i]
        f0, f1, f2 = -d * twist[i, 0], -d * twist[i, 1], -d * twist[i, 2]
        t0, t1, t2 = -dr * twist[i, 3], -dr * twist[i, 4], -dr * twist[i, 5]
        if pull:
            f0 += k * (target[i, 0, 3] - tip[i, 0, 3])
            f1 += k * (target[i, 1, 3] - tip[i, 1, 3])
            f2 += k * (target[i, 2, 3] - tip[i, 2, 3])
            if hold:
                e0, e1, e2 = _rotation_error(target[i], tip[i])
                t0 += kr * e0
                t1 += kr * e1
                t2 += kr * e2
        n = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
        if n > max_force:
            s = max_force / n
            f0, f1, f2 = f0 * s, f1 * s, f2 * s
        n = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        if n > max_torque:
            s = max_torque / n
            t0, t1, t2 = t0 * s, t1 * s, t2 * s
        out[i, 0], out[i, 1], out[i, 2] = f0, f1, f2
        out[i, 3], out[i, 4], out[i, 5] = t0, t1, t2


_rotation_vector = helper(so3.rotation_vector_floats)


@helper
def _rotation_error(target, tip):
    """Rotation vector (rad) of ``R_target·R_tipᵀ`` (the rotations of two 4x4 poses)."""
    a, b, c = target[0, 0], target[0, 1], target[0, 2]
    d, e, f = target[1, 0], target[1, 1], target[1, 2]
    g, h, k = target[2, 0], target[2, 1], target[2, 2]
    u0, u1, u2 = tip[0, 0], tip[0, 1], tip[0, 2]
    v0, v1, v2 = tip[1, 0], tip[1, 1], tip[1, 2]
    w0, w1, w2 = tip[2, 0], tip[2, 1], tip[2, 2]
    return _rotation_vector(
        a * u0 + b * u1 + c * u2, a * v0 + b * v1 + c * v2, a * w0 + b * w1 + c * w2,
        d * u0 + e * u1 + f * u2, d * v0 + e * v1 + f * v2, d * w0 + e * w1 + f * w2,
        g * u0 + h * u1 + k * u2, g * v0 + h * v1 + k * v2, g * w0 + h * w1 + k * w2,
    )  # fmt: skip


def handle_xfrc(
    wrench_hrsv: np.ndarray,
    p_hrsv_tip: np.ndarray,
    R_world_hrsv: np.ndarray,
    p_world_hrsv: np.ndarray,
    p_world_com: np.ndarray,
) -> np.ndarray:
    """MuJoCo's ``xfrc_applied`` (..., 6: force N, torque N·m, world axes, at the body's
    centre of mass ``p_world_com`` (..., 3), m) of a hand wrench ``wrench_hrsv`` (..., 6,
    HRSV axes) acting at the handle tip ``p_hrsv_tip`` (..., 3): the force moved from the
    tip to the centre of mass adds its moment. ``R_world_hrsv`` (3, 3), ``p_world_hrsv``
    (3,) place HRSV in the world. Elementwise (the same bits in any batch, see
    :func:`~davinci_sim.geometry.so3.rotate_rows`)."""
    f = rotate_rows(R_world_hrsv, wrench_hrsv[..., :3])
    lever = rotate_rows(R_world_hrsv, p_hrsv_tip) + p_world_hrsv - p_world_com
    if f.ndim == 1:  # one hand: the same operations on floats
        (fx, fy, fz), (lx, ly, lz) = f.tolist(), lever.tolist()
        tx, ty, tz = rotate_rows(R_world_hrsv, wrench_hrsv[3:]).tolist()
        mx, my, mz = ly * fz - lz * fy, lz * fx - lx * fz, lx * fy - ly * fx
        return np.array([fx, fy, fz, tx + mx, ty + my, tz + mz])
    lx, ly, lz = lever[..., 0:1], lever[..., 1:2], lever[..., 2:3]
    fx, fy, fz = f[..., 0:1], f[..., 1:2], f[..., 2:3]
    # lever × f, written out (numpy's cross computes the same products, slower)
    moment = np.concatenate([ly * fz - lz * fy, lz * fx - lx * fz, lx * fy - ly * fx], axis=-1)
    return np.concatenate([f, rotate_rows(R_world_hrsv, wrench_hrsv[..., 3:]) + moment], axis=-1)


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import, as
    :mod:`~davinci_sim.kinematics.fk_compiled` does: never in the middle of a 1 kHz loop.
    (The simulated hand's first tick would otherwise compile it in the simulation's thread.)"""
    one = np.ones(1)
    hand_wrenches(None, np.eye(4)[None], np.zeros((1, 6)), one, one, HandImpedance())


warm(_warm_up)
