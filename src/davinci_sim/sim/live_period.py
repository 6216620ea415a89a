"""A control period of one arm of the live simulation in one compiled call: many ticks of
:meth:`Simulation.tick <davinci_sim.sim.simulation.Simulation.tick>` without returning to
Python (:mod:`davinci_sim.sim.live_kernel`).

A caller that streams a ramp of setpoints to one arm — the single learning environment, 20
ticks per action — would otherwise call ``servo_cp``/``servo_jp`` and ``tick`` per tick:
a few hundred Python calls for one MuJoCo step. :class:`ArmPeriod` runs those ticks in one
call whenever nothing else needs Python between two steps (:meth:`ArmPeriod.ready`: no
component, no encoder noise, every arm's pre-step idle, the arm ready for the command);
each law is the live objects' own compiled form, on the live ``MjData`` and servo arrays.
A tick the kernel stops before (a refusal, an IK answer to polish, a fault, a divergence)
is the caller's to run in Python, the same tick as before. The results are the Python
ticks' bit for bit (``tests/sim/test_live_period.py``): the same compiled laws on the same
numbers — the arm's base frame recomputed from the setup and ECM joints whenever they move
(``Simulation._frames``, with its tolerance), its inverse by the arm's own arithmetic
(``Arm._T_base_reference``), MuJoCo's warning counters read after each step.

A caller that samples the state after every tick (the path-following environment's task)
can still run compiled: with ``record`` the kernel keeps, at each tick's start, what a sample
of the state the tick before left reads (the time, the arm's joints, the camera's and the
arm's base frames: :class:`PeriodSamples`), and stops at a step that leaves contacts (their
forces are read from the state itself, ``mjData.ncon`` found by :func:`contact_count_address`);
:func:`run_period` hands the kept samples to the caller, then lets it sample the last tick
from the state.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from davinci_sim.kinematics import fk
from davinci_sim.kinematics.jit import warmed_up
from davinci_sim.sim import operating_state as ops
from davinci_sim.sim import rows_step, simulation
from davinci_sim.sim.divergence import WARNINGS

if TYPE_CHECKING:
    from davinci_sim.sim.arm import Arm
    from davinci_sim.sim.simulation import Simulation

_BOUND_KERNEL: Any = None
_BIND: Any = None
DONE = -1
if rows_step.COMPILED:  # (MuJoCo's library is loaded into LLVM's symbols by rows_step)
    from davinci_sim.kinematics.bound import bind
    from davinci_sim.sim.live_kernel import DONE, live_period

    _BOUND_KERNEL, _BIND = live_period, bind

COMPILED = _BOUND_KERNEL is not None
"""Whether :class:`ArmPeriod` can run (else callers tick in Python)."""

_SIG = int(mujoco.mjtState.mjSTATE_INTEGRATION)  # (the divergence guard's state)
_NO_IK = (np.zeros(29), np.zeros(12), np.zeros(6, dtype=bool), np.zeros(6), np.zeros(6),
          np.zeros(2))  # fmt: skip
"""Stands for the IK's constants in a joint period (one compiled signature)."""
_NO_PLAN = (np.zeros((1, 6, 0)), np.zeros(1, dtype=bool), np.zeros((1, 4, 4)),
            np.zeros(1, dtype=bool), np.zeros((1, 4, 4)), 0, np.zeros((6, 0)), True, np.eye(4),
            True, np.zeros(0, dtype=np.intp))  # fmt: skip
"""Stands for the frame plan's constants where the base frame is held."""


def warning_address(data: mujoco.MjData) -> int | None:
    """The address of ``data``'s warning statistics (``mjWarningStat warning[]``: ``int``
    ``lastinfo``, ``number``), which follow ``solver_fwdinv`` (two ``mjtNum``) in
    ``mjData``; checked by writing distinct counts through the bindings and reading them
    back (then restored). None if the layout is not that one."""
    n = len(data.warning)
    address = data.solver_fwdinv.ctypes.data + data.solver_fwdinv.nbytes
    kept = [(w.lastinfo, w.number) for w in data.warning]
    try:
        for i in range(n):
            data.warning[i].lastinfo, data.warning[i].number = 7_000 + i, 9_000 + i
        seen = list((ctypes.c_int32 * (2 * n)).from_address(address))
        expected = [v for i in range(n) for v in (7_000 + i, 9_000 + i)]
    finally:
        for w, (info, number) in zip(data.warning, kept, strict=True):
            w.lastinfo, w.number = info, number
    return address if seen == expected else None


