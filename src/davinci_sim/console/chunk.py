"""The console's steady ticks in compiled calls: :class:`ConsoleChunk`, the simulation's
chunker (:meth:`Simulation.advance <davinci_sim.sim.simulation.Simulation.advance>`).

A console whose operator holds the handles still, teleoperating with the seed's guidance on,
spends its ticks on the same laws every time: each MTM's read, each following teleoperation,
the MTMs' orientation locks, the watch, the servo, the step, the fixture's force and the task
session's sample. :class:`ConsoleChunk` runs up to :data:`MAX_TICKS` such ticks in one call
of :func:`~davinci_sim.console.chunk_kernel.console_chunk` whenever every component is in
that state (:meth:`ConsoleChunk.plan`: idle, or one of the kinds the kernel has); after the
call it writes back what the Python ticks would have left in the objects (devices' inputs,
the hands' wrenches, the jaws, the locks, the limiters, the filters) and hands the task
session its samples, in tick order. Anything else — a key held, a command, a clutch, a
component the kernel has no form of — ticks in Python (:meth:`Simulation.tick`), the oracle
the chunk is tested against bit for bit (``tests/console/test_chunk.py``).

A command sent between two calls takes effect at the next one: the live runners' calls are
at most ``runtime.loop.CHUNK_TICKS`` ticks (4 ms of simulated time), so a command waits at
most that long.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from davinci_sim.console import haptic_row
from davinci_sim.console import teleop_psm as teleop_psm_module
from davinci_sim.console.haptic_loop import HapticLoop
from davinci_sim.console.teleop_ecm import TeleopECM
from davinci_sim.console.teleop_psm import ENABLED, TeleopPSM
from davinci_sim.devices import simulated as simulated_module
from davinci_sim.devices.hand_input import HandInput
from davinci_sim.devices.simulated import SimulatedMTM
from davinci_sim.devices.state import DeviceInput
from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics.fixture import FixtureField
from davinci_sim.haptics.fixture_row import path_constants
from davinci_sim.kinematics import fk
from davinci_sim.sim import live_period, rows_step
from davinci_sim.sim import operating_state as ops
from davinci_sim.sim import simulation as simulation_module
from davinci_sim.sim.arms import MTM, MTM_WRIST_JOINTS, PSM, PSM_SAFE_CARTESIAN_DISTANCE
from davinci_sim.sim.divergence import WARNINGS

if TYPE_CHECKING:
    from davinci_sim.console.console import Console
    from davinci_sim.sim.simulation import Simulation

_KERNEL: Any = None
DONE = -1
if (
    rows_step.COMPILED
    and haptic_row.COMPILED
    and teleop_psm_module._ROW is not None
    and simulated_module._ROW is not None
):
    from davinci_sim.console.chunk_kernel import DONE, console_chunk

    _KERNEL = console_chunk

COMPILED = _KERNEL is not None
"""Whether :class:`ConsoleChunk` can run (else the console ticks in Python)."""

MAX_TICKS = 32
"""The most ticks one call runs. The live runners ask for at most
``runtime.loop.CHUNK_TICKS`` (4 ms: a command from outside waits at most that long); a
script's ``Simulation.step(n)``, which nothing interrupts, runs up to this many per call."""

IDLE = "idle"
"""What a component's ``chunk_part()`` returns when its ticks do nothing in the chunk's
state (a trainee's operator with no hand to move)."""

_SIG = int(mujoco.mjtState.mjSTATE_INTEGRATION)  # (the divergence guard's state)


@dataclass(frozen=True)
class SampleRequest:
    """What a component samples after every step (``chunk_part()``'s answer of a task
    session): the tool of ``teleop`` (its PSM's tip in the camera frame), the guidance force
    its MTM's haptic loop requested and its master's position; the chunk calls
    ``take(t, T_cart_camera, T_camera_tip, requested, master)`` for each tick, in order, after
    the call (``requested`` None where the loop has not rendered for that MTM)."""

    teleop: str
    take: Any
    tool_geom: np.ndarray
    """(ngeom,) bool: the instrument's geoms (``InstrumentContacts.tool_geom``)."""
    other_geom: np.ndarray
    """(ngeom,) bool: the geoms whose contact with the instrument counts."""


