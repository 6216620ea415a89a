"""The console's steady ticks in compiled calls: :class:`ConsoleChunk`, the simulation's
chunker (:meth:`Simulation.advance <davinci_sim.sim.simulation.Simulation.advance>`).

A console whose operator holds the handles still, teleoperating with the seed's guidance on,
spends its ticks on the same laws every time: each MTM's read, each following teleoperation
(or, while the camera pedal is held, the camera teleoperation), the MTMs' orientation locks,
the watch, the servo, the step, the fixture's force and the task session's sample.
:class:`ConsoleChunk` runs up to :data:`MAX_TICKS` such ticks in one call of
:func:`~davinci_sim.console.chunk_kernel.console_chunk` whenever every component is in that
state (:meth:`ConsoleChunk.plan`: idle, or one of the kinds the kernel has); after the call
it writes back what the Python ticks would have left in the objects (devices' inputs, the
hands' wrenches, the jaws, the locks, the limiters, the filters) and hands the task session
its samples, in tick order (a key held and the clutch held included). Anything else — a
pedal's press, a command, a master aligning, a component the kernel has no form of — ticks
in Python (:meth:`Simulation.tick`), the oracle the chunk is
tested against bit for bit (``tests/console/test_chunk.py``).

A command sent between two calls takes effect at the next one: the live runners' calls are
at most ``runtime.loop.CHUNK_TICKS`` ticks (4 ms of simulated time), so a command waits at
most that long. Between the ends of their snapshot periods the live runners defer the
write-back (``defer``): the calls keep the session's samples, and :meth:`ConsoleChunk.flush`
writes the objects back and hands the session all the samples at once where something reads
them (the period's end, where the runner publishes; a served call; a Python tick; a new
plan), so the Python between two calls is a few copies.

Size: about 570 lines because the plan (which states the kernel ticks, each check a reason to
leave a tick to Python), the call and the write-back (what the Python ticks would have left
in the same objects) are one contract: a state the plan admits is a state the write-back
must cover. The rows themselves are built in :mod:`~davinci_sim.console.chunk_rows`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from davinci_sim.console import haptic_row
from davinci_sim.console import teleop_psm as teleop_psm_module
from davinci_sim.console.chunk_rows import (
    Plan,
    SampleRequest,
    copied,
    device_row,
    ecm_following,
    ecm_idle,
    ecm_row,
    filled,
    floats,
    hand_movable,
    indices,
    keep_camera,
    no_fixture,
    objects_row,
    teleop_role,
    teleop_row,
)
from davinci_sim.console.haptic_loop import HapticLoop
from davinci_sim.console.teleop_ecm import TeleopECM
from davinci_sim.console.teleop_psm import TeleopPSM
from davinci_sim.devices import simulated as simulated_module
from davinci_sim.devices.hand_input import HandInput
from davinci_sim.devices.simulated import SimulatedMTM
from davinci_sim.devices.state import DeviceInput
from davinci_sim.sim import live_period, rows_step
from davinci_sim.sim import operating_state as ops
from davinci_sim.sim import simulation as simulation_module
from davinci_sim.sim.component import IDLE
from davinci_sim.sim.divergence import WARNINGS

if TYPE_CHECKING:
    from davinci_sim.console.console import Console
    from davinci_sim.sim.simulation import Simulation

__all__ = ["COMPILED", "IDLE", "MAX_TICKS", "ConsoleChunk", "SampleRequest"]

_KERNEL: Any = None
_BIND: Any = None
DONE = -1
if (
    rows_step.COMPILED
    and haptic_row.COMPILED
    and teleop_psm_module._ROW is not None
    and simulated_module._ROW is not None
):
    from davinci_sim.console.chunk_kernel import DONE, console_chunk
    from davinci_sim.kinematics.bound import bind

    _KERNEL, _BIND = console_chunk, bind

COMPILED = _KERNEL is not None
"""Whether :class:`ConsoleChunk` can run (else the console ticks in Python)."""


MAX_TICKS = 32
"""The most ticks one call runs. The live runners ask for at most
``runtime.loop.CHUNK_TICKS`` (4 ms: a command from outside waits at most that long); a
script's ``Simulation.step(n)``, which nothing interrupts, runs up to this many per call."""