def contact_count_address(data: mujoco.MjData) -> int | None:
    """The address of ``data``'s ``int ncon``, which follows the warning statistics and the
    timers (``mjTimerStat timer[]``: ``mjtNum`` duration, ``int`` number, 16 bytes) in
    ``mjData``; checked by writing distinct timer counts through the bindings and reading
    them back (then restored), and by the six sizes from ``ncon`` on (``ncon``, ``ne``,
    ``nf``, ``nl``, ``nefc``, ``nJ``) matching the bindings'. None if the layout differs."""
    w = warning_address(data)
    if w is None:
        return None
    timers = w + 8 * len(data.warning)
    n = len(data.timer)
    kept = [t.number for t in data.timer]
    try:
        for i in range(n):
            data.timer[i].number = 5_000 + i
        seen = [ctypes.c_int32.from_address(timers + 16 * i + 8).value for i in range(n)]
    finally:
        for t, number in zip(data.timer, kept, strict=True):
            t.number = number
    address = timers + 16 * n
    sizes = list((ctypes.c_int32 * 6).from_address(address))
    expected = [data.ncon, data.ne, data.nf, data.nl, data.nefc, data.nJ]
    return address if seen == [5_000 + i for i in range(n)] and sizes == expected else None


class ArmPeriod:
    """Control periods of ``arm`` in ``sim`` (see the module docstring). Build one per arm
    and keep it: it holds the simulation's buffer addresses (checked at every call)."""

    def __init__(self, sim: Simulation, arm: Arm) -> None:
        if not COMPILED:
            raise RuntimeError("ArmPeriod needs numba and MuJoCo's library (rows_step.COMPILED)")
        self.sim, self.arm = sim, arm
        self._data = data = sim.data
        self._model = model = sim.model
        w = warning_address(data)
        self.available = w is not None
        """Whether the kernel can watch MuJoCo's warnings here (else :meth:`ready` is False)."""
        ncon = contact_count_address(data)
        self.records = ncon is not None
        """Whether a period can keep its ticks' samples (:meth:`run`'s ``record``): the
        kernel reads ``mjData.ncon`` here."""
        self._address = np.array(
            [x.ctypes.data for x in (data.ctrl, data.qpos, data.qvel, data.qfrc_bias,
                                     data.qfrc_gravcomp)] + [w or 0, ncon or 0], dtype=np.intp,
        )  # fmt: skip
        self._sizes = np.array([model.nu, model.nq, model.nv, len(data.warning)], dtype=np.intp)
        self._state = np.empty(mujoco.mj_stateSize(model, _SIG))
        self._warnings = np.array(list(WARNINGS), dtype=np.intp)
        chain = arm.chain
        self._arm = (
            np.ascontiguousarray(arm._idx, dtype=np.intp),
            np.ascontiguousarray(arm._qposadr, dtype=np.intp),
        )
        offset = getattr(arm, "_shaft_offset", None)
        cp = getattr(arm, "_cp", None)
        self.cartesian_ok = offset is not None and cp is not None
        """Whether Cartesian periods run compiled (a PSM with the closed-form IK)."""
        if self.cartesian_ok:
            from davinci_sim.sim.arms import PSM_SAFE_CARTESIAN_DISTANCE

            constants = _writable(cp[0])
            self._shaft = (int(arm._qposadr[2]), float(offset), PSM_SAFE_CARTESIAN_DISTANCE)
            self._ik = (*constants[:5], constants[9])
        else:
            self._shaft = (-1, 0.0, 0.0)
            self._ik = _NO_IK
        self._fk = _writable(fk._consts(chain).packed)
        servo = sim.servo
        self._servo = (
            np.array(servo.qposadr, dtype=np.intp),
            np.array(servo.dofadr, dtype=np.intp),
            bool(servo._model_gravcomp),
        )
        self._limits = (
            np.ascontiguousarray(chain.qmin, dtype=float),
            np.ascontiguousarray(chain.qmax, dtype=float),
            np.array(arm._feedforward_bound, dtype=float),
        )
        # The base frame: constant (no setup joints), or the simulation's frame plan's row.
        plan = sim._frame_plan
        self._on_suj = f"SUJ/{arm.name}" in sim.arms
        self._plan_row = self._camera_row = -1
        if self._on_suj and plan is not None and arm.name in plan.arms:
            k = len(plan.arms)
            self._plan_row, self._camera_row = k + 2 + plan.arms.index(arm.name), k
            self._plan = (*_writable(plan.args), plan.reference, *_writable(plan.ref_args),
                          np.array(sim._frame_adr, dtype=np.intp))  # fmt: skip
            self._frames_out = np.empty((2 * k + 2, 4, 4))
            self._key = np.empty(len(sim._frame_adr))
        else:
            self._plan = _NO_PLAN
            self._frames_out = np.empty((0, 4, 4))
            self._key = np.empty(0)
        self._computed = np.zeros(1, dtype=bool)
        # The goal's buffers, written at each call (the kernel's arrays bound once).
        n = max(3, arm.dof)
        self._goal = (np.empty((4, 4)), np.empty((3, 3)), np.empty(n), np.empty(n),
                      np.empty(arm.dof), np.empty(6))  # fmt: skip
        self._final = (np.empty((4, 4)), np.empty((6, arm.dof)))  # (T_base_tip, J)
        self._bounds: dict[int, tuple] = {}  # id(samples) -> (samples, bound)
        self._samples: dict[int, PeriodSamples] = {}

    def samples(self, K: int) -> PeriodSamples:
        """This period's buffer of samples for periods of ``K`` ticks (the same object at
        every call: :meth:`run` binds it once; its rows are overwritten by the next run)."""
        out = self._samples.get(K)
        if out is None:
            out = self._samples[K] = PeriodSamples.empty(K, self.arm.dof)
        return out

    def _bound(self, samples: PeriodSamples):
        """The kernel's arguments but the period's flags, bound once per ``samples`` buffer
        (the servo's and the watch's arrays are the simulation's own, built with it)."""
        entry = self._bounds.get(id(samples))
        if entry is not None and entry[0] is samples:
            return entry[1]
        servo, watch = self.sim.servo, self.sim._watch
        args = (
            (self._model._address, self._data._address, self._address, self._sizes,
             self._state, _SIG, self._warnings),
            (*self._servo, servo.kp, servo.kv, servo.effort_mode, servo.gravity_compensation,
             servo.q_ref, servo.qd_ref, servo.tau_ff),
            (watch._adr, watch._idx, watch._tol, watch._starts, watch._watched,
             watch._bad_since, watch._first_bad, watch._fault),
            (*self._arm, *self._shaft, *self._fk),
            self._ik,
            (*self._goal, *self._limits),
            (*self._plan, self._key, self._frames_out, self._plan_row, self._computed),
            (samples.t, samples.q, samples.frames),
            self._final,
        )  # fmt: skip
        if len(self._bounds) >= 8:  # (callers' own buffers, one after another)
            self._bounds.clear()
        bound = _BIND(args)
        self._bounds[id(samples)] = (samples, bound)
        return bound

    def _frames(self) -> bool | None:
        """How a Cartesian period gets the arm's base frame: held (False: a base frame the
        user set, or none without setup joints), recomputed from the joints (True), or no
        compiled form (None: a PSM on setup joints without the ECM's frame plan)."""
        if self.arm._T_user_base is not None or not self._on_suj:
            return False
        return True if self._plan_row >= 0 else None

    def ready(self, cartesian: bool) -> bool:
        """Whether ticks may run compiled now: nothing else needs Python between two steps
        and the arm would take the command (else the caller ticks in Python)."""
        sim, arm = self.sim, self.arm
        if not self.available or sim.data is not self._data or sim.model is not self._model:
            return False
        if cartesian and (not self.cartesian_ok or self._frames() is None):
            return False
        if sim._components or sim.encoder_noise_std > 0 or sim._noisy_qpos is not None:
            return False
        if sim._initial_components is None:  # (the first tick records the components)
            return False
        if not all(a._pre_step_idle() for a in sim.arms.values()):
            return False
        if arm._not_ready(cartesian=cartesian):
            return False
        servo, idx = sim.servo, arm._idx
        # What every accepted servo_cp/servo_jp sets besides the references: set already.
        return not servo.effort_mode[idx].any() and not servo.tau_ff[idx].any()

    def can_record(self, cartesian: bool) -> bool:
        """Whether a period can keep its ticks' samples (:class:`PeriodSamples`): a
        Cartesian one whose base frame follows the setup and ECM joints, where the kernel
        can read ``mjData.ncon``."""
        return self.records and cartesian and self.cartesian_ok and self._frames() is True

    def record_last(self, record: PeriodSamples, k: int) -> bool:
        """Row ``k`` of ``record`` after a recorded :meth:`run` that ran tick ``k`` last: the
        state now, as the kernel keeps each tick's sample (at the next tick's start, so never
        the last one's); False (nothing kept) where that step left contacts, whose forces
        only the state itself can tell."""
        data = self.sim.data
        if data.ncon:
            return False
        record.t[k] = data.time
        record.q[k] = data.qpos[self._arm[1]]
        record.frames[k, 0] = self._frames_out[self._camera_row]
        record.frames[k, 1] = self._frames_out[self._plan_row]
        return True

    def run(self, first: int, K: int, *, cartesian: bool, start, delta, velocity=None,
            R_ref_goal=None, twist_ref=None,
            record: PeriodSamples | None = None) -> int:  # fmt: skip
        """Ticks ``first`` … ``K`` of a period whose tick k commands
        ``start + (k/K)·delta``: a Cartesian goal (the tip's position in the arm's reference,
        m, with the orientation ``R_ref_goal`` (3, 3) and the feed-forward ``twist_ref`` (6,
        m/s and rad/s; None: none)) through ``servo_cp``, or a joint goal (rad, m) with the
        velocity ``velocity`` through ``servo_jp``. Call only when :meth:`ready`. Returns
        :data:`DONE`, or the tick k the caller must run in Python (ticks before it ran).

        ``record`` (only where :meth:`can_record`): each tick's sample but the last one run
        (``first`` … the last − 1: the state after each of them, as :class:`PeriodSamples`
        has it) is kept in it; the last one's is the state as it is when this returns."""
        sim, arm = self.sim, self.arm
        watch = sim._watch
        arms = watch.arms
        watched, since = watch._watched, watch._bad_since
        for k, a in enumerate(arms):
            watched[k] = a._state == ops.ENABLED
            since[k] = a._tracking_bad_since
        dof = arm.dof
        feedforward = twist_ref is not None
        T_base_ref = arm._T_base_reference() if cartesian else np.eye(4)
        frames = bool(cartesian and self._frames())
        if frames:  # the joints of the simulation's current frames (just asked for)
            self._key[:] = np.frombuffer(sim._base_frames["frames"][0])
        recording = record is not None and frames and self.records
        camera_row = self._camera_row if recording else 0
        if recording:  # (the kernel keeps them from the frames it holds: the current ones)
            current = sim._base_frames["frames"][1]
            self._frames_out[camera_row] = current["camera"]
            self._frames_out[self._plan_row] = current[arm.name][0]
        samples = record if recording else _NO_RECORD
        self._computed[0] = False
        n = 3 if cartesian else dof
        T_buf, R_buf, start_buf, delta_buf, velocity_buf, twist_buf = self._goal
        _put(T_buf, T_base_ref, (4, 4))
        _put(R_buf, R_ref_goal, (3, 3))
        _put(start_buf[:n], start, (n,))
        _put(delta_buf[:n], delta, (n,))
        _put(velocity_buf, None if cartesian else velocity, (dof,))
        _put(twist_buf, twist_ref, (6,))
        stop = _BOUND_KERNEL(
            self._bound(samples), first, K, cartesian, feedforward, frames,
            float(simulation.BASE_FRAME_TOLERANCE), recording, camera_row,
        )  # fmt: skip
        if self._computed[0]:  # the frames the kernel computed last: the simulation's now
            sim._keep_frames(self._key.tobytes(), self._frames_out.copy())
        if stop == DONE:  # the arm's kinematics at the joints now, as the next reader's
            arm._keep_kinematics(arm._q(), self._final[0].copy(), self._final[1].copy())
        ran = (K if stop == DONE else stop - 1) - first + 1
        sim.tick_count += ran
        for k, a in enumerate(arms):
            if watched[k]:
                a._tracking_bad_since = float(since[k])
        return int(stop)