def _w(a) -> np.ndarray:
    """A writable C-ordered float copy (the kernel's one signature)."""
    return np.array(a, dtype=float, order="C")


def _ints(*values) -> np.ndarray:
    return np.array(values, dtype=np.intp)


def _no_fixture() -> tuple:
    """A fixture of the kernel's types for a teleoperation without one (never used)."""
    path = path_constants(Polyline(np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]])))
    assert path is not None
    return (*path, 0.0, 0.0, 0.0, False, 0.001, 0.5, np.zeros(4), np.zeros(7))


class ConsoleChunk:
    """The chunker of ``sim`` with ``console`` (see the module docstring): ``chunk(n)``
    runs up to ``min(n, MAX_TICKS)`` ticks compiled and returns ``(ticks, post)``: the ticks
    it ran whole, and whether the next one's step ran too with its post-steps left to the
    caller (:meth:`Simulation.advance` runs them)."""

    def __init__(self, sim: Simulation, console: Console) -> None:
        self.sim, self.console = sim, console
        self._model, self._data = sim.model, sim.data
        data, model = sim.data, sim.model
        w = live_period.warning_address(data)
        ncon = live_period.contact_count_address(data)
        self.available = COMPILED and w is not None and ncon is not None
        self._address = np.zeros(10, dtype=np.intp)
        if self.available:
            self._address[:9] = [
                data.ctrl.ctypes.data, data.qpos.ctypes.data, data.qvel.ctypes.data,
                data.qfrc_bias.ctypes.data, data.qfrc_gravcomp.ctypes.data, w, ncon,
                data.xfrc_applied.ctypes.data, data.xipos.ctypes.data,
            ]  # fmt: skip
        self._sizes = _ints(model.nu, model.nq, model.nv, len(data.warning), 0, model.nbody)
        self._state = np.empty(mujoco.mj_stateSize(model, _SIG))
        self._times = np.zeros(3)
        servo = sim.servo
        self._servo = (_ints(*servo.qposadr), _ints(*servo.dofadr), bool(servo._model_gravcomp))
        plan = sim._frame_plan
        self._plan_ok = plan is not None
        self._frames = None
        if plan is not None:
            k = len(plan.arms)
            self._camera_row = k
            self._rows = {name: k + 2 + i for i, name in enumerate(plan.arms)}
            self._frames_out = np.empty((2 * k + 2, 4, 4))
            self._key = np.empty(len(sim._frame_adr))
            self._computed = np.zeros(1, dtype=bool)
            self._frames = (
                *(_wc(a) for a in plan.args), plan.reference, *(_wc(a) for a in plan.ref_args),
                _ints(*sim._frame_adr), self._key, float(simulation_module.BASE_FRAME_TOLERANCE),
                self._frames_out, self._computed, _ints(k),
            )  # fmt: skip
        self._device_rows: dict[str, tuple] = {}
        self._teleop_rows: dict[str, tuple] = {}
        self._no_fixture = _no_fixture()
        self._cooldown = 0

    # ------------------------------------------------------------ the call
    def __call__(self, n: int) -> tuple[int, bool]:
        if self._cooldown > 0:  # (not ready lately: do not ask at every tick)
            self._cooldown -= 1
            return 0, False
        plan = self.plan()
        if plan is None:
            self._cooldown = MAX_TICKS
            return 0, False
        return self._run(plan, min(int(n), MAX_TICKS))

    def plan(self) -> _Plan | None:
        """The kernel's arguments for the state now, or None where a tick needs Python."""
        sim = self.sim
        if not (self.available and self._plan_ok) or sim.data is not self._data:
            return None
        if sim.model is not self._model or sim._initial_components is None:
            return None
        if sim.encoder_noise_std > 0 or sim._noisy_qpos is not None:
            return None
        t = sim.data.time
        devices: list[SimulatedMTM] = []
        teleops: list[TeleopPSM] = []
        hands: list[HandInput] = []
        haptics: HapticLoop | None = None
        request: SampleRequest | None = None
        console = self.console
        for c in sim._components.values():
            if isinstance(c, HandInput):
                if c._holding and (t < c._v_until or c._gripper is not None):
                    return None
                hands.append(c)
            elif isinstance(c, SimulatedMTM):
                if teleops or haptics is not None:
                    return None  # (read after a teleoperation: another order)
                devices.append(c)
            elif c is console:
                if any(d._buttons for d in console.devices()):
                    return None
            elif isinstance(c, TeleopPSM):
                role = _teleop_role(c)
                if role is None:
                    return None
                if role == "follow":
                    teleops.append(c)
            elif isinstance(c, TeleopECM):
                if not _ecm_idle(c):
                    return None
            elif isinstance(c, HapticLoop) and c.console is console:
                haptics = c
            else:
                part = getattr(c, "chunk_part", None)
                answer = None if part is None else part()
                if isinstance(answer, SampleRequest) and request is None and haptics is not None:
                    request = answer
                elif answer != IDLE:
                    return None
        if not teleops:
            return None
        device_of = {d.name: i for i, d in enumerate(devices)}
        device_rows = []
        for d in devices:
            row = self._device_row(d)
            if row is None:
                return None
            device_rows.append(row)
        teleop_rows = []
        for tel in teleops:
            i = device_of.get(tel.device.name)
            row = None if i is None else self._teleop_row(tel, i, haptics)
            if row is None:
                return None
            teleop_rows.append(row)
        rec = self._request_row(request, teleops, haptics)
        if rec is None:
            return None
        return _Plan(devices, hands, teleops, haptics, request, tuple(device_rows),
                     tuple(teleop_rows), rec)  # fmt: skip

    # ------------------------------------------------------------ rows
    def _device_row(self, d: SimulatedMTM) -> tuple | None:
        """A simulated MTM's row: its hand, its read's outputs and its arm's lock, or None
        where its tick needs Python."""
        arm = d.arm
        if not isinstance(arm, MTM) or d.watchdog is not None or d._was_stale:
            return None
        if arm._T_user_base is not None or arm._impedance is not None or arm._traj is not None:
            return None
        if arm.gripper._traj is not None or d._input is None:
            return None
        servo = self.sim.servo
        effort = servo.effort_mode
        lock_on = arm._R_lock is not None and bool(effort[arm._idx[0]])
        if lock_on and arm._lock_traj is None:
            return None  # (the lock's first tick starts its trajectory: Python's)
        if not lock_on and (arm._lock_traj is not None or arm._lock_goal is not None):
            return None
        wrench = arm._wrench
        if wrench is not None and wrench[1].any() and wrench[0] != "spatial":
            return None
        static = self._device_rows.get(d.name)
        if static is None or static[0] is not arm:
            static = self._device_rows[d.name] = (arm, *_device_static(d))
        (_, fk_c, adr, vadr, grip_adr, T_ref_base, R_hrsv_base, R_world_hrsv, p_world_hrsv,
         body, q, T, J, F, T_hrsv, twist, xfrc, gripper, lock_c, wrist_idx,
         idx) = static  # fmt: skip
        if d.arm.base_frame()[0] is not d.arm.kin.T_reference_base:
            return None
        hand = d.hand
        target = d._hand_target
        impedance = np.array([hand.stiffness, hand.damping, hand.rotational_stiffness,
                              hand.rotational_damping, hand.max_force,
                              hand.max_torque])  # fmt: skip
        flags = np.array([d._hand_on, target is not None, d._hold_orientation])
        m = MTM_WRIST_JOINTS.stop - MTM_WRIST_JOINTS.start
        lock_flags = np.array([lock_on, arm._lock_goal is not None])
        lock_traj = np.zeros(2 * m)
        lock_goal = np.zeros(m)
        R_base_goal = np.eye(3)
        ratio = arm._trajectory_ratio
        if lock_on:
            lock_traj[:m], lock_traj[m:] = arm._lock_traj
            if arm._lock_goal is not None:
                lock_goal[:] = arm._lock_goal
            R_base_goal = _w(arm.base_frame()[0][:3, :3].T @ arm._R_lock)  # (MTM._lock_seed)
        lock = (*lock_c[:5], R_base_goal, *lock_c[5:], float(ratio))
        return (
            fk_c, adr, vadr, grip_adr, T_ref_base, R_hrsv_base, flags,
            _w(np.eye(4) if target is None else target), impedance, _w(d._push), R_world_hrsv,
            p_world_hrsv, body, np.array([d._hand_applied]), _w(d._hand_wrench), q, T, J, F,
            T_hrsv, twist, xfrc, gripper, lock, lock_flags, lock_traj, lock_goal, wrist_idx, idx,
        )  # fmt: skip

    def _teleop_row(self, tel: TeleopPSM, device: int, haptics: HapticLoop | None) -> tuple | None:
        """A following teleoperation's row (and its fixture's, if the haptic loop renders
        one for its MTM), or None where its tick needs Python."""
        psm = tel.psm
        if not isinstance(psm, PSM) or getattr(psm, "_cp", None) is None:
            return None
        if psm._T_user_base is not None or psm.name not in self._rows:
            return None
        if psm._traj is not None or psm._wrench is not None or psm.jaw._traj is not None:
            return None
        if psm._refusals or psm._not_ready(cartesian=True):
            return None
        servo = self.sim.servo
        if servo.effort_mode[psm._idx].any() or servo.tau_ff[psm._idx].any():
            return None
        static = self._teleop_rows.get(tel.name)
        if static is None or static[0] is not psm:
            static = self._teleop_rows[tel.name] = (psm, *_teleop_static(psm, self._rows))
        _, cp, adr, idx, row, T_base_ref, shaft, limits, q, T, J, F, q_out, qd_out, jaw_idx = static
        c, spec = tel.config, psm.jaw.spec
        from davinci_sim.console import teleop_math as tm

        flags = np.array([tel._scale, c.use_mtm_linear_velocity, c.use_mtm_angular_velocity,
                          tel._translation_locked, tel._rotation_locked], dtype=float)  # fmt: skip
        jaw = np.zeros(12)
        jaw[:11] = (tel._ghost, 0.0, tel._jaw_catching_up, c.jaw_rate, c.jaw_rate_after_clutch,
                    tel._dt, tel._jaw_s, tel._jaw_o, spec.qmin, spec.qmax,
                    tm.JAW_CATCH_UP_TOLERANCE)  # fmt: skip
        jaw_state = np.array([tel._jaw_sent, float(tel._ignore_jaw)])
        anchors = (_w(tel._T_camera_psm0), _w(tel._T_hrsv_mtm0), _w(tel._R_offset))
        fixture = self._fixture(tel, haptics)
        if fixture is None:
            return None
        return (cp, adr, idx, row, T_base_ref, shaft, anchors, flags, jaw, jaw_state, limits,
                _ints(device), q, T, J, F, q_out, qd_out, *fixture, jaw_idx)  # fmt: skip

    def _fixture(self, tel: TeleopPSM, haptics: HapticLoop | None) -> tuple | None:
        """The fixture part of ``tel``'s row: ``(constants, state, outputs)``, inactive where
        the loop renders nothing for its MTM; None where it renders in Python."""
        dof = tel.device.arm.dof
        out = (np.zeros(6), np.zeros(6), np.zeros(dof), np.zeros(1, dtype=bool))
        entries = [] if haptics is None or not haptics._fields else [
            e for e in haptics._fields.values() if e.mtm in (None, tel.mtm_name)
        ]  # fmt: skip
        if not entries:
            state = (np.zeros(2, dtype=bool), np.zeros(3), np.zeros(3), np.zeros(6))
            return self._no_fixture_for(dof), state, out
        if len(entries) != 1 or not haptic_row.COMPILED:
            return None
        field_ = entries[0].field
        if type(field_) is not FixtureField:
            return None
        row = field_.compiled_row()
        args = tel.device.render_args() if row is not None else None
        if args is None:
            return None
        _, _, _, previous, steps, ftmax = args
        vf = field_.row_filter(tel.psm.name)
        _, path, B, G_max, transition, summed = row
        constants = (*path, float(B), float(G_max), float(transition), bool(summed),
                     float(vf.dt), float(vf.alpha), _w(steps), _w(ftmax))  # fmt: skip
        state = (np.array([True, bool(vf._started)]), vf._p, vf._v, _w(previous))
        return constants, state, out

    def _no_fixture_for(self, dof: int) -> tuple:
        nf = self._no_fixture
        return (*nf[:-1], np.zeros(dof))

    def _request_row(self, request: SampleRequest | None, teleops: list[TeleopPSM],
                     haptics: HapticLoop | None) -> tuple | None:  # fmt: skip
        """The session's sample part: ``(on, teleop, fixture_teleop, watch, tool_geom,
        other_geom, t, T_tip, T_camera, requested, master, req_now)``."""
        K = MAX_TICKS
        names = [t.name for t in teleops]
        if request is None:
            return (np.zeros(1, dtype=bool), _ints(0), _ints(-1), np.zeros(1, dtype=bool),
                    np.zeros(1, dtype=bool), np.zeros(1, dtype=bool), np.empty(K),
                    np.empty((K, 4, 4)), np.empty((K, 4, 4)), np.empty((K, 3)),
                    np.empty((K, 3)), np.zeros(3))  # fmt: skip
        if request.teleop not in names:
            return None
        tel = teleops[names.index(request.teleop)]
        mtm = tel.mtm_name
        fixture_teleop = -1
        for i, other in enumerate(teleops):
            entries = [] if haptics is None else [
                e for e in haptics._fields.values() if e.mtm in (None, other.mtm_name)
            ]  # fmt: skip
            if entries and other.mtm_name == mtm:
                fixture_teleop = i
                break
        now = None if haptics is None else haptics.requested(mtm)
        if now is None and fixture_teleop < 0:
            return None  # (None every tick: rare, and Python's)
        if not self._contact_layout():
            return None
        return (np.ones(1, dtype=bool), _ints(names.index(request.teleop)),
                _ints(fixture_teleop), np.ones(1, dtype=bool),
                np.ascontiguousarray(request.tool_geom, dtype=bool),
                np.ascontiguousarray(request.other_geom, dtype=bool), np.empty(K),
                np.empty((K, 4, 4)), np.empty((K, 4, 4)), np.empty((K, 3)), np.empty((K, 3)),
                np.zeros(3) if now is None else _w(now[:3]))  # fmt: skip

    def _contact_layout(self) -> bool:
        """Whether the kernel can read the contacts' geoms: the address of
        ``mjData.contact[0].geom`` and the contacts' stride (bytes), taken from the
        bindings' view of the contacts the first time there are some (they live at the start
        of the data's arena, where every step puts them)."""
        if self._address[9]:
            return True
        data = self._data
        if data.ncon == 0:
            return False
        geom = data.contact.geom
        if geom.strides[1] != 4 or geom.dtype != np.int32:
            return False
        self._address[9] = geom.ctypes.data
        self._sizes[4] = geom.strides[0]
        return True

    # ------------------------------------------------------------ run
    def _run(self, plan: _Plan, K: int) -> tuple[int, bool]:
        sim = self.sim
        servo, watch = sim.servo, sim._watch
        watched, since = watch._watched, watch._bad_since
        for k, a in enumerate(watch.arms):
            watched[k] = a._state == ops.ENABLED
            since[k] = a._tracking_bad_since
        # the frames the simulation holds now (the kernel compares its joints with theirs)
        frames = sim._base_frames.get("frames")
        if frames is None:
            sim._frames()
            frames = sim._base_frames["frames"]
        self._key[:] = np.frombuffer(frames[0])
        current = frames[1]
        self._frames_out[self._camera_row] = current["camera"]
        for name, row in self._rows.items():
            self._frames_out[row] = current[name][0]
        self._computed[0] = False
        phys = (
            self._model._address, self._data._address, self._address, self._sizes,
            self._state, _SIG, np.array(list(WARNINGS), dtype=np.intp), *self._servo,
            servo.kp, servo.kv, servo.effort_mode, servo.gravity_compensation, servo.q_ref,
            servo.qd_ref, servo.tau_ff, float(sim.model.opt.timestep), self._times,
        )  # fmt: skip
        wt = (watch._adr, watch._idx, watch._tol, watch._starts, watched, since,
              watch._first_bad, watch._fault)  # fmt: skip
        code = int(_KERNEL(phys, wt, self._frames, plan.device_rows, plan.teleop_rows,
                           plan.rec, K))  # fmt: skip
        if code == DONE:
            whole, post = K, False
        else:
            whole, post = code // 2 - 1, code % 2 == 1
        pre = whole + (1 if post else 0)  # ticks whose pre-steps and step ran
        if self._computed[0]:
            sim._keep_frames(self._key.tobytes(), self._frames_out.copy())
        for k, a in enumerate(watch.arms):
            if watched[k]:
                a._tracking_bad_since = float(since[k])
        if pre:
            sim.tick_count += pre
            self._store(plan, whole)
        return whole, post

    def _store(self, plan: _Plan, whole: int) -> None:
        """What the Python ticks leave in the objects: the last tick's reads, the hands', the
        jaws' and the locks' state; the fixtures' and the session's after each whole tick."""
        t_pre = float(self._times[0])
        for h in plan.hands:
            h._time = t_pre
        for d, row in zip(plan.devices, plan.device_rows, strict=True):
            T, twist = row[19].copy(), row[20].copy()
            T.setflags(write=False)
            twist.setflags(write=False)
            d._now = t_pre
            d._input = DeviceInput(T, twist, float(row[22][0]), t_pre)
            d._hand_wrench = row[14].copy()
            d._hand_applied = bool(row[13][0])
            arm = d.arm
            if row[24][0]:
                m = row[26].shape[0]
                arm._lock_traj = (row[25][:m].copy(), row[25][m:].copy())
                arm._lock_goal = row[26].copy()
        for tel, row in zip(plan.teleops, plan.teleop_rows, strict=True):
            if not tel._ignore_jaw:
                tel._ghost, tel._jaw_catching_up = float(row[8][0]), bool(row[8][2])
                tel._jaw_sent = float(row[9][0])
        if whole == 0:
            return
        haptics = plan.haptics
        for tel, row in zip(plan.teleops, plan.teleop_rows, strict=True):
            state, out = row[19], row[20]
            if not state[0][0]:
                continue
            field_ = [e for e in haptics._fields.values() if e.mtm in (None, tel.mtm_name)][0]
            field_.field.row_filter(tel.psm.name)._started[...] = True
            requested, limited, tau = out[0].copy(), out[1].copy(), out[2].copy()
            haptics._requested[tel.mtm_name] = requested
            dev = plan.device_rows[row[11][0]]
            tel.device.rendered(limited, tau, bool(out[3][0]), dev[15].copy(), dev[4])
        rec = plan.rec
        if rec[0][0]:
            plan.request.take(rec[6][:whole].copy(), rec[8][:whole].copy(),
                              rec[7][:whole].copy(), rec[9][:whole].copy(),
                              rec[10][:whole].copy())  # fmt: skip


