"""The study batch's compiled tick (:class:`~davinci_sim.study.batch.TrialBatch` with numba):
the constants it packs once, the two kernel calls of :mod:`davinci_sim.study.tick_kernel`
per tick, and their warm-up at import. (Beside ``batch.py``, which is long enough.)

Everything after the trainee's hand runs compiled: the teleoperation with its IK
(``teleop_rows``), then tracking, servo, ``mj_step``, bias forces, both arms' kinematics and
the haptic loop (``physics_rows``). The trainee and the task's state machine stay Python.
The batch's numpy tick is the fallback (a fixture with no compiled law; a tick whose
teleoperation a row needs Python for) and the tests' oracle.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from davinci_sim.console import teleop_math as tm
from davinci_sim.haptics import fixture_row
from davinci_sim.haptics.combine import FixtureSum
from davinci_sim.haptics.fixture_row import path_constants
from davinci_sim.kinematics import fk
from davinci_sim.kinematics.jit import warmed_up
from davinci_sim.kinematics.psm_ik import _DEFAULT_TOLERANCE
from davinci_sim.kinematics.psm_ik import _packed as _ik_packed
from davinci_sim.sim import rows_step

if TYPE_CHECKING:
    from davinci_sim.study.batch import TrialBatch

_KERNELS = None
if rows_step.COMPILED:  # (MuJoCo's library is loaded into LLVM's symbols by rows_step)
    from davinci_sim.devices import device_row
    from davinci_sim.study import chunk_rows as CHUNK
    from davinci_sim.study import tick_kernel as _KERNELS
else:
    CHUNK = None


def constants(batch: TrialBatch, keys) -> dict | None:
    """``batch``'s constants for :func:`tick`, or None (no numba, or a fixture with no
    compiled form): every condition's fixture must be a law the fixture row computes (the
    seed's viscous law, Rota's viscous-elastic one or a spring, alone or as a sum of one,
    on one path, in the task's frame) or none (an empty sum: the viscous law at B = G_max =
    0, a force of ±0 that the sum makes +0). Sets ``batch._cond_index``."""
    if _KERNELS is None or batch.T_task_camera is None or batch._body is None:
        return None
    laws_of = {}
    for key, fixture in batch.fixtures.items():
        parts = fixture.fixtures if isinstance(fixture, FixtureSum) else (fixture,)
        law = _row_law(parts)
        if law is None:
            return None
        laws_of[key] = law
    paths = {id(law[4]) for law in laws_of.values() if law[4] is not None}
    if len(paths) > 1:
        return None
    path = path_constants(next((law[4] for law in laws_of.values() if law[4] is not None),
                               fixture_row.ZERO_LAW_PATH))  # fmt: skip
    if path is None:
        return None
    order = list(laws_of)
    batch._cond_index = np.array([order.index(k) for k in keys], dtype=np.intp)
    c = {
        "B": np.array([laws_of[k][0] for k in order]),
        "G_max": np.array([laws_of[k][1] for k in order]),
        "transition": np.array([laws_of[k][2] for k in order]),
        "law": np.array([laws_of[k][3] for k in order], dtype=np.int64),
        "law_params": np.array([laws_of[k][5] for k in order], dtype=float),
        "path": path,
    }  # fmt: skip
    ik = _ik_packed(batch.psm_chain)
    c["ik"] = (ik.geometry, ik.tool, ik.revolute, ik.lim_lo, ik.lim_hi)
    c["psm_fk"] = fk._consts(batch.psm_chain).packed
    c["mtm_fk"] = fk._consts(batch.mtm_chain).packed
    idx = np.intp
    c["psm"] = (np.asarray(batch.psm_act, idx), np.asarray(batch.psm_q, idx),
                np.asarray(batch.psm_tol, float), batch.psm_chain.qmin,
                batch.psm_chain.qmax)  # fmt: skip
    c["mtm"] = (np.asarray(batch.mtm_q, idx), np.asarray(batch.mtm_v, idx),
                np.asarray(batch.mtm_act, idx), np.asarray(batch.mtm_ftmax, float))  # fmt: skip
    c["jaw"] = (np.asarray(batch.gripper_q, idx), np.asarray(batch.jaw_act, idx))
    servo = batch._servo
    c["servo"] = (np.asarray(servo.qposadr, idx), np.asarray(servo.dofadr, idx),
                  bool(servo._model_gravcomp), servo.kp, servo.kv)  # fmt: skip
    lim = batch.limits
    dt = batch.dt
    c["clamp"] = (float(lim.max_force), float(lim.max_torque),
                  float(lim.max_force_rate * dt), float(lim.max_torque_rate * dt))  # fmt: skip
    return c


def _row_law(parts) -> tuple | None:
    """``(B, G_max, transition, law, path, params)`` of a condition's fixture parts as
    :func:`~davinci_sim.haptics.fixture_row.fixture_law_row` takes them, or None where it
    has no compiled law the batch runs (a user's law keeps the batch on its numpy tick;
    ``path`` None: no force)."""
    if not parts:
        return 0.0, 0.0, 0.0, fixture_row.VISCOUS, None, fixture_row.NO_PARAMS.copy()
    law = fixture_row.compiled_law_of(parts[0]) if len(parts) == 1 else None
    if law is None or law[0] == fixture_row.USER:
        return None
    code, B, G_max, transition, path, _, params = law
    return B, G_max, transition, code, path, params


def hand_xfrc(batch: TrialBatch, K: np.ndarray, D: np.ndarray) -> np.ndarray:
    """The hands' ``xfrc_applied`` (n, 6) of :meth:`TrialBatch._hand` after the trainees'
    step (``K``, ``D`` (n,): their limbs' stiffness and damping now): the hand wrenches,
    the push and ``handle_xfrc`` in one compiled call (``device_row.hand_rows``)."""
    impedance, R, p = hand_constants(batch)
    _contiguous(batch, "T_hand", "T_mtm", "twist_mtm", "xipos")
    xfrc = np.empty((batch.n, 6))
    device_row.hand_rows(
        batch.T_hand, batch.T_mtm, batch.twist_mtm, np.ascontiguousarray(K, dtype=float),
        np.ascontiguousarray(D, dtype=float), impedance, batch.trainee.push_force(), R, p,
        batch.xipos, xfrc,
    )  # fmt: skip
    return xfrc


def hand_constants(batch: TrialBatch) -> tuple:
    """The hands' constants: impedance (rotational stiffness and damping, maximum force and
    torque), HRSV's rotation and origin in the world (kept in ``batch._compiled``)."""
    c = batch._compiled
    if "hand" not in c:
        h = batch.impedance
        c["hand"] = (
            np.array([h.rotational_stiffness, h.rotational_damping, h.max_force, h.max_torque]),
            np.array(batch.R_world_hrsv, dtype=float), np.array(batch.p_world_hrsv, dtype=float),
        )  # fmt: skip
    return c["hand"]


