"""The rows of :class:`~davinci_sim.console.chunk.ConsoleChunk`'s kernel
(:func:`~davinci_sim.console.chunk_kernel.console_chunk`): what each kind of component gives
it — a simulated MTM (its hand, its read, its arm's orientation lock), a following
teleoperation (its anchors, its jaw, its PSM's servo_cp constants, the fixture the haptic
loop renders for its MTM), the camera teleoperation while it follows (its anchors, the ECM's
constants, its hands' clamps) — built from the live objects as their Python ticks read them,
or None where such a tick needs Python; and which components are idle (their ticks do
nothing in the chunk's state). Arrays the kernel updates in place are the objects' own where
they are arrays (the velocity filters), copies otherwise (written back by the chunk).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from davinci_sim.console import haptic_row
from davinci_sim.console import teleop_math as tm
from davinci_sim.console.haptic_loop import HapticLoop
from davinci_sim.console.teleop_ecm import TeleopECM
from davinci_sim.console.teleop_psm import DISABLED, ENABLED, TeleopPSM
from davinci_sim.devices import hand_input_row
from davinci_sim.devices.hand_input import HandInput
from davinci_sim.devices.simulated import SimulatedMTM
from davinci_sim.haptics.fixture import FixtureField
from davinci_sim.haptics.fixture_row import VISCOUS, ZERO_LAW_PATH, path_constants
from davinci_sim.kinematics import fk
from davinci_sim.kinematics.arms import load_arm
from davinci_sim.sim.arms import (
    _LOCK_DAMPING,
    _LOCK_STEPS,
    MTM,
    MTM_WRIST_JOINTS,
    PSM,
    PSM_SAFE_CARTESIAN_DISTANCE,
)


@dataclass(frozen=True)
class SampleRequest:
    """What a component samples after every step (``chunk_part()``'s answer of a task
    session): the tool of ``teleop`` (its PSM's tip in the camera frame), the guidance force
    its MTM's haptic loop requested and its master's position; the chunk calls
    ``take(t, T_cart_camera, T_camera_tip, requested, master, readings, contacts, clutch)``
    after each call (deferred: at its flush) with the m whole ticks' samples since, in order:
    (m,) s, (m, 4, 4), (m, 4, 4), (m, 3) N, (m, 3) m, the objects' readings (below; None
    without objects), the contacts measured (below; None where not measured), the clutch
    (the same for the calls: a pedal's press or release is a Python tick's). Without
    ``contacts``, a tick whose step leaves a contact of the instrument with something it
    counts ends the call before its post-steps (the session measures it in Python)."""

    teleop: str
    take: Any
    tool_geom: np.ndarray
    """(ngeom + 1,) bool: the instrument's geoms (``InstrumentContacts.tool_geom``; the
    last, false: a flex's side of a contact, geom −1)."""
    other_geom: np.ndarray
    """(ngeom + 1,) bool: the geoms whose contact with the instrument counts."""
    objects: Any = None
    """The kind's :class:`~davinci_sim.tasks.objects_probe.ObjectsProbe` (None: none): the
    chunk reads its objects after each step and ``take`` gets the readings,
    ``(xpos (m, k, 3), xmat (m, k, 9), grasp (m, k), tips (m, A, 3), flex_force (m,))``."""
    contacts: Any = None
    """The instruments' :class:`~davinci_sim.tasks.trainer.InstrumentContacts` (None: not
    measured): the chunk measures them after each step, as its ``measure`` does, and
    ``take`` gets ``(count (m,), force (m,) N)``."""


def floats(a) -> np.ndarray:
    """A writable C-ordered float copy (the kernel's one signature)."""
    return np.array(a, dtype=float, order="C")


SLOTS = 2
"""The kernel's slots for devices and for following teleoperations (a console has two MTMs,
each following at most one PSM): fewer fill theirs with a filler, more keep Python's
ticks. One compiled signature whatever the console's state."""


def filled(rows: list) -> tuple | None:
    """``rows`` in the kernel's :data:`SLOTS` slots: each slot left holds a filler (the first
    row marked off: its arrays shared, never written); None for none or more than fit."""
    if not rows or len(rows) > SLOTS:
        return None
    filler = (*rows[0][:-1], np.zeros(1, dtype=bool))
    return (*rows, *((filler,) * (SLOTS - len(rows))))