_COOLDOWN = 8
"""Calls (about ticks) a chunker waits after finding a tick that needs Python before it
asks again (asking costs about a Python tick's time)."""

_SIG = int(mujoco.mjtState.mjSTATE_INTEGRATION)  # (the divergence guard's state)
_WARNINGS = np.array(list(WARNINGS), dtype=np.intp)  # (the guard's warnings, by index)


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
        self._address = np.zeros(14, dtype=np.intp)
        if self.available:
            self._address[:9] = [
                data.ctrl.ctypes.data, data.qpos.ctypes.data, data.qvel.ctypes.data,
                data.qfrc_bias.ctypes.data, data.qfrc_gravcomp.ctypes.data, w, ncon,
                data.xfrc_applied.ctypes.data, data.xipos.ctypes.data,
            ]  # fmt: skip
            self._address[10:13] = [data.xpos.ctypes.data, data.xmat.ctypes.data,
                                  data.site_xpos.ctypes.data]  # fmt: skip
        self._sizes = indices(model.nu, model.nq, model.nv, len(data.warning), 0, model.nbody)
        self._state = np.empty(mujoco.mj_stateSize(model, _SIG))
        self._times = np.zeros(4)
        servo = sim.servo
        self._servo = (indices(*servo.qposadr), indices(*servo.dofadr), bool(servo._model_gravcomp))
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
                *(copied(a) for a in plan.args), plan.reference,
                *(copied(a) for a in plan.ref_args),
                indices(*sim._frame_adr), self._key, 0.0, self._frames_out, self._computed,
                indices(k),
            )  # fmt: skip
        self._device_rows: dict[str, tuple] = {}
        self._teleop_rows: dict[str, tuple] = {}
        self._ecm_rows: dict = {}
        self._no_fixture = no_fixture()
        self._cooldown = 0
        self._last: Plan | None = None
        self._frames_new = False  # (the kernel computed frames the simulation has yet to keep)
        self._pending: Plan | None = None
        """The plan of the deferred calls (``defer``) whose write-back waits for :meth:`flush`."""
        self._samples: list[tuple] = []
        """The session's samples of those calls, in order (copies: each call refills the rows)."""
        if self.available and self._plan_ok:
            self._warm()

    def _warm(self) -> None:
        """The kernel compiled (or loaded from numba's cache) now, with this console's rows
        as they are: a call of no tick. (Its first call in the loop would otherwise compile
        it there: about a minute on a clean checkout.)"""
        sim, console = self.sim, self.console
        servo = sim.servo
        devices = [c for c in sim._components.values() if isinstance(c, SimulatedMTM)][:2]
        device_rows = [device_row(d, servo, self._device_rows, check=False) for d in devices]
        teleop_rows = []
        for tel in console.psm_teleops.values():
            if tel.device in devices:
                teleop_rows.append(teleop_row(
                    tel, devices.index(tel.device), None, servo, self._rows, self._teleop_rows,
                    self._no_fixture, check=False,
                ))  # fmt: skip
        slots_d = filled([r for r in device_rows if r is not None])
        slots_t = filled([r for r in teleop_rows if r is not None][:2])
        if slots_d is not None and slots_t is not None:
            rec = self._request_row(None, [], 0, None)
            assert rec is not None
            ecm = ecm_row(None, {}, self._ecm_rows)
            assert ecm is not None
            self._run(Plan([], [], [], None, None, slots_d, slots_t, rec, {}, ecm), 0)

    # ------------------------------------------------------------ the call
    def __call__(self, n: int, changed: bool = True, defer: bool = False) -> tuple[int, bool]:
        """Up to ``min(n, MAX_TICKS)`` ticks; ``changed`` False when nothing but this
        chunker's own calls has run since its last call (no Python tick, no command), which
        then ran all its ticks: its plan still holds (the rows are what the objects hold).
        ``defer``: a call that runs all its ticks leaves its write-back (the objects, the
        session's samples) to :meth:`flush`, which the next call that plans runs first."""
        plan = None if changed else self._last
        self._last = None
        if plan is None:
            self.flush()  # (planning reads the objects)
            if self._cooldown > 0:  # (not ready lately: do not ask at every tick)
                self._cooldown -= 1
                return 0, False
            plan = self.plan()
            if plan is None:
                self._cooldown = _COOLDOWN
                return 0, False
        K = min(int(n), MAX_TICKS)
        whole, post = self._run(plan, K, defer)
        if whole == K and not post:
            self._last = plan
        return whole, post

    def plan(self) -> Plan | None:
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
        idle: dict[str, TeleopPSM] = {}
        hands: list[HandInput] = []
        haptics: HapticLoop | None = None
        request: SampleRequest | None = None
        camera: TeleopECM | None = None
        console = self.console
        for c in sim._components.values():
            if isinstance(c, HandInput):
                if not hand_movable(c, t):
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
                role = teleop_role(c)
                if role is None:
                    return None
                if role == "follow":
                    teleops.append(c)
                else:
                    idle[c.name] = c
            elif isinstance(c, TeleopECM):
                if ecm_following(c):
                    camera = c
                elif not ecm_idle(c):
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
        device_of = {d.name: i for i, d in enumerate(devices)}
        moved = {h.device.name: h for h in hands if h._holding}
        if any(name not in device_of for name in moved):
            return None
        device_rows = []
        for d in devices:
            row = device_row(d, sim.servo, self._device_rows, rate=moved.get(d.name))
            if row is None:
                return None
            device_rows.append(row)
        teleop_rows = []
        for tel in teleops:
            i = device_of.get(tel.device.name)
            row = (
                None
                if i is None
                else teleop_row(
                    tel, i, haptics, sim.servo, self._rows, self._teleop_rows, self._no_fixture
                )
            )
            if row is None:
                return None
            teleop_rows.append(row)
        # Idle teleoperations' rows marked off (not followed): the session's, whose PSM it
        # samples, or any one for the kernel's types when none follows.
        rows_of = list(teleops)
        names = [t.name for t in teleops]
        off = [] if request is None or request.teleop in names else [request.teleop]
        if not teleop_rows and not off and idle:
            off = [next(iter(idle))]
        for name in off:
            tel = idle.get(name)
            if tel is None:
                return None
            i = device_of.get(tel.device.name)
            row = None if i is None else teleop_row(
                tel, i, None, sim.servo, self._rows, self._teleop_rows, self._no_fixture,
                check=False,
            )  # fmt: skip
            if row is None:
                return None
            teleop_rows.append((*row[:-1], np.zeros(1, dtype=bool)))
            rows_of.append(tel)
        if camera is not None and teleops:  # (both render on the MTMs' one clamp: Python's)
            return None
        ecm = ecm_row(camera, device_of, self._ecm_rows)
        if ecm is None:
            return None
        if not self._arms_idle(devices, teleops, teleop_rows[: len(teleops)], camera):
            return None
        rec = self._request_row(request, rows_of, len(teleops), haptics)
        slots_d, slots_t = filled(device_rows), filled(teleop_rows)
        if rec is None or slots_d is None or slots_t is None:
            return None
        sampled = None if request is None else idle.get(request.teleop)
        clutch = sampled is not None and bool(sampled._clutched)  # (a follower is not)
        return Plan(devices, hands, teleops, haptics, request, slots_d, slots_t, rec, moved,
                     ecm, camera, clutch=clutch)  # fmt: skip

    def _arms_idle(self, devices: list[SimulatedMTM], teleops: list[TeleopPSM],
                   rows: list[tuple], camera: TeleopECM | None) -> bool:  # fmt: skip
        """Whether the arms' pre-steps are the kernel's: an arm no row drives (an idle
        teleoperation's PSM, the ECM, a setup arm, another script's arm) has nothing to do
        (no trajectory or wrench: a move, say a script's ``move_jp``, samples its
        trajectory in Python), and an MTM's wrench is the one its fixture or the camera
        teleoperation renders in the kernel every tick, or none."""
        driven = {d.arm.name for d in devices} | {t.psm.name for t in teleops}
        if camera is not None:
            driven.add(camera.ecm.name)
        if not all(a._pre_step_idle() for n, a in self.sim.arms.items() if n not in driven):
            return False
        rendered = {row[11][0] for row in rows if row[19][0][0]}  # (devices with a fixture)
        if camera is not None:  # (both its hands, every tick)
            rendered |= {i for i, d in enumerate(devices) if d in (camera.left, camera.right)}
        for i, d in enumerate(devices):
            wrench = d.arm._wrench
            if wrench is not None and wrench[1].any() and i not in rendered:
                return False
        return True

    # ------------------------------------------------------------ rows
    def _request_row(self, request: SampleRequest | None, rows_of: list[TeleopPSM],
                     following: int, haptics: HapticLoop | None) -> tuple | None:  # fmt: skip
        """The session's sample part: ``(on, teleop, fixture_teleop, watch, tool_geom,
        other_geom, t, T_tip, T_camera, requested, master, req_now)`` then its objects'
        (:func:`~davinci_sim.console.chunk_rows.objects_row`). ``rows_of``: the
        teleoperations of the kernel's rows, the first ``following`` of them followed. The
        guidance force requested for the session's MTM is the fixture's, or the last one
        while none renders on it (zero before any: ``live_sample``'s)."""
        K = MAX_TICKS
        names = [t.name for t in rows_of]
        if request is None:
            return (np.zeros(1, dtype=bool), indices(0), indices(-1), np.zeros(1, dtype=bool),
                    np.zeros(1, dtype=bool), np.zeros(1, dtype=bool), np.empty(K),
                    np.empty((K, 4, 4)), np.empty((K, 4, 4)), np.empty((K, 3)),
                    np.empty((K, 3)), np.zeros(3), *objects_row(None, None, MAX_TICKS))  # fmt: skip
        if request.teleop not in names:
            return None
        mtm = rows_of[names.index(request.teleop)].mtm_name
        fixture_teleop = -1  # (the teleoperation whose fixture renders on the session's MTM)
        if haptics is not None and haptics.entries_for(mtm):
            fixture_teleop = next(
                (i for i, o in enumerate(rows_of[:following]) if o.mtm_name == mtm), -1
            )
        now = None if haptics is None else haptics.requested(mtm)
        if not self._contact_layout():
            return None
        return (np.ones(1, dtype=bool), indices(names.index(request.teleop)),
                indices(fixture_teleop), np.ones(1, dtype=bool),
                np.ascontiguousarray(request.tool_geom, dtype=bool),
                np.ascontiguousarray(request.other_geom, dtype=bool), np.empty(K),
                np.empty((K, 4, 4)), np.empty((K, 4, 4)), np.empty((K, 3)), np.empty((K, 3)),
                np.zeros(3) if now is None else floats(now[:3]),
                *objects_row(request.objects, request.contacts, MAX_TICKS))  # fmt: skip

    def _contact_layout(self) -> bool:
        """Whether the kernel can read the contacts' geoms and flexes: the addresses of
        ``mjData.contact[0].geom`` and ``.flex`` and the contacts' stride (bytes), taken
        from the bindings' view of the contacts the first time there are some (they live at
        the start of the data's arena, where every step puts them)."""
        if self._address[9]:
            return True
        data = self._data
        if data.ncon == 0:
            return False
        geom, flex = data.contact.geom, data.contact.flex
        for a in (geom, flex):
            if a.strides != geom.strides or a.strides[1] != 4 or a.dtype != np.int32:
                return False
        self._address[9], self._address[13] = geom.ctypes.data, flex.ctypes.data
        self._sizes[4] = geom.strides[0]
        return True

    # ------------------------------------------------------------ run
    def _run(self, plan: Plan, K: int, defer: bool = False) -> tuple[int, bool]:
        sim = self.sim
        watch = sim._watch
        watched, since = watch._watched, watch._bad_since
        kernel = plan.kernel
        if kernel is None:  # (a plan's first call: else the objects hold what it left)
            for k, a in enumerate(watch.arms):
                watched[k] = a._state == ops.ENABLED
                since[k] = a._tracking_bad_since
            self._sync_frames()
            # The plan's calls pass the same objects: bound once, each call unboxes one.
            plan.args = _BIND(self._args(plan))
            kernel = _KERNEL
        self._computed[0] = False
        self._times[3] = sim.data.time
        code = int(kernel(plan.args, K))
        if plan.kernel is None and len(_KERNEL.overloads) == 1:
            # (the compiled function itself, without the dispatcher's typing)
            plan.kernel = next(iter(_KERNEL.overloads.values())).entry_point
        if code == DONE:
            whole, post = K, False
        else:
            whole, post = code // 2 - 1, code % 2 == 1
        pre = whole + (1 if post else 0)  # ticks whose pre-steps and step ran
        self._frames_new = self._frames_new or bool(self._computed[0])
        sim.tick_count += pre
        if pre and defer and whole == K and not post:
            # (the rows, the watch's arrays and the frames keep the last tick's until the
            # next call: only the session's samples of each call must be kept)
            if plan.rec[0][0]:
                self._samples.append(_samples_of(plan.rec, whole))
            self._pending = plan
            return whole, post
        self._store_watch()
        if pre:  # (after the deferred calls' samples, of the same plan: planning flushes)
            samples, self._samples = self._samples, []
            deferred, self._pending = self._pending is not None, None
            if whole and plan.rec[0][0]:
                samples.append(_samples_of(plan.rec, whole))
            self._store(plan, bool(whole) or deferred, samples)
        return whole, post

    def _store_watch(self) -> None:
        """The watch's and the frames' part of the write-back: each watched arm's time of a
        tracking error above its bound, the base frames the kernel computed last."""
        sim = self.sim
        if self._frames_new:
            sim._keep_frames(self._key.tobytes(), self._frames_out.copy())
            self._frames_new = False
        watch = sim._watch
        watched, since = watch._watched, watch._bad_since
        for k, a in enumerate(watch.arms):
            if watched[k]:
                a._tracking_bad_since = float(since[k])

    def flush(self) -> None:
        """The deferred calls' write-back (``defer``): the objects as their last tick left
        them, the session's samples of all of them in order. A no-op when none waits."""
        plan = self._pending
        if plan is None:
            return
        self._pending = None
        samples, self._samples = self._samples, []
        self._store_watch()
        self._store(plan, True, samples)

    def _sync_frames(self) -> None:
        """The frames the simulation holds now into the kernel's (it compares its joints
        with theirs)."""
        sim = self.sim
        frames = sim._base_frames.get("frames")
        if frames is None:
            sim._frames()
            frames = sim._base_frames["frames"]
        self._key[:] = np.frombuffer(frames[0])
        current = frames[1]
        self._frames_out[self._camera_row] = current["camera"]
        for name, row in self._rows.items():
            self._frames_out[row] = current[name][0]

    def _args(self, plan: Plan) -> tuple:
        """The kernel's arguments but the number of ticks."""
        sim = self.sim
        servo, watch = sim.servo, sim._watch
        phys = (
            self._model._address, self._data._address, self._address, self._sizes,
            self._state, _SIG, _WARNINGS, *self._servo,
            servo.kp, servo.kv, servo.effort_mode, servo.gravity_compensation, servo.q_ref,
            servo.qd_ref, servo.tau_ff, float(sim.model.opt.timestep), self._times,
        )  # fmt: skip
        wt = (watch._adr, watch._idx, watch._tol, watch._starts, watch._watched,
              watch._bad_since, watch._first_bad, watch._fault)  # fmt: skip
        fr = self._frames  # (the tolerance as it is now: tests and the study's engine set it)
        fr = (*fr[:12], float(simulation_module.BASE_FRAME_TOLERANCE), *fr[13:])
        return phys, wt, fr, plan.device_rows, plan.teleop_rows, plan.rec, plan.ecm

    def _store(self, plan: Plan, fixtures: bool, samples: list[tuple]) -> None:
        """What the Python ticks leave in the objects: the last tick's reads, the hands', the
        jaws' and the locks' state; with ``fixtures`` (a whole tick ran since the last
        store: the rows' fixture outputs are its last one's) the fixtures'; the session's
        ``samples`` (:func:`_samples_of` of each call, in order)."""
        t_pre = float(self._times[0])
        for h in plan.hands:
            h._time = t_pre
        for d, row in zip(plan.devices, plan.device_rows, strict=False):  # (not the fillers)
            hand = plan.moved.get(d.name)
            if hand is not None:  # (the rate input's targets and the device's pose target)
                state = row[29][1]
                hand._target = state[:3].copy()
                if hand._R_target is not None:
                    hand._R_target = state[12:21].reshape(3, 3).copy()
                d._hand_target = row[7].copy()
            T, twist = row[19].copy(), row[20].copy()
            T.setflags(write=False)
            twist.setflags(write=False)
            d._now = t_pre
            d._input = DeviceInput._checked(T, twist, float(row[22][0]), t_pre)
            d._hand_wrench = row[14].copy()
            d._hand_applied = bool(row[13][0])
            d._hand_velocity[:] = 0.0  # (the reads used it up)
            arm = d.arm
            if row[24][0]:
                m = row[26].shape[0]
                arm._lock_traj = (row[25][:m].copy(), row[25][m:].copy())
                arm._lock_goal = row[26].copy()
        for tel, row in zip(plan.teleops, plan.teleop_rows, strict=False):
            if not tel._ignore_jaw:  # (zip: not the fillers)
                tel._ghost, tel._jaw_catching_up = float(row[8][0]), bool(row[8][2])
                tel._jaw_sent = float(row[9][0])
        if plan.camera is not None:  # (its part of the last tick whose pre-steps ran)
            keep_camera(plan)
        haptics = plan.haptics
        for tel, row in zip(plan.teleops, plan.teleop_rows, strict=False) if fixtures else ():
            state, out = row[19], row[20]
            if not state[0][0]:
                continue
            started = plan.started.get(tel.name)
            if started is None:  # (the fixture's velocity filter: it has started)
                fixture = haptics.entries_for(tel.mtm_name)[0].field
                started = plan.started[tel.name] = fixture.row_filter(tel.psm.name)._started
            started[...] = True
            requested, limited, tau = out[0].copy(), out[1].copy(), out[2].copy()
            haptics._requested[tel.mtm_name] = requested
            dev = plan.device_rows[row[11][0]]
            tel.device.rendered(limited, tau, bool(out[3][0]), dev[15].copy(), dev[4])
        if samples:
            taken = samples[0] if len(samples) == 1 else _joined(samples)
            plan.request.take(*taken, plan.clutch)