@dataclass(frozen=True)
class PeriodSamples:
    """What a sample of the state after each tick of a period reads (rows by tick number,
    1 … K; :meth:`ArmPeriod.run`'s ``record``)."""

    t: np.ndarray
    """(K + 1,) the time after the tick, s."""
    q: np.ndarray
    """(K + 1, dof) the arm's joints (rad, m)."""
    frames: np.ndarray
    """(K + 1, 2, 4, 4) the camera (ECM tip) in the cart, then the arm's base frame in its
    reference (``Arm.base_frame``), m."""

    @classmethod
    def empty(cls, K: int, dof: int) -> PeriodSamples:
        return cls(np.empty(K + 1), np.empty((K + 1, dof)), np.empty((K + 1, 2, 4, 4)))


_NO_RECORD = PeriodSamples.empty(0, 0)


def run_period(
    sim: Simulation, arm: Arm, K: int, *, cartesian: bool, start, delta, velocity=None,
    R_ref_goal=None, twist_ref=None, period: ArmPeriod | None = None, after_tick=None,
    recorded=None,
) -> None:  # fmt: skip
    """The K ticks of a control period whose tick k commands ``start + (k/K)·delta`` to
    ``arm`` (the arguments of :meth:`ArmPeriod.run`): in ``period``'s compiled calls while
    it is :meth:`~ArmPeriod.ready`, else tick by tick in Python — ``arm.servo_cp`` (the goal
    with the orientation ``R_ref_goal`` and the twist) or ``arm.servo_jp`` (with
    ``velocity``), :meth:`Simulation.tick`, then ``after_tick()`` if given. Without
    ``period``: the Python path, the oracle of the compiled one.

    A caller that samples every tick (``after_tick``) gets compiled calls only with
    ``recorded(samples, ticks)`` where ``period`` :meth:`~ArmPeriod.can_record`: each call's
    ticks but its last are given to it afterwards (``ticks``, a range of tick numbers, the
    rows of ``samples``: :class:`PeriodSamples`, in order), then ``after_tick()`` samples the
    last one from the state itself, before any later tick runs; a call that ends the period
    gives its last tick too where its step left no contacts
    (:meth:`~ArmPeriod.record_last`), with no ``after_tick()``."""
    ramp = {"cartesian": cartesian, "start": start, "delta": delta, "velocity": velocity,
            "R_ref_goal": R_ref_goal, "twist_ref": twist_ref}  # fmt: skip
    record = None
    if after_tick is not None:
        if recorded is not None and period is not None and period.can_record(cartesian):
            record = period.samples(K)
        else:
            period = None  # (every tick sampled in Python)
    T_goal = np.eye(4)
    if cartesian:
        T_goal[:3, :3] = R_ref_goal
    k = 1
    while k <= K:
        if period is not None and period.ready(cartesian):
            stop = period.run(k, K, record=record, **ramp)
            last = K if stop == DONE else stop - 1
            if record is not None and last >= k:
                if stop == DONE and period.record_last(record, K):
                    recorded(record, range(k, K + 1))
                    return
                if last > k:
                    recorded(record, range(k, last))
                after_tick()
            if stop == DONE:
                return
            k = stop
        g = start + (k / K) * delta  # (envs.control.ramp)
        if cartesian:
            T_goal[:3, 3] = g
            arm.servo_cp(T_goal, twist_ref)
        else:
            arm.servo_jp(g, velocity)
        sim.tick()
        if after_tick is not None:
            after_tick()
        k += 1