def indices(*values) -> np.ndarray:
    """Indices (addresses, rows) as the kernel's ``intp`` array."""
    return np.array(values, dtype=np.intp)


def no_fixture() -> tuple:
    """A fixture of the kernel's types for a teleoperation without one (never used)."""
    path = path_constants(ZERO_LAW_PATH)
    assert path is not None
    return (*path, 0.0, 0.0, 0.0, False, VISCOUS, 0, np.zeros(6), 0.001, 0.5, np.zeros(4),
            np.zeros(7))  # fmt: skip


def _lock_on(arm: MTM, servo) -> bool:
    """Whether the MTM's orientation lock drives its wrist (``MTM._pre_step``: a lock goal
    while the arm is in effort mode)."""
    return arm._R_lock is not None and bool(servo.effort_mode[arm._idx[0]])


def _device_ready(d: SimulatedMTM, servo) -> bool:
    """Whether a simulated MTM's tick has the kernel's form now: no watchdog, its arm in
    effort mode or holding (no trajectory, impedance or user base frame), the orientation
    lock driving the wrist already or off, a spatial wrench if any."""
    arm = d.arm
    if d.watchdog is not None or d._was_stale or d._input is None:
        return False
    if arm._T_user_base is not None or arm._impedance is not None or arm._traj is not None:
        return False
    if arm.gripper._traj is not None or arm.base_frame()[0] is not arm.kin.T_reference_base:
        return False
    lock_on = _lock_on(arm, servo)
    if lock_on and arm._lock_traj is None:
        return False  # (the lock's first tick starts its trajectory: Python's)
    if not lock_on and (arm._lock_traj is not None or arm._lock_goal is not None):
        return False
    wrench = arm._wrench
    return wrench is None or not wrench[1].any() or wrench[0] == "spatial"


def device_row(
    d: SimulatedMTM, servo, cache: dict, check: bool = True, rate: HandInput | None = None
) -> tuple | None:
    """A simulated MTM's row: its hand, its read's outputs, its arm's lock and the rate
    input ``rate`` that moves its hand (if any), or None where its tick needs Python
    (without ``check``: the row as it is, for the kernel's types)."""
    arm = d.arm
    if not isinstance(arm, MTM) or (check and not _device_ready(d, servo)):
        return None
    lock_on = _lock_on(arm, servo) and arm._lock_traj is not None
    static = cache.get(d.name)
    if static is None or static[0] is not arm:
        static = cache[d.name] = (arm, *_device_static(d))
    (_, fk_c, adr, vadr, grip_adr, T_ref_base, R_hrsv_base, R_world_hrsv, p_world_hrsv,
     body, q, T, J, F, T_hrsv, twist, xfrc, gripper, lock_c, wrist_idx,
     idx) = static  # fmt: skip
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
        R_base_goal = floats(arm.base_frame()[0][:3, :3].T @ arm._R_lock)  # (MTM._lock_seed)
    lock = (*lock_c[:5], R_base_goal, *lock_c[5:], float(ratio))
    if check:  # (the handle where the last read left it: the rate input's lead)
        T_hrsv[:, :] = d._input.T_hrsv_tip
    return (
        fk_c, adr, vadr, grip_adr, T_ref_base, R_hrsv_base, flags,
        floats(np.eye(4) if target is None else target), impedance, floats(d._push), R_world_hrsv,
        p_world_hrsv, body, np.array([d._hand_applied]), floats(d._hand_wrench), q, T, J, F,
        T_hrsv, twist, xfrc, gripper, lock, lock_flags, lock_traj, lock_goal, wrist_idx, idx,
        hand_part(rate, d._hand_velocity), np.ones(1, dtype=bool),
    )  # fmt: skip