def _contiguous(batch: TrialBatch, *names: str) -> None:
    """The batch's arrays ``names`` as C-ordered arrays (the kernels' one signature; the
    numpy tick may leave a strided result behind)."""
    for name in names:
        a = getattr(batch, name)
        if not a.flags.c_contiguous:
            setattr(batch, name, np.ascontiguousarray(a))


def tick(batch: TrialBatch, xfrc: np.ndarray) -> None:
    """``batch``'s tick after the hand in two compiled calls, the teleoperation in Python
    when a row needs it; the same laws in the same order as :meth:`TrialBatch.tick`'s numpy
    tick."""
    if _KERNELS.teleop_rows(*teleop_args(batch)):
        batch._teleop()
        _contiguous(batch, "ghost", "jaw_catching_up", "jaw_sent")
    _KERNELS.physics_rows(*physics_args(batch, np.ascontiguousarray(xfrc), with_time=True))
    batch._contacts.measure_rows(batch.models, batch.datas, np.flatnonzero(batch.active),
                                 batch.n_contacts, batch.contact_force)  # fmt: skip
    batch.ticks += batch.active
    batch.time += batch.dt
    batch._task()


def teleop_args(batch: TrialBatch) -> tuple:
    """The arguments of ``tick_kernel.teleop_rows`` for ``batch`` (its arrays, written in
    place, and new scratch rows)."""
    c = batch._compiled
    _contiguous(batch, "T_psm", "J_psm", "T_mtm", "J_mtm", "twist_mtm", "requested",
                "wrench_sent", "_bad_since")  # fmt: skip
    n, dof = batch.n, len(batch.psm_act)
    psm_act, psm_q, psm_tol, qmin, qmax = c["psm"]
    q_ik, ok, qd = np.empty((n, dof)), np.empty(n, dtype=bool), np.empty((n, dof))
    rate, rate_after_clutch = batch.jaw_rates
    return (
        batch.T_camera_psm0, batch.T_hrsv_mtm0, batch.T_mtm, batch.R_offset, float(batch.scale),
        bool(batch.use_linear), bool(batch.use_angular), batch.twist_mtm, batch.T_rcm_camera,
        batch.Q, psm_q, batch.J_psm, batch.q_ref, batch.qd_ref, psm_act,
        qmin, qmax, *c["ik"], *c["psm_fk"], _DEFAULT_TOLERANCE,
        *c["jaw"], batch.ghost, batch.jaw_catching_up, batch.jaw_sent, float(rate),
        float(rate_after_clutch), batch.dt, float(batch.jaw_s), float(batch.jaw_o),
        float(batch.jaw_spec.qmin), float(batch.jaw_spec.qmax), tm.JAW_CATCH_UP_TOLERANCE,
        q_ik, ok, qd,
    )  # fmt: skip