@dataclass
class _Plan:
    devices: list
    hands: list
    teleops: list
    haptics: Any
    request: Any
    device_rows: tuple
    teleop_rows: tuple
    rec: tuple


def _ro(a: np.ndarray) -> np.ndarray:
    a = a.copy()
    a.setflags(write=False)
    return a


def _wc(a):
    return a.copy() if isinstance(a, np.ndarray) else a


def _teleop_role(tel: TeleopPSM) -> str | None:
    """``"follow"``, ``"idle"`` (its tick does nothing now) or None (its tick needs Python)."""
    from davinci_sim.console.teleop_psm import DISABLED

    current, desired = tel._current, tel._desired
    if current == DISABLED:
        return "idle" if desired == DISABLED else None
    if current != ENABLED or desired == DISABLED:
        return None
    psm = tel.psm.operating_state()
    if psm.state != "ENABLED" or not psm.is_homed or not tel.device.is_ready():
        return None
    if tel.device.is_stale():
        return None
    if not tel._following:
        return "idle"
    if tel._clutched or tel.device.input() is None:
        return None
    return "follow"


def _ecm_idle(tel: TeleopECM) -> bool:
    from davinci_sim.console.teleop_ecm import DISABLED

    if tel._current == DISABLED:
        return tel._desired == DISABLED
    if tel._current != ENABLED or tel._desired == DISABLED or tel._following:
        return False
    ecm = tel.ecm.operating_state()
    return ecm.state == "ENABLED" and ecm.is_homed and tel._devices_ready()