def hand_part(hand: HandInput | None, velocity: np.ndarray) -> tuple:
    """The rate input's part of its device's row: ``(on, state, params)``: whether it holds
    the handle, and its state and parameters as
    :func:`~davinci_sim.devices.hand_input_row.hand_rate_row` takes them; ``velocity`` the
    device's hand target's velocity now (6,: its next read's)."""
    on = np.array([hand is not None and hand._holding])
    state, params = np.zeros(hand_input_row.STATE_SIZE), np.zeros(hand_input_row.PARAMS_SIZE)
    state[21:27] = velocity
    if hand is not None:
        state[:3], state[3:6], state[6:9], state[9:12] = (
            hand._target, hand._origin, hand._v, hand._w)  # fmt: skip
        params[:4] = hand.max_lead, hand.workspace, hand._v_until, hand.max_turn_lead
        if hand._R_target is not None:
            state[12:21] = hand._R_target.ravel()
            params[4] = 1.0
    return on, state, params


def hand_movable(hand: HandInput, t: float) -> bool:
    """Whether a rate input's tick has the kernel's form from time ``t`` (s) on: no gripper
    squeeze pending, no first turn (it grasps the wrist: a turn while the wrist's target is
    held has the kernel's form), its device's target a pose whose orientation it keeps."""
    if not hand._holding:
        return True
    turning = t < hand._v_until and hand._w.any()
    if hand._gripper is not None or (turning and hand._R_target is None):
        return False
    d = hand.device
    if not isinstance(d, SimulatedMTM) or not d._hand_on or d._hand_target is None:
        return False
    R = hand._R_target
    return R is None or bool(np.array_equal(d._hand_target[:3, :3], R))


def _teleop_ready(tel: TeleopPSM, servo) -> bool:
    """Whether a following teleoperation's PSM takes its goal by the compiled law now:
    ready for Cartesian control, no trajectory or wrench, nothing but the references set."""
    psm = tel.psm
    if psm._T_user_base is not None or psm._refusals or psm._not_ready(cartesian=True):
        return False
    if psm._traj is not None or psm._wrench is not None or psm.jaw._traj is not None:
        return False
    return not (servo.effort_mode[psm._idx].any() or servo.tau_ff[psm._idx].any())


def teleop_row(
    tel: TeleopPSM,
    device: int,
    haptics: HapticLoop | None,
    servo,
    rows: dict,
    cache: dict,
    no_fixture: tuple,
    check: bool = True,
) -> tuple | None:
    """A following teleoperation's row (and its fixture's, if the haptic loop renders
    one for its MTM), or None where its tick needs Python (without ``check``: the row as it
    is, no fixture, for the kernel's types)."""
    psm = tel.psm
    if not isinstance(psm, PSM) or getattr(psm, "_cp", None) is None or psm.name not in rows:
        return None
    if check and not _teleop_ready(tel, servo):
        return None
    static = cache.get(tel.name)
    if static is None or static[0] is not psm:
        static = cache[tel.name] = (psm, *_teleop_static(psm, rows))
    _, cp, adr, idx, row, T_base_ref, shaft, limits, q, T, J, F, q_out, qd_out, jaw_idx = static
    c, spec = tel.config, psm.jaw.spec

    flags = np.array([tel._scale, c.use_mtm_linear_velocity, c.use_mtm_angular_velocity,
                      tel._translation_locked, tel._rotation_locked], dtype=float)  # fmt: skip
    jaw = np.zeros(12)
    jaw[:11] = (tel._ghost, 0.0, tel._jaw_catching_up, c.jaw_rate, c.jaw_rate_after_clutch,
                tel._dt, tel._jaw_s, tel._jaw_o, spec.qmin, spec.qmax,
                tm.JAW_CATCH_UP_TOLERANCE)  # fmt: skip
    jaw_state = np.array([tel._jaw_sent, float(tel._ignore_jaw)])
    anchors = (floats(tel._T_camera_psm0), floats(tel._T_hrsv_mtm0), floats(tel._R_offset))
    fixture = fixture_part(tel, haptics if check else None, no_fixture)
    if fixture is None:
        return None
    return (cp, adr, idx, row, T_base_ref, shaft, anchors, flags, jaw, jaw_state, limits,
            indices(device), q, T, J, F, q_out, qd_out, *fixture, jaw_idx,
            np.ones(1, dtype=bool))  # fmt: skip


