"""The MTM's Cartesian impedance (``servo_ci``, dvrk.md 2.2): gains and the wrench they give.

The dVRK's impedance controller (sawControllers, used by ``mtsIntuitiveResearchKitArm``
``servo_ci``) renders, along each axis of a frame of its own, a spring-damper with separate
gains on each side of a point: the *force* frame (``force_orientation`` at ``force_position``)
for the handle's position, the *torque* frame (``torque_orientation``) for its orientation.
Per axis, with ``e`` the position (or rotation-vector) error of the handle from the frame and
``v`` its velocity in the frame's axes: on the positive side (``e > 0``) ``e`` shrinks by the
deadband (not below 0) and the force is ``p·e + d·v + bias`` with the positive gains; on the
other side the same with the negative gains. The force and torque are then expressed back in
the reference frame (``measured_cp``'s: HRSV for MTMs) and applied at the handle. The gains
are signed as the dVRK's: a spring pulling back has ``p < 0`` (N/m, N·m/rad), a damper
``d < 0`` (N·s/m, N·m·s/rad).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from davinci_sim.geometry import so3

#: Largest stiffness (N/m or N·m/rad), damping (N·s/m or N·m·s/rad) and deadband (m or rad)
#: of an impedance command: far beyond what an MTM can render (its motors give a few N at the
#: handle, dvrk.md 1.5; the dVRK's examples use 200-500 N/m), so a bigger value is an error.
MAX_STIFFNESS = 1e5
MAX_DAMPING = 1e4
MAX_DEADBAND = 10.0
#: Largest bias, N and N·m (the bounds of a ``servo_cf`` wrench, sim.validation).
MAX_BIAS_FORCE = 100.0
MAX_BIAS_TORQUE = 10.0


def _zeros() -> np.ndarray:
    return np.zeros(3)


@dataclass(frozen=True, eq=False)
class HalfPlaneGains:
    """Gains of one side of the three axes (``crtk_msgs/CartesianImpedanceHalfPlaneGains``):
    each (3,) along x, y, z of the force or torque frame."""

    p: np.ndarray = field(default_factory=_zeros)
    d: np.ndarray = field(default_factory=_zeros)
    bias: np.ndarray = field(default_factory=_zeros)
    deadband: np.ndarray = field(default_factory=_zeros)


@dataclass(frozen=True, eq=False)
class CartesianImpedance:
    """A ``servo_ci`` command (``crtk_msgs/CartesianImpedance``), in the arm's reference frame
    (``measured_cp``'s): the force frame's origin ``force_position`` (3,) m and axes
    ``force_orientation`` (3, 3), the torque frame's axes ``torque_orientation`` (3, 3), and
    the gains of each side. All zero by default: no force."""

    force_position: np.ndarray = field(default_factory=_zeros)
    force_orientation: np.ndarray = field(default_factory=lambda: np.eye(3))
    torque_orientation: np.ndarray = field(default_factory=lambda: np.eye(3))
    position_positive: HalfPlaneGains = field(default_factory=HalfPlaneGains)
    position_negative: HalfPlaneGains = field(default_factory=HalfPlaneGains)
    orientation_positive: HalfPlaneGains = field(default_factory=HalfPlaneGains)
    orientation_negative: HalfPlaneGains = field(default_factory=HalfPlaneGains)


def _half_planes(
    error: np.ndarray, velocity: np.ndarray, pos: HalfPlaneGains, neg: HalfPlaneGains
) -> np.ndarray:
    positive = error > 0.0
    e = np.where(
        positive,
        np.maximum(error - np.abs(pos.deadband), 0.0),
        np.minimum(error + np.abs(neg.deadband), 0.0),
    )
    p = np.where(positive, pos.p, neg.p)
    d = np.where(positive, pos.d, neg.d)
    bias = np.where(positive, pos.bias, neg.bias)
    return e * p + velocity * d + bias


def impedance_wrench(
    gains: CartesianImpedance, T_ref_tip: np.ndarray, twist_ref: np.ndarray
) -> np.ndarray:
    """The wrench (6: N then N·m, at the tip, in the reference frame's axes) that ``gains``
    give for the handle at ``T_ref_tip`` (4, 4) moving at ``twist_ref`` (6: m/s then rad/s,
    reference axes); see the module docstring."""
    R_f, R_t = gains.force_orientation, gains.torque_orientation
    error = R_f.T @ (T_ref_tip[:3, 3] - gains.force_position)
    force = R_f @ _half_planes(error, R_f.T @ twist_ref[:3], gains.position_positive,
                               gains.position_negative)  # fmt: skip
    rotation_error = so3.rotation_vector(R_t.T @ T_ref_tip[:3, :3])
    torque = R_t @ _half_planes(rotation_error, R_t.T @ twist_ref[3:],
                                gains.orientation_positive, gains.orientation_negative)  # fmt: skip
    return np.concatenate([force, torque])


def _array(value, shape: tuple[int, ...]) -> np.ndarray | None:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        return None
    return a if a.shape == shape and np.isfinite(a).all() else None


def impedance_problem(gains) -> str:
    """Why ``gains`` is not a valid :class:`CartesianImpedance` (its arrays' shapes, finite
    values, rotations, bounds), or ``""``."""
    if not isinstance(gains, CartesianImpedance):
        return f"needs a CartesianImpedance, got {type(gains).__name__}"
    for name in ("force_position",):
        v = _array(getattr(gains, name), (3,))
        if v is None or np.abs(v).max() > 10.0:
            return f"{name} must be 3 finite values within 10 m"
    for name in ("force_orientation", "torque_orientation"):
        R = _array(getattr(gains, name), (3, 3))
        if R is None or not so3.is_rotation(R):
            return f"{name} must be a rotation matrix"
    for side in ("position_positive", "position_negative", "orientation_positive",
                 "orientation_negative"):  # fmt: skip
        half = getattr(gains, side)
        if not isinstance(half, HalfPlaneGains):
            return f"{side} must be HalfPlaneGains, got {type(half).__name__}"
        max_bias = MAX_BIAS_FORCE if side.startswith("position") else MAX_BIAS_TORQUE
        for name, bound in (("p", MAX_STIFFNESS), ("d", MAX_DAMPING), ("bias", max_bias),
                            ("deadband", MAX_DEADBAND)):  # fmt: skip
            v = _array(getattr(half, name), (3,))
            if v is None or not (np.abs(v) <= bound).all():
                return f"{side}.{name} must be 3 finite values within ±{bound:g}"
    return ""
