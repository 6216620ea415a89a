"""Joint servo actuators: one position-servo actuator per actuated joint, named like it.

Each actuator is ``general`` with gain ``[kp]`` and affine bias ``[0, −kp, −kv]``, i.e.
force = kp·(ctrl − q) − kv·q̇, clamped to ±ftmax (dvrk.md tables; no ctrl range). The
simulation layer adds gravity compensation and velocity feed-forward through ctrl, so kp > 0
everywhere. The gains come from the joint-space inertia at the home pose: with M_ii the
diagonal entry (armature included), kp = ω²·M_ii and kv = 2ζω·M_ii give each joint a
critically damped response of natural frequency ω. MuJoCo's ``implicitfast`` integrates
the kv term implicitly; ω·dt ≤ 0.13 at 1 ms keeps the explicit kp term far from its limit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import mujoco
import numpy as np


@dataclass(frozen=True)
class JointServoSpec:
    """Servo tuning and drive of one joint."""

    joint: str
    ftmax: float
    """Effort limit, N·m or N."""
    frequency_hz: float
    armature: float
    """Reflected drive inertia, kg·m² or kg."""
    damping_ratio: float = 1.0
    viscous_friction: float = 0.0
    """The drive's viscous friction, N·m·s/rad or N·s/m (MuJoCo joint ``damping``)."""
    coulomb_friction: float = 0.0
    """The drive's dry friction, N·m or N (MuJoCo joint ``frictionloss``, made to stick:
    :data:`STICKING_FRICTION`)."""


class ServoGains(NamedTuple):
    """Gains of all actuators of a model, in actuator order."""

    names: tuple[str, ...]
    kp: np.ndarray
    """N·m/rad or N/m."""
    kv: np.ndarray
    """N·m·s/rad or N·s/m."""
    forcerange: np.ndarray
    """(nu, 2) effort limits."""


#: MuJoCo's dry friction is a soft constraint: below the friction force a joint still creeps,
#: at a speed set by the constraint's impedance. With the default (0.9) a servo holding a
#: joint slides it to its setpoint within a second, as if there were no friction; at the
#: impedance's upper end the joint sticks (creep about 1 % of the error per second), as a
#: drive's static friction holds it a little off its setpoint.
STICKING_FRICTION = (0.9999, 0.9999, 0.001, 0.5, 2.0)


def add_actuators(spec: mujoco.MjSpec, servos: list[JointServoSpec]) -> None:
    """Add one actuator per servo (placeholder gains, see :func:`tune_gains`), set armatures
    and the drives' friction."""
    for s in servos:
        joint = spec.joint(s.joint)
        if joint is None:
            raise KeyError(f"no joint {s.joint!r} in the spec")
        joint.armature = s.armature
        if s.viscous_friction > 0:
            joint.damping = [s.viscous_friction, 0.0, 0.0]
        if s.coulomb_friction > 0:
            joint.frictionloss = s.coulomb_friction
            joint.solimp_friction = STICKING_FRICTION
        act = spec.add_actuator(name=s.joint, target=s.joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.dyntype = mujoco.mjtDyn.mjDYN_NONE
        act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = [-s.ftmax, s.ftmax]
        _set_gains(act, 1.0, 0.0)


def _set_gains(act, kp: float, kv: float) -> None:
    gain = np.zeros(10)
    gain[0] = kp
    bias = np.zeros(10)
    bias[1], bias[2] = -kp, -kv
    act.gainprm = gain
    act.biasprm = bias


def tune_gains(
    spec: mujoco.MjSpec, model: mujoco.MjModel, qpos: np.ndarray, servos: list[JointServoSpec]
) -> None:
    """Set kp, kv of the spec's actuators from ``model``'s inertia at ``qpos``."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    for s in servos:
        dof = model.jnt_dofadr[model.joint(s.joint).id]
        w = 2.0 * np.pi * s.frequency_hz
        m_ii = M[dof, dof]
        _set_gains(spec.actuator(s.joint), w * w * m_ii, 2.0 * s.damping_ratio * w * m_ii)


def servo_gains(model: mujoco.MjModel) -> ServoGains:
    """kp, kv and effort limits of every actuator of a generated model."""
    names = tuple(model.actuator(i).name for i in range(model.nu))
    return ServoGains(
        names=names,
        kp=model.actuator_gainprm[:, 0].copy(),
        kv=-model.actuator_biasprm[:, 2].copy(),
        forcerange=model.actuator_forcerange.copy(),
    )