def fixture_part(tel: TeleopPSM, haptics: HapticLoop | None, no_fixture: tuple) -> tuple | None:
    """The fixture part of ``tel``'s row: ``(constants, state, outputs)``, inactive where
    the loop renders nothing for its MTM; None where it renders in Python."""
    dof = tel.device.arm.dof
    out = (np.zeros(6), np.zeros(6), np.zeros(dof), np.zeros(1, dtype=bool))
    entries = [] if haptics is None else haptics.entries_for(tel.mtm_name)
    if not entries:
        state = (np.zeros(2, dtype=bool), np.zeros(3), np.zeros(3), np.zeros(6))
        return (*no_fixture[:-1], np.zeros(dof)), state, out
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
    _, path, B, G_max, transition, summed, law, law_fn, params = row
    constants = (*path, float(B), float(G_max), float(transition), bool(summed), int(law),
                 int(law_fn), floats(params), float(vf.dt), float(vf.alpha), floats(steps),
                 floats(ftmax))  # fmt: skip
    state = (np.array([True, bool(vf._started)]), vf._p, vf._v, floats(previous))
    return constants, state, out


def copied(a):
    """A copy of an array (a constant the kernel must not share), anything else as it is."""
    return a.copy() if isinstance(a, np.ndarray) else a


def teleop_role(tel: TeleopPSM) -> str | None:
    """``"follow"``, ``"idle"`` (its tick does nothing now) or None (its tick needs Python)."""
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


def ecm_idle(tel: TeleopECM) -> bool:
    """Whether the camera teleoperation's tick does nothing now (disabled, or enabled and
    not following, its arms ready)."""
    if tel._current == DISABLED:
        return tel._desired == DISABLED
    if tel._current != ENABLED or tel._desired == DISABLED or tel._following:
        return False
    ecm = tel.ecm.operating_state()
    return ecm.state == "ENABLED" and ecm.is_homed and tel._devices_ready()


def _device_static(d: SimulatedMTM) -> tuple:
    """A simulated MTM's constants and the kernel's scratch for it."""
    arm = d.arm
    dof = arm.dof
    T_ref_base = floats(arm.kin.T_reference_base)
    m = MTM_WRIST_JOINTS.stop - MTM_WRIST_JOINTS.start
    lo, hi = arm._wrist_limits
    v_max, a_max = arm._wrist_v_a
    consts = tuple(copied(a) for a in fk._consts(arm.chain).packed)
    scratch2 = tuple(np.empty_like(a) for a in arm._lock_scratch2)
    lock_c = (*consts, MTM_WRIST_JOINTS.start, _LOCK_STEPS, float(_LOCK_DAMPING), floats(lo),
              floats(hi), *scratch2, floats(v_max), floats(a_max))  # fmt: skip
    del m
    return (
        consts, indices(*arm._qposadr), indices(*arm._dofadr), indices(*arm.gripper._qposadr),
        T_ref_base, floats(T_ref_base[:3, :3]), floats(d._R_world_hrsv), floats(d._p_world_hrsv),
        indices(d._body), np.empty(dof), np.empty((4, 4)), np.empty((6, dof)),
        np.empty((dof, 12)), np.empty((4, 4)), np.empty(6), np.empty(6), np.empty(1), lock_c,
        indices(*arm._wrist_idx), indices(*arm._idx),
    )  # fmt: skip


def _teleop_static(psm: PSM, rows: dict) -> tuple:
    """A PSM's servo_cp constants, addresses, limits and the kernel's scratch for it."""
    constants, bound = psm._cp[0], psm._cp[1]
    dof = psm.dof
    cp = tuple(copied(a) for a in constants)
    shaft = np.array([float(psm._qposadr[2]), float(psm._shaft_offset),
                      PSM_SAFE_CARTESIAN_DISTANCE])  # fmt: skip
    limits = (floats(psm._qmin), floats(psm._qmax), floats(bound))
    return (cp, indices(*psm._qposadr), indices(*psm._idx), indices(rows[psm.name]),
            np.empty((4, 4)), shaft, limits, np.empty(dof), np.empty((4, 4)), np.empty((6, dof)),
            np.empty((dof, 12)), np.empty(dof), np.empty(dof), indices(*psm.jaw._idx))  # fmt: skip


