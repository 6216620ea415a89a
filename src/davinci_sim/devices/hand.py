"""The operator's hand on a simulated MTM handle: a 6-D spring-damper towards a target pose.

Pure law (:func:`hand_wrench`); :class:`~davinci_sim.devices.SimulatedMTM` applies the result
to the handle body as an external force, so the MTM moves through its own dynamics and the
haptic wrench the MTM renders pushes back against the hand, as on the real console.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from davinci_sim.devices.safety import limit_norms
from davinci_sim.geometry import so3
from davinci_sim.geometry.so3 import rotate_rows, rotation_vectors


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


def hand_wrench(
    T_target: np.ndarray | None,
    T_tip: np.ndarray,
    twist_tip: np.ndarray,
    impedance: HandImpedance,
    *,
    hold_orientation: bool = True,
) -> np.ndarray:
    """Wrench (6,) the hand applies at the handle tip, in the frame of the poses.

    ``F = K·(p_target − p) − D·v`` and, if ``hold_orientation``,
    ``τ = K_r·rotvec(R_target·Rᵀ) − D_r·ω`` (else only ``−D_r·ω``), each clamped to the
    hand's maximum. ``T_target`` None means the hand rests on the handle without pulling:
    damping only.
    """
    vx, vy, vz, wx, wy, wz = np.asarray(twist_tip, dtype=float).tolist()
    d, dr = impedance.damping, impedance.rotational_damping
    f = [-d * vx, -d * vy, -d * vz]
    tau = [-dr * wx, -dr * wy, -dr * wz]
    if T_target is not None:
        k = impedance.stiffness
        f = [f[i] + k * (float(T_target[i, 3]) - float(T_tip[i, 3])) for i in range(3)]
        if hold_orientation:
            err = so3.rotation_vector(T_target[:3, :3] @ T_tip[:3, :3].T).tolist()
            kr = impedance.rotational_stiffness
            tau = [tau[i] + kr * err[i] for i in range(3)]
    f = _clamp(f, impedance.max_force)
    tau = _clamp(tau, impedance.max_torque)
    return np.array(f + tau)


def hand_wrenches(
    T_target: np.ndarray,
    T_tip: np.ndarray,
    twist_tip: np.ndarray,
    stiffness,
    damping,
    impedance: HandImpedance,
    *,
    hold_orientation: bool = True,
) -> np.ndarray:
    """:func:`hand_wrench` for a batch of hands ``(n, ...)`` (a study's trials), each with its
    own translational ``stiffness`` (N/m) and ``damping`` (N·s/m), (n,); the rotational
    values and the limits are ``impedance``'s. Poses ``(n, 4, 4)``, twists ``(n, 6)``; returns
    ``(n, 6)``, force then torque, in the frame of the poses."""
    twist = np.asarray(twist_tip, dtype=float)
    k = np.asarray(stiffness, dtype=float)[:, None]
    d = np.asarray(damping, dtype=float)[:, None]
    f = k * (T_target[:, :3, 3] - T_tip[:, :3, 3]) - d * twist[:, :3]
    tau = -impedance.rotational_damping * twist[:, 3:]
    if hold_orientation:
        R_error = T_target[:, :3, :3] @ np.swapaxes(T_tip[:, :3, :3], -1, -2)
        tau = tau + impedance.rotational_stiffness * rotation_vectors(R_error)
    return np.concatenate(
        [limit_norms(f, impedance.max_force), limit_norms(tau, impedance.max_torque)], axis=1
    )


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


def _clamp(v: list[float], limit: float) -> list[float]:
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if n > limit:
        return [x * (limit / n) for x in v]
    return v
