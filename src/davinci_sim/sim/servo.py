"""The joint servo of every actuated joint: PD + gravity compensation + feed-forward effort.

Each MuJoCo actuator of the generated model is a ``general`` actuator with force
``kp·(ctrl − q) − kv·q̇``, clamped to the joint's dVRK ``ftmax``. Setting

    ctrl = q_ref + (kv·q̇_ref + τ_gravity + τ_ff) / kp

gives force = kp·(q_ref − q) + kv·(q̇_ref − q̇) + τ_gravity + τ_ff, with the damping term
integrated implicitly by MuJoCo (stable at 1 ms). τ_gravity is MuJoCo's own inverse dynamics
at zero acceleration (``qfrc_bias``: gravity and Coriolis), less the weight of bodies the
model compensates itself (``gravcomp``: an operator's hand on an MTM handle). In effort mode
a joint gets no PD term (q_ref = q, q̇_ref = q̇): only gravity compensation and the
feed-forward effort, as the dVRK's ``free`` and ``servo_jf``/``servo_cf`` do.
"""

from __future__ import annotations

import mujoco
import numpy as np

from davinci_sim.kinematics.jit import helper


def servo_ctrl(q, qd, tau_bias, q_ref, qd_ref, tau_ff, effort_mode, gravity_compensation, kp, kv):
    """The actuators' ``ctrl`` realising the servo law (module docstring), any leading batch
    axes: joint positions ``q`` and velocities ``qd`` (rad, m, per s), ``tau_bias`` MuJoCo's
    ``qfrc_bias`` of the joints, setpoints ``q_ref``/``qd_ref``, feed-forward ``tau_ff``
    (N·m, N), masks ``effort_mode``/``gravity_compensation``, gains ``kp``/``kv``."""
    tau_g = np.where(gravity_compensation, tau_bias, 0.0)
    q_ref = np.where(effort_mode, q, q_ref)
    qd_ref = np.where(effort_mode, qd, qd_ref)
    return q_ref + (kv * qd_ref + tau_g + tau_ff) / kp


@helper
def servo_ctrl_scalar(q, qd, tau_bias, q_ref, qd_ref, tau_ff, effort_mode, gravity, kp, kv):
    """:func:`servo_ctrl` of one actuator on floats, the same operations in the same order
    (the same bits): the compiled rows of :mod:`davinci_sim.sim.chunk_kernel`."""
    tau_g = tau_bias if gravity else 0.0
    if effort_mode:
        q_ref, qd_ref = q, qd
    return q_ref + (kv * qd_ref + tau_g + tau_ff) / kp


class JointServo:
    """Vectorised servo over all actuators of a model, in actuator order."""

    def __init__(self, model: mujoco.MjModel) -> None:
        n = model.nu
        self.actuator_names = tuple(model.actuator(i).name for i in range(n))
        self.index = {name: i for i, name in enumerate(self.actuator_names)}
        joint_ids = model.actuator_trnid[:, 0]
        self.qposadr = model.jnt_qposadr[joint_ids].copy()
        self.dofadr = model.jnt_dofadr[joint_ids].copy()
        self.kp = model.actuator_gainprm[:, 0].copy()
        self.kv = -model.actuator_biasprm[:, 2].copy()
        if np.any(self.kp <= 0):
            bad = [self.actuator_names[i] for i in np.flatnonzero(self.kp <= 0)]
            raise ValueError(f"actuators need kp > 0 for the servo, got kp <= 0 for {bad}")
        self.q_ref = np.zeros(n)
        """Position setpoint of each joint (rad or m)."""
        self.qd_ref = np.zeros(n)
        """Velocity feed-forward (rad/s or m/s)."""
        self.tau_ff = np.zeros(n)
        """Feed-forward effort added to the PD and gravity terms (N·m or N)."""
        self.effort_mode = np.zeros(n, dtype=bool)
        """True: no PD term for this joint (free / effort control)."""
        self.gravity_compensation = np.ones(n, dtype=bool)
        # Bodies whose weight the model compensates itself (gravcomp, e.g. an operator's hand
        # on an MTM handle) must not be compensated twice.
        self._model_gravcomp = model.ngravcomp > 0

    def indices(self, names) -> np.ndarray:
        """Actuator indices for the given actuator names."""
        try:
            return np.array([self.index[n] for n in names], dtype=int)
        except KeyError as e:
            raise KeyError(f"no actuator {e.args[0]!r}; actuators: {self.actuator_names}") from None

    def bias(self, data: mujoco.MjData) -> np.ndarray:
        """The joints' bias forces the servo compensates: ``qfrc_bias`` less what the
        model's own gravity compensation (``qfrc_gravcomp``) already cancels."""
        return self.bias_of(data.qfrc_bias, data.qfrc_gravcomp)

    def bias_of(self, qfrc_bias: np.ndarray, qfrc_gravcomp: np.ndarray) -> np.ndarray:
        """:meth:`bias` from MuJoCo's ``qfrc_bias`` and ``qfrc_gravcomp`` (..., nv), any
        leading batch axes (the study's trials), in actuator order."""
        if self._model_gravcomp:
            return qfrc_bias[..., self.dofadr] - qfrc_gravcomp[..., self.dofadr]
        return qfrc_bias[..., self.dofadr]

    def apply(self, data: mujoco.MjData) -> None:
        """Write ``data.ctrl`` for the current state (call right before ``mj_step``)."""
        data.ctrl[:] = servo_ctrl(
            data.qpos[self.qposadr],
            data.qvel[self.dofadr],
            self.bias(data),
            self.q_ref,
            self.qd_ref,
            self.tau_ff,
            self.effort_mode,
            self.gravity_compensation,
            self.kp,
            self.kv,
        )

    #: What :meth:`get_state` saves: references, masks and the gains in use.
    _STATE = ("q_ref", "qd_ref", "tau_ff", "effort_mode", "gravity_compensation", "kp", "kv")

    def get_state(self) -> dict:
        """Copies of the servo's arrays (:data:`_STATE`)."""
        return {name: getattr(self, name).copy() for name in self._STATE}

    def set_state(self, state: dict) -> None:
        """Write a :meth:`get_state` back in place (the arrays keep their identity)."""
        for name in self._STATE:
            getattr(self, name)[:] = state[name]


class ServoJoints:
    """A group of the servo's joints (an arm, a jaw's two fingers): where they are in the
    servo's rows and in MuJoCo's ``qpos``/``qvel``. Subclasses call :meth:`_bind_servo`."""

    _idx: np.ndarray
    _qposadr: np.ndarray
    _dofadr: np.ndarray

    def _bind_servo(self, servo: JointServo, actuator_names) -> None:
        self._idx = servo.indices(actuator_names)
        self._qposadr = servo.qposadr[self._idx]
        self._dofadr = servo.dofadr[self._idx]

    @property
    def actuator_indices(self) -> np.ndarray:
        """The joints' actuators (servo rows) (a copy)."""
        return self._idx.copy()

    @property
    def qpos_addresses(self) -> np.ndarray:
        """The joints' ``qpos`` addresses in the MuJoCo model (a copy)."""
        return self._qposadr.copy()

    @property
    def dof_addresses(self) -> np.ndarray:
        """The joints' ``qvel`` addresses in the MuJoCo model (a copy)."""
        return self._dofadr.copy()
