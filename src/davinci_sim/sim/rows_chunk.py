"""A control period of many simulations in one compiled call: the arm's laws and MuJoCo's
step, tick after tick, without returning to Python.

:class:`~davinci_sim.sim.rows_step.RowStepper` took ``mj_step`` of every row out of Python,
but the laws between two steps still ran as numpy calls on the whole batch, one call per
law per tick: at the environments' 20 ticks an action that was a quarter of the time.
:class:`ArmChunk` runs the whole period per row in compiled code
(:mod:`~davinci_sim.sim.chunk_kernel`): for each tick k of K,

1. the setpoint on the period's ramp (:func:`davinci_sim.envs.control.ramp`'s arithmetic):
   a joint goal with its velocity, or a tip goal in the arm's reference through the
   closed-form PSM IK (:func:`~davinci_sim.kinematics.psm_closed_form.closed_form_rows`,
   joint limits with ``LIMIT_SLACK``; a failed answer keeps the setpoint, as ``servo_cp``
   does) with the twist feed-forward (:func:`~davinci_sim.sim.arm_laws.solve_square_into`,
   ``joint_velocity``'s solve);
2. the tracking watch (:func:`~davinci_sim.sim.arm_laws.tracking_fault_scalar`): a row that
   faults stops there;
3. the joint servo (:func:`~davinci_sim.sim.servo.servo_ctrl_scalar`), ``mj_step`` (the
   wheel's library, as :mod:`~davinci_sim.sim.rows_kernel`), the state read back, the
   servo's bias forces (``JointServo.bias_of``);
4. the tip's pose in the arm's reference and its Jacobian
   (:func:`~davinci_sim.kinematics.fk_compiled.tip_pose_row`), recorded per tick if asked
   (a task's per-tick sample is then taken from the record after the call).

Where the Python path would take a branch the kernel has no compiled form of (an IK answer
that needs the DLS polish, a singular Jacobian's least squares) the row stops *before*
that tick (``stop[r] = k``): the caller runs tick k in Python for it and calls again from
k + 1. The Python path stays as the fallback (no numba, ``DAVINCI_SIM_JIT=0``) and as the
tests' oracle: the same laws in the same order, the same results to rounding (the IK goal's
product and the solve are summed in a different order: ~1e-16 relative).

Rows are one per simulation with the full model's layout (``qpos``, ``qvel``, actuators); a
reduced model (:mod:`davinci_sim.envs.reduced`) steps with maps from its own layout into it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from davinci_sim.kinematics import fk
from davinci_sim.kinematics.chain import DHChain
from davinci_sim.kinematics.jit import kernel_array, warmed_up
from davinci_sim.kinematics.psm_ik import _DEFAULT_TOLERANCE
from davinci_sim.kinematics.psm_ik import _packed as _ik_packed
from davinci_sim.sim import rows_step
from davinci_sim.sim.rows_step import RowStepper
from davinci_sim.sim.servo import JointServo

_KERNEL: Any = None
if rows_step.COMPILED:  # (MuJoCo's library is loaded into LLVM's symbols by rows_step)
    from davinci_sim.sim.chunk_kernel import DONE, FAULT, period_rows

    _KERNEL = period_rows
else:  # pragma: no cover - without numba
    DONE, FAULT = -1, -2

COMPILED = _KERNEL is not None
"""Whether :class:`ArmChunk` can run (else callers take their Python path)."""


@dataclass(frozen=True)
class Ramp:
    """One control period's setpoint ramp for n rows (see :mod:`davinci_sim.envs.control`).

    ``cartesian``: the goal is the tip's position in the arm's reference (m), with the
    orientation ``R_base_goal`` (n, 3, 3) already in the arm's base and the feed-forward
    twist ``twist_base`` (n, 6: m/s, rad/s) in the base; else a joint goal (n, dof) with its
    velocity ``velocity`` (n, dof). Tick k's goal is ``start + (k / K)·delta``.
    """

    cartesian: bool
    start: np.ndarray
    delta: np.ndarray
    velocity: np.ndarray
    R_base_goal: np.ndarray
    twist_base: np.ndarray


@dataclass
class Record:
    """Per-tick record of a call (for a task's samples): the tip pose ``T`` (n, K, 4, 4),
    the row's time after the tick ``t`` (n, K), s, and ``ran`` (n, K) whether it ran."""

    T: np.ndarray
    t: np.ndarray
    ran: np.ndarray

    @classmethod
    def empty(cls, n: int, K: int) -> Record:
        return cls(np.empty((n, K, 4, 4)), np.empty((n, K)), np.zeros((n, K), dtype=bool))


_NO_RECORD = Record(np.empty((0, 1, 4, 4)), np.empty((0, 1)), np.zeros((0, 1), dtype=bool))


class ArmChunk:
    """Control periods of one arm in the simulations of ``stepper`` (see the module
    docstring).

    Args:
        stepper: the rows' simulations (their ``MjModel``/``MjData`` pointers).
        servo: the joint servo of the full model (actuator order, gains, masks).
        chain, actuators, qpos: the arm's chain (a PSM for Cartesian ramps), its actuators
            (servo rows) and ``qpos`` addresses (full model).
        tolerance: the tracking tolerance per joint (rad, m).
        T_ref_base: the arm's base in its reference (4, 4) (PSM: the camera), held.
        layout: a reduced model's ``(qpos, dof, actuator)`` addresses in the full model, or
            None (the rows step the full model).
        copy_gravcomp: read ``qfrc_gravcomp`` back after each step.
        timestep: the model's ``opt.timestep``, s.
    """

    def __init__(
        self, stepper: RowStepper, servo: JointServo, chain: DHChain, actuators, qpos,
        tolerance, T_ref_base, *, layout=None, copy_gravcomp: bool, timestep: float,
    ) -> None:  # fmt: skip
        if not COMPILED:
            raise RuntimeError("ArmChunk needs numba and MuJoCo's library (rows_step.COMPILED)")
        self.stepper = stepper
        nu = len(servo.kp)
        model = stepper.models[0]
        if layout is None:
            layout = (np.arange(model.nq), np.arange(model.nv), np.arange(nu))
        self._layout = tuple(np.ascontiguousarray(x, dtype=np.intp) for x in layout)
        self._servo = (
            np.ascontiguousarray(servo.qposadr, dtype=np.intp),
            np.ascontiguousarray(servo.dofadr, dtype=np.intp),
            bool(copy_gravcomp),
            bool(servo._model_gravcomp),
            float(timestep),
            np.ascontiguousarray(servo.kp, dtype=float),
            np.ascontiguousarray(servo.kv, dtype=float),
        )
        self.chain = chain
        self._arm = (
            np.ascontiguousarray(actuators, dtype=np.intp),
            np.ascontiguousarray(qpos, dtype=np.intp),
            np.ascontiguousarray(tolerance, dtype=float),
            np.ascontiguousarray(chain.qmin, dtype=float),
            np.ascontiguousarray(chain.qmax, dtype=float),
            *fk._consts(chain).packed,
        )
        self.T_ref_base = np.ascontiguousarray(T_ref_base, dtype=float)
        self.T_base_ref = np.linalg.inv(self.T_ref_base)
        self._ik = None  # (the closed-form IK's constants: PSM chains only)
        try:
            p = _ik_packed(chain)
        except ValueError:
            pass
        else:
            tol = kernel_array(_DEFAULT_TOLERANCE)  # (as _NO_IK's: one kernel signature)
            self._ik = (p.geometry, p.tool, p.revolute, p.lim_lo, p.lim_hi, tol)

    def run(self, rows, first, K: int, stop, effort_mode, gravity, Q, V, qfrc_bias,
            qfrc_gravcomp, bias, q_ref, qd_ref, tau_ff, time, bad_since, ramp: Ramp,
            T_tip, J_tip, record: Record | None = None) -> None:  # fmt: skip
        """Ticks ``first[r]`` … ``K`` of each row ``r`` of ``rows`` (see the module
        docstring), every array updated in place at those rows: the state (``Q``, ``V``,
        ``qfrc_bias``, ``qfrc_gravcomp`` full-model layout; ``time``, s), the servo's
        ``bias``, ``q_ref``, ``qd_ref`` (``tau_ff``, ``effort_mode``, ``gravity`` read), the
        tracking watch's ``bad_since`` (s, nan), the tip ``T_tip`` (n, 4, 4) and ``J_tip``
        (n, 6, dof), and ``record`` if given. ``stop[r]`` ends as :data:`DONE`,
        :data:`FAULT` (the arm faulted at a tick: no step of that tick) or the tick the
        caller must run in Python. Releases the GIL: threads may run disjoint rows."""
        if ramp.cartesian and self._ik is None:
            raise ValueError(f"{self.chain.name}: Cartesian ramps need a PSM chain")
        ik = self._ik or _NO_IK
        rec = _NO_RECORD if record is None else record
        s = self.stepper
        qadr, dadr, act = self._layout
        qposadr, dofadr, copy_g, minus_g, timestep, kp, kv = self._servo
        _KERNEL(
            s._model, s._data, s._address, np.asarray(rows, dtype=np.intp), first, K, stop,
            qadr, dadr, act, qposadr, dofadr, copy_g, minus_g, timestep,
            kp, kv, effort_mode, gravity,
            Q, V, qfrc_bias, qfrc_gravcomp, bias, q_ref, qd_ref, tau_ff, time, bad_since,
            *self._arm, self.T_ref_base, ramp.cartesian, ramp.start, ramp.delta,
            ramp.velocity, ramp.R_base_goal, self.T_base_ref, ramp.twist_base,
            *ik, T_tip, J_tip, record is not None, rec.T, rec.t, rec.ran,
        )  # fmt: skip


_NO_IK = (
    np.zeros(29), np.zeros(12), np.zeros(6, dtype=bool), np.zeros(6), np.zeros(6), np.zeros(2),
)  # fmt: skip
"""Stands for the IK's constants where a joint ramp does not use them (one signature)."""


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import with the callers' one signature, on
    no rows (no simulation is touched), as :mod:`davinci_sim.sim.rows_step` does."""
    if _KERNEL is None:
        return
    i, f, b = np.zeros(0, dtype=np.intp), np.zeros(0), np.zeros(0, dtype=bool)
    f2, f3 = np.zeros((0, 0)), np.zeros((0, 0, 0))
    addresses, fk_links = np.zeros((0, 7), dtype=np.intp), np.zeros((6, 0))
    _KERNEL(
        i, i, addresses, i, i, 1, i, i, i, i, i, i, True, True, 0.001, f, f, b, b,
        f2, f2, f2, f2, f2, f2, f2, f2, f, f, i, i, f, f, f, fk_links, True, np.eye(4), True,
        np.eye(4), True, f2, f2, f2, f3, np.eye(4), f2, *_NO_IK, f3, f3, False,
        *_NO_RECORD.__dict__.values(),
    )  # fmt: skip


if not warmed_up(_warm_up, "the control period cannot be compiled: Python ticks"):
    _KERNEL, COMPILED = None, False
