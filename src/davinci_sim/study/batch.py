"""Many trials at once: the study's engine, stepping a batch of trials together at 1 kHz.

One trial on the live simulator (:func:`~davinci_sim.study.trial.run_trial`) spends almost
all its time in Python calls that each handle one arm of one trial. :class:`TrialBatch`
runs n trials as arrays instead:

* The start is the same for every trial: :func:`~davinci_sim.study.trial.setup_trial` brings
  one live simulation (console, teleoperation, tool at point 1) to the moment the trainee
  takes the handle; each trial gets a copy of its ``MjData`` and of the servo, teleoperation,
  device and haptic state read from the live objects.
* Every tick applies, to all trials at once, the laws the live components apply to one —
  the same functions, called with one row per trial (this module composes them and states
  no formula of its own): the trainee (:class:`~davinci_sim.operators.SyntheticTrainee`,
  ``command`` and ``push_force``) and its hand on the MTM handle
  (:func:`~davinci_sim.devices.hand.hand_wrenches`, :func:`~davinci_sim.devices.hand.handle_xfrc`);
  the arms' laws of :mod:`~davinci_sim.sim.arm_laws` (pose and Jacobian, ``measured_cv``, the
  ``servo_cp`` twist feed-forward, Jᵀ·w of ``spatial/servo_cf``, joint limits, the tracking
  fault); the teleoperation's following law (:func:`~davinci_sim.console.teleop_math.follow_pose`,
  ``follow_twist``, ``follow_jaw``) and the batched closed-form PSM IK
  (:func:`~davinci_sim.kinematics.psm_ik.psm_ik_closed_form_batch`); the joint servo
  (:func:`~davinci_sim.sim.servo.servo_ctrl`, ``JointServo.bias``); the fixture through the
  velocity filter and the frame change (:func:`~davinci_sim.haptics.fixture.fixture_force_camera`,
  :class:`~davinci_sim.haptics.velocity.VelocityFilter`) and the device's safety clamp
  (:func:`~davinci_sim.devices.safety.clamp_wrenches`); the task state machine and the
  metrics (with the trainer metrics' sample fields: the tip in the left image,
  :func:`~davinci_sim.model.cameras.in_left_image`; the MTM handle position; the
  instrument's contacts, :class:`~davinci_sim.tasks.trainer.InstrumentContacts`, read only
  when a trial's step has any). The fixture is any the task offers
  (:mod:`davinci_sim.haptics.kinds`: the seed's viscous law, spring, a registered or
  ``module:Name`` law): each condition's fixture is built as the live trial builds it
  (``task.fixture`` of the trial's entry) and called with the rows of that condition
  (:meth:`TrialBatch.fixture_forces`). Only ``mj_step`` runs per trial (MuJoCo's C),
  and only for trials still running: every running trial's step in one compiled call
  (:class:`~davinci_sim.sim.rows_step.RowStepper`), the same bits as Python's calls.
* With numba, the trainees' step (:mod:`davinci_sim.operators.trainee_row`) and, for the
  seed's viscous conditions, the hands and everything after them run compiled
  (:mod:`davinci_sim.study.batch_compiled`); this numpy tick is the fallback and the oracle
  (``tests/study/test_batch_compiled.py``).
* The order within a tick is the live simulation's: trainee, hand, teleoperation, arms,
  servo, physics, then the haptic loop and the task on the new state.
* Each trial's model carries its subject's hand mass on the MTM (what the live
  ``SimulatedMTM`` does when the hand takes the handle); trials of a subject share one model.
  When half the trials have ended, the arrays drop their rows.

What the batch does not do: anything the study's trials never reach on the live path
(clutch, a refused or faulted arm recovering, alignment, locks). It holds the camera and
setup-joint frames as at the start (the ECM does not move in a trial; the live simulation
follows the setup joints' ~1e-5 rad/s yield under the arms' reaction forces). A PSM
``servo_cp`` whose IK fails keeps the previous setpoint, as the arm does; a PSM tracking
fault (the arm would go to FAULT and the teleoperation stop) ends that trial, unfinished.
``tests/study`` checks that a batch reproduces :func:`~davinci_sim.study.trial.run_trial`.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from types import SimpleNamespace

import mujoco
import numpy as np

from davinci_sim.console import teleop_math as tm
from davinci_sim.devices.hand import hand_wrenches, handle_xfrc
from davinci_sim.devices.safety import clamp_wrenches
from davinci_sim.geometry.so3 import rotate_pairs, rotate_rows
from davinci_sim.haptics.fixture import fixture_force_camera
from davinci_sim.haptics.velocity import DEFAULT_CUTOFF_HZ, VelocityFilter
from davinci_sim.kinematics.psm_ik import psm_ik_closed_form_batch
from davinci_sim.model.cameras import in_left_image
from davinci_sim.sim import arm_laws as laws
from davinci_sim.sim.jaw import finger_setpoints
from davinci_sim.sim.rows_step import RowStepper
from davinci_sim.sim.servo import servo_ctrl
from davinci_sim.study import batch_chunk, batch_compiled
from davinci_sim.study.adaptive import fixture_keys
from davinci_sim.study.trial import (
    METRICS,
    TrialSpec,
    load_spec_task,
    setup_trial,
    trial_inputs,
    trial_row,
)
from davinci_sim.tasks import Phase, Sample
from davinci_sim.tasks.state import advance
from davinci_sim.tasks.trainer import InstrumentContacts

#: Below this many rows a batch is not compacted any more (the fixed cost per tick dominates).
COMPACT_MIN_ROWS = 8


class TrialBatch:
    """n trials of one task and one seed, stepped together (see the module docstring).

    Args:
        specs: the trials (all with the same ``task`` and ``seed``).
    """

    def __init__(self, specs: list[TrialSpec]) -> None:
        if not specs:
            raise ValueError("a batch needs at least one trial")
        tasks = {s.task for s in specs}
        if len(tasks) != 1:
            raise ValueError(f"one batch of trials needs one task, got {sorted(tasks)}")
        self.specs = list(specs)
        n = self.n = len(specs)
        task = self.task = load_spec_task(specs[0])
        setup = self._setup = setup_trial(task)
        sim, teleop, device = setup.sim, setup.teleop, setup.device
        psm, mtm = teleop.psm, device.arm
        self.dt = sim.dt
        # --- each trial's physics: a copy of the live data (derived quantities included)
        self.datas = [copy.copy(sim.data) for _ in range(n)]
        self._body = device.handle_body
        d = sim.data
        self.Q, self.V = np.tile(d.qpos, (n, 1)), np.tile(d.qvel, (n, 1))
        self.bias = np.tile(sim.servo.bias(d), (n, 1))
        """The servo's bias forces (JointServo.bias), one row per trial, actuator order."""
        self._qfrc = np.tile(d.qfrc_bias, (n, 1)), np.tile(d.qfrc_gravcomp, (n, 1))
        """MuJoCo's ``qfrc_bias`` and ``qfrc_gravcomp`` of each trial (after its last step)."""
        self.xipos = np.tile(d.xipos[self._body], (n, 1))
        # --- the joint servo (one row per trial)
        servo = self._servo = sim.servo
        self.q_ref = np.tile(servo.q_ref, (n, 1))
        self.qd_ref = np.tile(servo.qd_ref, (n, 1))
        self.tau_ff = np.tile(servo.tau_ff, (n, 1))
        self.effort_mode = servo.effort_mode.copy()
        self.gravity = servo.gravity_compensation.copy()
        # --- arms: joints, chains and the fixed base frames (the ECM does not move)
        self.psm_chain, self.mtm_chain = psm.chain, mtm.chain
        self.psm_act, self.mtm_act = psm.actuator_indices, mtm.actuator_indices
        self.psm_q, self.mtm_q = psm.qpos_addresses, mtm.qpos_addresses
        self.psm_v, self.mtm_v = psm.dof_addresses, mtm.dof_addresses
        self.jaw_act = psm.jaw.actuator_indices
        self.jaw_spec = psm.jaw.spec
        self.gripper_q = mtm.gripper.qpos_addresses
        self.T_camera_rcm = psm.base_frame()[0].copy()
        self.T_rcm_camera = np.linalg.inv(self.T_camera_rcm)
        self.T_hrsv_mtmbase = mtm.base_frame()[0].copy()
        self.psm_tol = psm.tracking_tolerance
        self.mtm_ftmax = mtm.chain.ftmax
        # --- the teleoperation as it follows now (dvrk.md 4.2)
        config = teleop.config
        anchors = teleop.following_anchors()
        if anchors.translation_locked or anchors.rotation_locked:
            raise NotImplementedError("a batch of trials does not run locked teleoperations")
        self.scale = anchors.scale
        self.use_linear = config.use_mtm_linear_velocity
        self.use_angular = config.use_mtm_angular_velocity
        self.T_camera_psm0 = anchors.T_camera_psm0
        self.T_hrsv_mtm0 = anchors.T_hrsv_mtm0
        self.R_offset = anchors.R_offset
        self.jaw_s, self.jaw_o = anchors.jaw_scale, anchors.jaw_offset
        self.jaw_rates = config.jaw_rate, config.jaw_rate_after_clutch
        self.jaw_catching_up = np.full(n, anchors.jaw_catching_up)
        self.ghost = np.full(n, anchors.jaw_ghost)
        self.jaw_sent = np.full(n, anchors.jaw_sent)
        # --- the device: HRSV in the world, the hand's grasp, the safety clamp
        T_world_hrsv = device.T_world_hrsv
        self.R_world_hrsv, self.p_world_hrsv = T_world_hrsv[:3, :3], T_world_hrsv[:3, 3]
        self.limits = device.limits
        self.wrench_sent = np.tile(device.wrench(), (n, 1))
        # The hand takes the handle where the device last read it, holding the orientation
        # the handle has now (what TraineeHand's grasp does on the live path).
        hand_start = device.input().position
        self.T_hand = np.tile(mtm.measured_cp().T, (n, 1, 1))
        self.T_hand[:, :3, 3] = hand_start
        self.R_hand0 = self.T_hand[:, :3, :3].copy()  # (turned by the wrist: operators.wrist)
        # --- trainees, fixtures, task
        self.T_world_camera = setup.T_world_camera
        self.T_task_camera = setup.T_task_camera
        """The camera in the task's frame, the frame of the fixture and the task's checks
        (FixtureField(frame=task.frame) on the live path)."""
        self.params, self.trainee = trial_inputs(specs, task, self.T_world_camera, hand_start)
        # The subjects' limb stiffness and damping; the wrist's values and the hand's limits
        # are the device's (operators.console.hand_impedance).
        self.impedance = device.hand
        # Each trial's model: the subject's hand mass on the MTM's hand body, as SimulatedMTM
        # puts it there when the hand takes the handle.
        # (One model per distinct mass: trials of a subject share it, and fewer models stay
        # in the CPU caches.)
        by_mass: dict[float, mujoco.MjModel] = {}
        for mass in self.params.mass.tolist():
            if mass not in by_mass:
                by_mass[mass] = copy.copy(sim.model)
                by_mass[mass].body_mass[device.hand_body] = mass
                # MuJoCo's auto-reset back on (the live simulation turns it off to undo a
                # diverged step itself): a diverged trial resets, faults and ends unfinished.
                by_mass[mass].opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
        self.models = [by_mass[m] for m in self.params.mass.tolist()]
        self._stepper = RowStepper(self.models, self.datas, self._body)
        # Each trial's fixture as the live trial builds it (task.fixture of its entry: its
        # guidance plus the task's walls), one per key (a practice trial's condition index;
        # negative for an adaptive trial's (condition, B) and a retention trial's fixture-off
        # entry: study.adaptive.fixture_keys).
        keys = fixture_keys(specs)
        self.fixtures = {}
        for s, key in zip(specs, keys, strict=True):
            if key not in self.fixtures:
                self.fixtures[key] = task.fixture(s.fixture)
        self.cond = np.array(keys, dtype=int)
        """The key of each current row's fixture in :attr:`fixtures`."""
        self.index = np.arange(n)
        """Position of each current row in ``specs`` (rows of ended trials are dropped)."""
        self.velocity = VelocityFilter((n,), dt=self.dt, cutoff_hz=DEFAULT_CUTOFF_HZ)
        self.state = task.initial_state(n)
        self.metrics = task.metrics_accumulator(n)
        self.time = sim.time
        self.t_start = sim.time
        self.t_end = self.t_start + np.array([s.timeout for s in specs])
        self.active = np.ones(n, dtype=bool)
        self.fault = np.zeros(n, dtype=bool)
        self.ticks = np.zeros(n, dtype=np.int64)
        self._bad_since = np.full(n, np.nan)
        self.requested = np.zeros((n, 3))
        # The trainer metrics' sample fields: the left image, the instrument's contacts.
        self.camera = sim.endoscope
        self._contacts = InstrumentContacts.of_task(sim.model, task)
        self.n_contacts = np.zeros(n, dtype=np.int64)
        self.contact_force = np.zeros(n)
        self._kinematics()
        self._cond_index = np.zeros(n, dtype=np.intp)
        self._compiled = batch_compiled.constants(self, keys)  # (None: the numpy tick)
        self._results = {name: np.full(n, np.nan) for name in METRICS}
        self._finished = np.zeros(n, dtype=bool)
        self._ticks = np.zeros(n, dtype=np.int64)

    #: Arrays with one row per running trial (see :meth:`_compact`).
    _ROWS = (
        "Q", "V", "bias", "xipos", "q_ref", "qd_ref", "tau_ff", "ghost", "jaw_catching_up",
        "jaw_sent", "wrench_sent", "T_hand", "R_hand0", "cond", "t_end", "active", "fault",
        "ticks", "_bad_since", "requested", "T_psm", "J_psm", "T_mtm", "J_mtm", "twist_mtm",
        "index", "n_contacts", "contact_force", "_cond_index",
    )  # fmt: skip

    def _retire(self, rows: np.ndarray) -> None:
        """Keep the results of ``rows`` (current row indices)."""
        result = self.metrics.result()
        where = self.index[rows]
        for name in METRICS:
            self._results[name][where] = getattr(result, name)[rows]
        self._finished[where] = self.state.phase[rows] >= Phase.FINISHED
        self._ticks[where] = self.ticks[rows]

    def _compact(self) -> None:
        """Drop the rows of ended trials, so that the laws run on running trials only."""
        keep = np.flatnonzero(self.active)
        self._retire(np.flatnonzero(~self.active))
        for name in self._ROWS:
            setattr(self, name, getattr(self, name)[keep])
        self._qfrc = self._qfrc[0][keep], self._qfrc[1][keep]
        self.datas = [self.datas[i] for i in keep]
        self.models = [self.models[i] for i in keep]
        self._stepper = self._stepper.take(keep)
        self.trainee = self.trainee.take(keep)
        self.velocity = self.velocity.take(keep)
        self.metrics = self.metrics.take(keep)
        self.state = type(self.state)(*(a[keep] for a in self.state))
        self.n = len(keep)

    # ------------------------------------------------------------ per tick
    def _kinematics(self) -> None:
        """Poses, Jacobians and twists of both arms at the current state (measured_cp / cv)."""
        T, self.J_psm = laws.tip_kinematics(self.psm_chain, self.Q[:, self.psm_q])
        self.T_psm = laws.pose_in_reference(self.T_camera_rcm, T)
        T, self.J_mtm = laws.tip_kinematics(self.mtm_chain, self.Q[:, self.mtm_q])
        self.T_mtm = laws.pose_in_reference(self.T_hrsv_mtmbase, T)
        R = self.T_hrsv_mtmbase[:3, :3]
        self.twist_mtm = laws.twist_in_reference(R, self.J_mtm, self.V[:, self.mtm_v])

    def _hand(self) -> np.ndarray:
        """Trainee step and its hand on the handle: ``xfrc_applied`` of the handle (n, 6)."""
        tr = self.trainee
        t = tr.time  # (the step's: command moves it on)
        x_eq = tr.command(self.dt, self.T_psm[:, :3, 3], self.wrench_sent[:, :3])
        self.T_hand[:, :3, 3] = x_eq
        if tr.wrist is not None:
            self.T_hand[:, :3, :3] = tr.hand_rotations(t, self.R_hand0)
        K, D = tr.stiffness, tr.damping  # (the subject's, × (1 + co-contraction))
        if self._compiled is not None:  # (the same floats in one compiled call)
            return batch_compiled.hand_xfrc(self, K, D)
        w = hand_wrenches(self.T_hand, self.T_mtm, self.twist_mtm, K, D, self.impedance)
        w[:, :3] += tr.push_force()
        R, p = self.R_world_hrsv, self.p_world_hrsv
        return handle_xfrc(w, self.T_mtm[:, :3, 3], R, p, self.xipos)

    def _teleop(self) -> None:
        """The teleoperation's following tick: PSM ``servo_cp`` with feed-forward, jaw."""
        goal = tm.follow_pose(
            self.T_camera_psm0, self.T_hrsv_mtm0, self.T_mtm, self.R_offset, self.scale
        )
        twist = tm.follow_twist(
            self.twist_mtm, self.scale, use_linear=self.use_linear, use_angular=self.use_angular
        )
        q_now = self.Q[:, self.psm_q]
        ik = psm_ik_closed_form_batch(self.psm_chain, self.T_rcm_camera @ goal, q_now)
        ok = ik.success & laws.within_limits(ik.q, self.psm_chain.qmin, self.psm_chain.qmax)
        ok &= ~laws.other_branch_rows(ik.q, q_now)  # (the live servo_cp refuses it: held)
        qd = laws.joint_velocity(self.J_psm, rotate_pairs(self.T_rcm_camera[:3, :3], twist))
        rows = np.flatnonzero(ok)
        self.q_ref[np.ix_(rows, self.psm_act)] = ik.q[rows]
        self.qd_ref[np.ix_(rows, self.psm_act)] = qd[rows]
        # Jaw from gripper within the jaw rate (dvrk.md 4.2), sent when it changes.
        gripper = self.Q[:, self.gripper_q].sum(axis=1)
        rate, rate_after_clutch = self.jaw_rates
        self.ghost, self.jaw_catching_up, jaw = tm.follow_jaw(
            self.ghost,
            gripper,
            self.jaw_catching_up,
            rate=rate,
            rate_after_clutch=rate_after_clutch,
            dt=self.dt,
            jaw_scale=self.jaw_s,
            jaw_offset=self.jaw_o,
            jaw_min=self.jaw_spec.qmin,
            jaw_max=self.jaw_spec.qmax,
        )
        changed = jaw != self.jaw_sent
        if np.any(changed):
            self.jaw_sent = np.where(changed, jaw, self.jaw_sent)
            rows = np.flatnonzero(changed)
            self.q_ref[np.ix_(rows, self.jaw_act)] = finger_setpoints(jaw[rows, None])
            self.qd_ref[np.ix_(rows, self.jaw_act)] = 0.0

    def _tracking(self) -> None:
        """The PSM's tracking-error watch (the arm's): a fault ends the trial."""
        bad = laws.tracking_bad(
            self.Q[:, self.psm_q],
            self.q_ref[:, self.psm_act],
            self.psm_tol,
            self.effort_mode[self.psm_act],
        ).any(axis=1)
        self._bad_since, fault = laws.tracking_fault(bad, self._bad_since, self.time)
        fault &= self.active
        self.fault |= fault
        self.active &= ~fault

    def _haptics(self) -> None:
        """The haptic loop on the new state: fixture force → safety clamp → MTM efforts."""
        p = self.T_psm[:, :3, 3]
        v = self.velocity.update(p)
        self.requested = self.fixture_forces(p, v)
        w = np.concatenate([self.requested, np.zeros((self.n, 3))], axis=1)
        self.wrench_sent = clamp_wrenches(w, self.wrench_sent, self.limits, self.dt)
        # spatial/servo_cf: the wrench in the MTM base orientation, Jᵀ·w, clamped to ftmax.
        R_base_hrsv = self.T_hrsv_mtmbase[:3, :3].T
        tau = laws.wrench_effort(self.J_mtm, R_base_hrsv, self.wrench_sent, self.mtm_ftmax)
        self.tau_ff[:, self.mtm_act] = tau

    def fixture_forces(self, p_camera_tip: np.ndarray, v_camera_tip: np.ndarray) -> np.ndarray:
        """Each row's fixture force (n, 3), N, camera axes, for tips at ``p_camera_tip``
        moving at ``v_camera_tip`` ((n, 3), camera frame): the fixture protocol of the live
        haptic loop (:func:`~davinci_sim.haptics.fixture.fixture_force_camera`, the frame
        change and ``fixture.force``), called once per condition with that condition's rows.
        A fixture's law is row-wise, so a row gets the same bits in any batch."""
        T = self.T_task_camera
        if len(self.fixtures) == 1:
            (fixture,) = self.fixtures.values()
            return fixture_force_camera(fixture, T, p_camera_tip, v_camera_tip)
        out = np.zeros((self.n, 3))
        for c, fixture in self.fixtures.items():
            rows = np.flatnonzero(self.cond == c)
            if len(rows):
                out[rows] = fixture_force_camera(fixture, T, p_camera_tip[rows], v_camera_tip[rows])
        return out

    def _task(self) -> None:
        """The task on the new state: one :class:`~davinci_sim.tasks.Sample` of every trial
        (tip in the task frame, the guidance force requested; the trainees never clutch)
        through the state machine and the metrics (:func:`~davinci_sim.tasks.state.advance`,
        as the live trial's monitor); a trial ends when finished or timed out."""
        T = self.T_task_camera
        p_camera = self.T_psm[:, :3, 3]
        tip = rotate_rows(T[:3, :3], p_camera) + T[:3, 3]
        sample = Sample.of(
            self.time, tip, self.requested, visible=in_left_image(p_camera, self.camera),
            master=self.T_mtm[:, :3, 3], contacts=self.n_contacts, tool_force=self.contact_force,
        )  # fmt: skip
        # A trial that has ended keeps its state.
        self.state, _ = advance(self.task, self.state, self.metrics, sample, self.active)
        phase = self.state.phase
        done = (phase >= Phase.FINISHED) | (self.time >= self.t_end - 1e-9)
        self.active &= ~done

    def tick(self) -> None:
        """One 1 ms tick of every running trial."""
        xfrc = self._hand()
        if self._compiled is not None:
            batch_compiled.tick(self, xfrc)
            return
        self._teleop()
        self._tracking()
        ctrl = servo_ctrl(
            self.Q[:, self._servo.qposadr],
            self.V[:, self._servo.dofadr],
            self.bias,
            self.q_ref,
            self.qd_ref,
            self.tau_ff,
            self.effort_mode,
            self.gravity,
            self._servo.kp,
            self._servo.kv,
        )
        Q, V, xipos = self.Q, self.V, self.xipos
        # MuJoCo's bias forces, whole rows (one copy each per trial, the servo's law below
        # once for the batch)
        qfrc_bias, qfrc_gravcomp = self._qfrc
        active = np.flatnonzero(self.active)
        # mj_step of every running trial in one compiled call (sim.rows_step)
        self._stepper.step(active, ctrl, xfrc, Q, V, qfrc_bias, qfrc_gravcomp, xipos)
        self._contacts.measure_rows(self.models, self.datas, active, self.n_contacts,
                                    self.contact_force)  # fmt: skip
        self.bias[active] = self._servo.bias_of(qfrc_bias[active], qfrc_gravcomp[active])
        self.ticks += self.active
        self.time += self.dt
        self._kinematics()
        self._haptics()
        self._task()

    def run(
        self,
        on_done: Callable[[int], None] | None = None,
        on_row: Callable[[int, dict], None] | None = None,
        on_tick: Callable[[TrialBatch], None] | None = None,
    ) -> list[dict]:
        """Tick until every trial has ended (a chunk of ticks at a time, ``batch_chunk``,
        unless ``on_tick``); returns the rows in ``specs`` order.

        ``on_done(k)`` is called with the number of trials that ended (for a progress bar);
        ``on_row(i, row)`` with each trial's row as soon as it ends (``i``: its position in
        ``specs``; the same row object is in the returned list), so that a caller can keep
        it before the batch ends. Row timings: ``sim_time`` is the trial's own simulated
        time (from the handle taken to its end); ``wall_time`` its share of the batch's
        wall time: the set-up shared equally, each chunk's shared among the trials running
        in it. ``on_tick(batch)``: after every tick (a recorder)."""
        n = len(self.specs)
        rows: list[dict | None] = [None] * n
        wall = np.full(n, self.setup_wall / n)
        running, clock = self.n, time.perf_counter
        t_tick = clock()
        while running:
            ran = self.index[self.active]  # the trials these ticks run
            chunk = on_tick is None and batch_chunk.can_chunk(self)
            batch_chunk.advance(self) if chunk else self.tick()  # (the same bits)
            if on_tick is not None:
                on_tick(self)
            now = clock()
            wall[ran] += (now - t_tick) / running
            t_tick = now
            still = int(self.active.sum())
            if still != running:
                if on_done is not None:
                    on_done(running - still)
                self._emit(rows, wall, on_row)
            running = still
            # Halve the arrays whenever half the trials have ended: the per-tick cost of
            # the laws grows with the rows, ended or not.
            if running <= self.n // 2 and self.n >= COMPACT_MIN_ROWS:
                self._compact()
        self._emit(rows, wall, on_row)
        return rows  # type: ignore[return-value]

    def _emit(self, rows: list, wall: np.ndarray, on_row) -> None:
        """Make the rows of the trials that have ended and have no row yet."""
        new = [int(k) for k in np.flatnonzero(~self.active) if rows[self.index[k]] is None]
        if not new:
            return
        self._retire(np.array(new))
        result = SimpleNamespace(**self._results)
        for k in new:
            i = int(self.index[k])
            row = trial_row(self.specs[i], self.task, result, i, bool(self._finished[i]))
            row["sim_time"] = float(self._ticks[i]) * self.dt
            row["wall_time"] = float(wall[i])
            rows[i] = row
            if on_row is not None:
                on_row(i, row)

    setup_wall = 0.0
    """Wall time of building the batch, s (set by :func:`run_batch`)."""


def run_batch(
    specs: list[TrialSpec],
    on_done: Callable[[int], None] | None = None,
    on_row: Callable[[int, dict], None] | None = None,
    on_tick: Callable[[TrialBatch], None] | None = None,
) -> list[dict]:
    """Run ``specs`` (one task and seed) as one :class:`TrialBatch`; rows in ``specs`` order
    (``on_done``, ``on_row``, ``on_tick``: see :meth:`TrialBatch.run`)."""
    wall0 = time.perf_counter()
    batch = TrialBatch(specs)
    batch.setup_wall = time.perf_counter() - wall0
    try:
        return batch.run(on_done, on_row, on_tick)
    finally:
        batch._setup.sim.close()