def objects_row(probe, contacts, K: int) -> tuple:
    """The request's objects and contacts part: ``(bodies, object_of, jaw_bit, tips, flags,
    xpos, xmat, grasp, tip_out, flex, flex_out, tool_of, arm_of, counts, f6, count_out,
    force_out)``: an :class:`~davinci_sim.tasks.objects_probe.ObjectsProbe`'s tables,
    ``flags`` (whether there are objects, whether the contacts are measured), the readings
    of each tick (``K`` rows: a call's most ticks), the probe's flex (−1: none) and its
    force each tick, then an :class:`~davinci_sim.tasks.trainer.InstrumentContacts`'
    tables, the force scratch and each tick's count and force; empty for None."""
    if probe is None:
        part = (indices(), np.full(1, -1, dtype=np.intp), np.zeros(1, dtype=np.int64),
                indices(), np.zeros(2, dtype=bool), np.empty((K, 0, 3)), np.empty((K, 0, 9)),
                np.empty((K, 0), dtype=np.int64), np.empty((K, 0, 3)), indices(-1),
                np.zeros(K))  # fmt: skip
    else:
        k, a = len(probe.bodies), len(probe.tips)
        part = (indices(*probe.bodies), np.ascontiguousarray(probe.object_of, dtype=np.intp),
                np.ascontiguousarray(probe.jaw_bit, dtype=np.int64), indices(*probe.tips),
                np.array([True, False]), np.empty((K, k, 3)), np.empty((K, k, 9)),
                np.empty((K, k), dtype=np.int64), np.empty((K, a, 3)), indices(probe.flex),
                np.zeros(K))  # fmt: skip
    if contacts is None:
        return (*part, indices(-1), indices(-1), np.zeros(1, dtype=bool), np.zeros(6),
                np.zeros(K, dtype=np.int64), np.zeros(K))  # fmt: skip
    part[4][1] = True
    return (*part, np.ascontiguousarray(contacts.tool_of, dtype=np.intp),
            np.ascontiguousarray(contacts.arm_of, dtype=np.intp),
            np.ascontiguousarray(contacts.counts, dtype=bool), np.zeros(6),
            np.zeros(K, dtype=np.int64), np.zeros(K))  # fmt: skip


def ecm_following(tel: TeleopECM) -> bool:
    """Whether the camera teleoperation's tick is its following tick now (enabled, its
    anchor set, not clutched, its arms ready)."""
    if tel._current != ENABLED or tel._desired != ENABLED or not tel._following:
        return False
    if tel._clutched or tel._initial is None:
        return False
    ecm = tel.ecm.operating_state()
    return ecm.state == "ENABLED" and ecm.is_homed and tel._devices_ready()