def _put(buffer: np.ndarray, x, shape) -> None:
    """``x`` (any array-like of ``shape``; zeros for None) into the kernel's float64
    ``buffer``: its one compiled signature, whatever the caller's array."""
    if x is None:
        buffer[...] = 0.0
    else:
        buffer[...] = np.asarray(x, dtype=float).reshape(shape)


def _writable(constants) -> tuple:
    """Writable copies of the arrays among ``constants`` (the one compiled signature)."""
    return tuple(np.array(c, order="C") if isinstance(c, np.ndarray) else c for c in constants)


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import with the callers' one signature, on no
    tick (no simulation is touched), as :mod:`davinci_sim.sim.rows_step` does."""
    if _BOUND_KERNEL is None:
        return
    i, f, b = np.zeros(0, dtype=np.intp), np.zeros(0), np.zeros(0, dtype=bool)
    i64 = np.zeros(1, dtype=np.int64)
    args = (
        (0, 0, np.zeros(7, dtype=np.intp), np.zeros(4, dtype=np.intp), f, _SIG, i),
        (i, i, True, f, f, b, b, f, f, f),
        (i64, i64, f, i64, b, f, i64, b),
        (i, i, -1, 0.0, 0.0, np.zeros((6, 0)), True, np.eye(4), True),
        _NO_IK,
        (np.eye(4), np.eye(3), f, f, f, np.zeros(6), f, f, f),
        (*_NO_PLAN, f, np.empty((0, 4, 4)), -1, np.zeros(1, dtype=bool)),
        (_NO_RECORD.t, _NO_RECORD.q, _NO_RECORD.frames),
        (np.empty((4, 4)), np.empty((6, 0))),
    )  # fmt: skip
    _BOUND_KERNEL(_BIND(args), 1, 0, True, False, False, 0.0, False, 0)


if COMPILED and not warmed_up(_warm_up, "the live control period cannot be compiled: Python ticks"):
    _BOUND_KERNEL, COMPILED = None, False