def physics_args(batch: TrialBatch, xfrc: np.ndarray, with_time: bool = False) -> tuple:
    """The arguments of ``tick_kernel.physics_rows`` for ``batch`` and the hands'
    ``xfrc`` (n, 6): with the batch's time first, or without it (``PHYSICS_ARGS``, the
    per-row kernels' tuple)."""
    c = batch._compiled
    s = batch._stepper
    psm_act, psm_q, psm_tol, qmin, qmax = c["psm"]
    mtm_q, mtm_v, mtm_act, ftmax = c["mtm"]
    qposadr, dofadr, minus_gravcomp, kp, kv = c["servo"]
    vf = batch.velocity
    qfrc_bias, qfrc_gravcomp = batch._qfrc
    return (
        *((batch.time,) if with_time else ()), s._model, s._data, s._address, batch._body,
        batch.active, batch.fault, batch._bad_since, psm_act, psm_q, psm_tol,
        qposadr, dofadr, minus_gravcomp, kp, kv, batch.effort_mode, batch.gravity,
        batch.Q, batch.V, qfrc_bias, qfrc_gravcomp, batch.xipos, batch.bias, batch.q_ref,
        batch.qd_ref, batch.tau_ff, xfrc,
        *c["psm_fk"], batch.T_camera_rcm, batch.T_psm, batch.J_psm,
        *c["mtm_fk"], batch.T_hrsv_mtmbase, mtm_q, mtm_v, batch.T_mtm, batch.J_mtm,
        batch.twist_mtm, vf._p, vf._v, vf._started, vf.dt, vf.alpha,
        batch.T_task_camera, batch._cond_index, c["B"], c["G_max"], c["transition"], c["law"],
        c["law_params"],
        *c["path"], batch.requested, batch.wrench_sent, *c["clamp"], mtm_act, ftmax,
    )  # fmt: skip