def ecm_row(tel: TeleopECM | None, slots: dict[str, int], cache: dict) -> tuple | None:
    """The camera teleoperation's row: on, :func:`~davinci_sim.console.camera_row.
    ecm_follow`'s constants, the slots of its left and right MTMs, their clamps and
    ``ftmax``, then its outputs (:func:`_ecm_outputs`); or None where its tick needs
    Python: an MTM not in the kernel's ``slots`` (device name → slot), a device that renders
    its wrench in Python, an ECM with a trajectory or a base frame of its own. ``tel``
    None: a row of the kernel's types, off."""
    if tel is None:
        static = cache.get("ECM/none")
        if static is None:
            dof = 7
            fk_none = fk._consts(load_arm("ECM").chain).packed  # (the types: never used)
            zero = ((np.zeros(1, dtype=bool), np.zeros(8), np.zeros(4), np.zeros(3),
                     np.zeros(4), np.zeros((4, 4)), *(copied(a) for a in fk_none),
                     np.empty((4, 4)), np.empty((6, 4)), np.empty((4, 12)), np.eye(3),
                     np.zeros((2, 3, 3)), indices(0, 0, 0, 0), indices(0, 1), np.zeros((2, 6)),
                     np.zeros((2, 4)), np.zeros(dof), np.zeros(dof),
                     *_ecm_outputs(dof)))  # fmt: skip
            static = cache["ECM/none"] = zero
        return static
    ecm = tel.ecm
    left, right = tel.left, tel.right
    if left.name not in slots or right.name not in slots or left is right:
        return None
    if ecm._traj is not None or ecm._T_user_base is not None:
        return None
    args = [d.render_args() for d in (left, right)]
    if any(a is None for a in args):  # (the anchor: ecm_following checked it)
        return None
    chain = ecm.chain
    static = cache.get(tel.name)
    if static is None or static[0] is not ecm:
        q_lim = np.array([chain.qmin, chain.qmax, ecm._qmin, ecm._qmax], dtype=float)
        fk_c = tuple(copied(a) for a in fk._consts(chain).packed)
        static = cache[tel.name] = (ecm, q_lim, fk_c, np.empty((4, 4)), np.empty((6, ecm.dof)),
                                    np.empty((ecm.dof, 12)), indices(*ecm._idx))  # fmt: skip
    _, q_lim, fk_c, T_e, J_e, F_e, ecm_idx = static
    g = tel._initial
    config = tel.config
    geo0 = np.array([*g.center, *g.up, g.half_width, g.half_depth], dtype=float)
    consts = np.array([tel._scale, config.camera_roll_offset, config.hands_stiffness,
                       config.haptic_feedback_ratio], dtype=float)  # fmt: skip
    dof = left.arm.dof
    return (
        np.ones(1, dtype=bool), geo0, consts, floats(tel._friction), floats(tel._q0), q_lim,
        *fk_c, T_e, J_e, F_e, floats(tel._R_base_camera0),
        np.array([tel._R_mtm0[0], tel._R_mtm0[1]], dtype=float), ecm_idx,
        indices(slots[left.name], slots[right.name]),
        np.array([args[0][3], args[1][3]], dtype=float),
        np.array([args[0][4], args[1][4]], dtype=float), floats(args[0][5]), floats(args[1][5]),
        *_ecm_outputs(dof),
    )  # fmt: skip


def _ecm_outputs(dof: int) -> tuple:
    """The camera row's outputs: what the chunk writes back (each hand's efforts, whether
    its clamp acted, the locked orientations), then one tick's, kept once it has run (the
    wrenches let through, the efforts, the clamp, the orientations, the locks' goals)."""
    return (np.zeros(dof), np.zeros(dof), np.zeros(2, dtype=bool), np.zeros((2, 3, 3)),
            np.zeros((2, 6)), np.zeros(dof), np.zeros(dof), np.zeros(2, dtype=bool),
            np.zeros((2, 3, 3)), np.zeros((2, 3, 3)))  # fmt: skip


def keep_camera(plan: Plan) -> None:
    """What the camera teleoperation's compiled ticks leave in its MTMs (``plan.camera``'s
    hands): each device's rendered wrench, its clamp and efforts, and its arm's locked
    orientation, as its last tick left them."""
    camera, e = plan.camera, plan.ecm
    previous, taus, active, R_lock = e[17], (e[21], e[22]), e[23], e[24]
    for k, d in enumerate((camera.left, camera.right)):
        dev = plan.device_rows[plan.devices.index(d)]
        d.rendered(previous[k].copy(), taus[k].copy(), bool(active[k]), dev[15].copy(), dev[4])
        d.arm._R_lock = R_lock[k].copy()


@dataclass
class Plan:
    """A :class:`~davinci_sim.console.chunk.ConsoleChunk` plan: the components its kernel
    ticks for and their rows, as one state of the console has them."""

    devices: list
    hands: list
    teleops: list
    haptics: Any
    request: Any
    device_rows: tuple
    teleop_rows: tuple
    rec: tuple
    moved: dict
    ecm: tuple
    """The camera teleoperation's row (off where it does not follow)."""
    camera: Any = None
    """The camera teleoperation the row follows with, or None."""
    args: Any = None
    """The kernel's arguments but the number of ticks, bound
    (:class:`~davinci_sim.kinematics.bound.Bound`; set at the plan's first call)."""
    kernel: Any = None
    """What the plan's next calls call (the compiled function, once its first call ran)."""
    started: dict = field(default_factory=dict)
    """Each following teleoperation's fixture filter's ``_started`` (found once)."""
    clutch: bool = False
    """The session's teleoperation clutched (not following): its samples' clutch."""
