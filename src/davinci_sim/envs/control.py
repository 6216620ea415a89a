"""The environments' control laws, pure and batch-capable: an action of the control rate
turned into the 1 kHz setpoints the arm is servoed to, one implementation for the single
environment (:class:`~davinci_sim.envs.base.DavinciEnv`, one row) and the vector one
(:class:`~davinci_sim.envs.vector.DavinciVectorEnv`, one row per environment).

An action is given once per control period of ``K`` ticks (``K = 1 kHz / control_hz``). As
the dVRK's teleoperation does with the master's motion, the setpoint moves on every tick,
not in one jump: tick ``k`` of ``1..K`` sends the goal ``g_from + (k/K)·Δ`` with the
velocity feed-forward ``Δ / (K·dt)`` (``servo_cp`` with a twist, ``servo_jp`` with a
velocity). Every function computes each row with the same elementwise arithmetic whatever
the batch size, so an environment gives the same bits alone and in a vector.

Frames and units: Cartesian goals are the tool tip in the camera (ECM tip) frame, m; joint
goals are the arm's joints, rad and m.
"""

from __future__ import annotations

import numpy as np

from davinci_sim.geometry.so3 import rotation_from_vector

#: The physics and servo tick, s (the simulation's 1 kHz).
TICK = 0.001


def ticks_per_action(control_hz: float, dt: float = TICK) -> int:
    """Ticks ``K`` of one control period at ``control_hz`` (Hz); the rate must divide 1 kHz
    (so that an action lasts a whole number of ticks).

    Raises:
        ValueError: for a rate that is not a positive divisor of the tick rate.
    """
    if not (isinstance(control_hz, int | float) and np.isfinite(control_hz) and control_hz > 0):
        raise ValueError(f"control_hz must be a positive number, got {control_hz!r}")
    K = round(1.0 / (control_hz * dt))
    if K < 1 or abs(K * control_hz * dt - 1.0) > 1e-9:
        raise ValueError(
            f"control_hz must divide the {1 / dt:g} Hz tick (e.g. 50, 100, 125, 250), "
            f"got {control_hz!r}"
        )
    return K


def ramp(g_from: np.ndarray, delta: np.ndarray, k: int, K: int) -> np.ndarray:
    """Tick ``k`` (1..K)'s goal: ``g_from + (k/K)·delta`` (..., d)."""
    return g_from + (k / K) * delta


def feedforward(delta: np.ndarray, K: int, dt: float = TICK) -> np.ndarray:
    """The velocity feed-forward of a ramp (..., d): ``delta / (K·dt)`` (m/s or rad/s)."""
    return delta / (K * dt)


def cartesian_delta(
    action: np.ndarray, goal: np.ndarray, max_step: float, lo: np.ndarray, hi: np.ndarray
) -> np.ndarray:
    """The goal's displacement (..., 3), m, for Cartesian actions (..., 3) in [-1, 1] (each
    axis scaled by ``max_step``, m per control period) from ``goal`` (..., 3), camera
    frame, kept within the workspace box [``lo``, ``hi``] (camera frame, m)."""
    a = np.minimum(np.maximum(action, -1.0), 1.0)
    target = np.minimum(np.maximum(goal + max_step * a, lo), hi)
    return target - goal


def joint_delta(
    action: np.ndarray, goal: np.ndarray, max_step: np.ndarray, qmin: np.ndarray, qmax: np.ndarray
) -> np.ndarray:
    """The joint goal's displacement (..., dof) for joint actions in [-1, 1] (joint i scaled
    by ``max_step[i]``, rad or m per control period), within the joint limits."""
    a = np.minimum(np.maximum(action, -1.0), 1.0)
    target = np.minimum(np.maximum(goal + max_step * a, qmin), qmax)
    return target - goal


def rotation_step(action: np.ndarray, max_step: float) -> np.ndarray:
    """The orientation goal's turn (..., 3), a rotation vector about the camera's axes in
    rad, for rotation actions (..., 3) in [-1, 1] (each axis scaled by ``max_step``, rad
    per control period)."""
    return max_step * np.minimum(np.maximum(action, -1.0), 1.0)


def ramp_rotation(R_from: np.ndarray, omega: np.ndarray, k: int, K: int) -> np.ndarray:
    """Tick ``k`` (1..K)'s orientation goal (3, 3): ``R_from`` turned by ``(k/K)·omega``
    (rotation vector, camera frame, rad), at a constant angular velocity over the period
    (its feed-forward: :func:`feedforward` of ``omega``)."""
    return rotation_from_vector((k / K) * omega) @ R_from


def jaw_angle(action: np.ndarray, jaw_min: float, jaw_max: float) -> np.ndarray:
    """The jaw opening (...), rad, of the jaw action (...) in [-1, 1]: -1 closed at
    ``jaw_min``, 1 open at ``jaw_max``."""
    a = np.minimum(np.maximum(action, -1.0), 1.0)
    return jaw_min + 0.5 * (a + 1.0) * (jaw_max - jaw_min)


def orientation_features(R: np.ndarray) -> np.ndarray:
    """An orientation (..., 3, 3) as its first two columns (..., 6), unitless: continuous,
    unlike Euler angles or a quaternion's sign (the third column is their cross product)."""
    return np.concatenate([R[..., :, 0], R[..., :, 1]], axis=-1)