def _samples_of(rec: tuple, whole: int) -> tuple:
    """The session's samples of a call's ``whole`` ticks, copied from its row ``rec``:
    ``SampleRequest.take``'s arguments but the clutch (times, camera in the cart, tip in
    the camera, requested force, master; the objects' readings and the contacts, or None)."""
    readings = contacts = None
    if rec[16][0]:  # (the objects' readings, the force on the flex last)
        readings = tuple(a[:whole].copy() for a in (*rec[17:21], rec[22]))
    if rec[16][1]:  # (the contacts measured)
        contacts = (rec[27][:whole].copy(), rec[28][:whole].copy())
    return (rec[6][:whole].copy(), rec[8][:whole].copy(), rec[7][:whole].copy(),
            rec[9][:whole].copy(), rec[10][:whole].copy(), readings, contacts)  # fmt: skip


def _joined(samples: list[tuple]) -> tuple:
    """:func:`_samples_of` of several calls as one, in order."""
    first = samples[0]
    out = [np.concatenate([s[i] for s in samples]) for i in range(5)]
    for i in (5, 6):
        if first[i] is None:
            out.append(None)
        else:
            out.append(tuple(np.concatenate([s[i][j] for s in samples])
                             for j in range(len(first[i]))))  # fmt: skip
    return tuple(out)