def _device_static(d: SimulatedMTM) -> tuple:
    arm = d.arm
    dof = arm.dof
    T_ref_base = _w(arm.kin.T_reference_base)
    m = MTM_WRIST_JOINTS.stop - MTM_WRIST_JOINTS.start
    lo, hi = arm._wrist_limits
    v_max, a_max = arm._wrist_v_a
    from davinci_sim.sim.arms import _LOCK_DAMPING, _LOCK_STEPS

    consts = tuple(_wc(a) for a in fk._consts(arm.chain).packed)
    scratch2 = tuple(np.empty_like(a) for a in arm._lock_scratch2)
    lock_c = (*consts, MTM_WRIST_JOINTS.start, _LOCK_STEPS, float(_LOCK_DAMPING), _w(lo),
              _w(hi), *scratch2, _w(v_max), _w(a_max))  # fmt: skip
    del m
    return (
        consts, _ints(*arm._qposadr), _ints(*arm._dofadr), _ints(*arm.gripper._qposadr),
        T_ref_base, _w(T_ref_base[:3, :3]), _w(d._R_world_hrsv), _w(d._p_world_hrsv),
        _ints(d._body), np.empty(dof), np.empty((4, 4)), np.empty((6, dof)),
        np.empty((dof, 12)), np.empty((4, 4)), np.empty(6), np.empty(6), np.empty(1), lock_c,
        _ints(*arm._wrist_idx), _ints(*arm._idx),
    )  # fmt: skip


def _teleop_static(psm: PSM, rows: dict) -> tuple:
    constants, bound = psm._cp[0], psm._cp[1]
    dof = psm.dof
    cp = tuple(_wc(a) for a in constants)
    shaft = np.array([float(psm._qposadr[2]), float(psm._shaft_offset),
                      PSM_SAFE_CARTESIAN_DISTANCE])  # fmt: skip
    limits = (_w(psm._qmin), _w(psm._qmax), _w(bound))
    return (cp, _ints(*psm._qposadr), _ints(*psm._idx), _ints(rows[psm.name]), np.empty((4, 4)),
            shaft, limits, np.empty(dof), np.empty((4, 4)), np.empty((6, dof)),
            np.empty((dof, 12)), np.empty(dof), np.empty(dof), _ints(*psm.jaw._idx))  # fmt: skip