def _warm_up() -> None:
    """Compile (or load from numba's cache) the compiled tick at import, on no rows, with
    the one signature :func:`tick` calls it with (the PSM's and MTM's
    real chain constants, every state array empty): a study's workers then load it."""
    if _KERNELS is None:
        return
    from davinci_sim.kinematics.arms import load_arm

    psm, mtm = load_arm("PSM1").chain, load_arm("MTMR").chain
    ik, psm_fk, mtm_fk = _ik_packed(psm), fk._consts(psm).packed, fk._consts(mtm).packed
    path = path_constants(fixture_row.ZERO_LAW_PATH)
    i, f, b = np.zeros(0, dtype=np.intp), np.zeros(0), np.zeros(0, dtype=bool)
    f2, f3, I4 = np.zeros((0, 6)), np.zeros((0, 4, 4)), np.eye(4)
    tp = (
        I4, I4, f3, np.eye(3), 1.0, True, False, f2, I4, f2, i, f3, f2, f2, i, psm.qmin,
        psm.qmax, ik.geometry, ik.tool, ik.revolute, ik.lim_lo, ik.lim_hi, *psm_fk,
        _DEFAULT_TOLERANCE, i, i, f, b, f, 1.0, 1.0, 0.001, 1.0, 0.0, 0.0, 1.0, 0.01, f2, b, f2,
    )  # fmt: skip
    head = (i, i, np.zeros((0, 7), dtype=np.intp), 0, b, b, f)
    rest = (
        i, i, f, i, i, True, f, f, b, b, f2, f2, f2, f2, f2, f2, f2, f2, f2, f2, *psm_fk, I4, f3,
        f3, *mtm_fk, I4, i, i, f3, f3, f2, f2, f2, b, 0.001, 0.5, I4, i, f, f, f,
        np.zeros(0, dtype=np.int64), f2, *path, f2, f2, 1.0, 1.0, 1.0, 1.0, i, f,
    )  # fmt: skip
    _KERNELS.teleop_rows(*tp)
    _KERNELS.physics_rows(0.0, *head, *rest)
    if CHUNK is not None:  # (the trainees' arrays of no rows, as SyntheticTrainee.row_args)
        f3d, e3 = np.zeros((2, 0, 3)), np.zeros((0, 3))
        trainee = (
            0.001, 0.5, 0.002, 0.3, np.zeros(3), np.array([0.0, 0.01]), np.array([0.0, 0.01]),
            np.array([0.01]), np.zeros((1, 3)), np.array([[0.01, 0.0, 0.0]]), e3, e3, False,
            np.zeros(4), f, np.zeros((0, 2, 3)), np.zeros(0, dtype=np.int64), f, e3, f, f, f, f,
            e3, f, e3, f, np.zeros((0, 1)), f2, np.zeros(2), e3, f, f, f, f, f3d, f3d.copy(),
            f3d.copy(), f, e3, e3.copy(), e3.copy(),
        )  # fmt: skip
        hand = (f3, np.ones(4), np.eye(3), np.zeros(3), e3, np.zeros((0, 3, 3)), np.zeros(2),
                np.zeros((2, 3)), False, 1.0)  # fmt: skip
        records = (np.zeros((1, 0, 3)), np.zeros((1, 0, 3)), np.zeros((1, 0, 3)),
                   np.zeros((1, 0), dtype=bool))  # fmt: skip
        CHUNK.chunk_rows(1, 0.0, 0.001, f, tp, (*head, *rest), trainee, 0, 0.001,
                         np.zeros((0, 1, 6)), f, f, hand, i, *records)  # fmt: skip
        _warm_up_task()


def _warm_up_task() -> None:
    """``chunk_rows.task_rows`` on no ticks of one trial of the seed's task: the types
    ``batch_chunk`` calls it with."""
    from davinci_sim.tasks import load_task, path_row
    from davinci_sim.tasks.metrics_one import running
    from davinci_sim.tasks.state import TaskMonitor

    task = load_task("seed_path")
    constants = path_row._constants(task)
    if not path_row.COMPILED or constants is None:
        return
    monitor = TaskMonitor(task, 1)
    f1, v3, b1 = np.zeros(1), np.zeros((1, 3)), np.zeros(1, dtype=bool)
    kept = (f1, v3, v3.copy(), b1, b1.copy(), v3.copy(), np.zeros(1, dtype=np.int64), f1.copy())
    records = np.zeros((0, 1, 3))
    CHUNK.task_rows(
        0, 0.0, 0.001, f1, np.eye(4), np.ones(4), constants, False,
        tuple(path_row.next_state(monitor.state)), records, records, records,
        np.zeros((0, 1), dtype=bool), np.zeros(1, dtype=np.int64), f1, kept,
        running(monitor.metrics), monitor.metrics._prev_in.copy(), b1.copy(),
        np.zeros(1, dtype=np.int64), (f1.copy(), v3.copy(), b1.copy(), b1.copy()),
    )  # fmt: skip


if not warmed_up(_warm_up, "the study's tick cannot be compiled: its numpy tick runs"):
    _KERNELS = None
