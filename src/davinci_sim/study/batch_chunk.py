"""The study batch's ticks a chunk at a time (:func:`advance`): every trial stepped up to
:data:`CHUNK_TICKS` ticks in a row by one compiled call
(:func:`~davinci_sim.study.chunk_rows.chunk_rows`), then the task's state machine and
metrics on each tick's recorded samples, in tick order, as :meth:`TrialBatch._task` runs
them. The same bits as that many :meth:`TrialBatch.tick` calls
(``tests/study/test_batch_chunk.py``): the trials are independent, and what a trial did
after its task ended (the chunk runs its K ticks before the task has seen them) is dropped:
its tick count, a tracking fault there.

A tick the chunk has no compiled form of (a goal whose IK needs Python; a step that left
contacts to measure) stops it: the state of the chunk's start is restored (the arrays
copied, each trial's MuJoCo state with ``mj_setState``), the chunk runs again up to that
tick, and that tick runs as :meth:`TrialBatch.tick`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

from davinci_sim.geometry.so3 import rotate_rows
from davinci_sim.model.cameras import in_left_image
from davinci_sim.operators.trainee import owned
from davinci_sim.sim.live_period import contact_count_address
from davinci_sim.study import batch_compiled
from davinci_sim.tasks import Phase, Sample, path_row
from davinci_sim.tasks.metrics_one import running
from davinci_sim.tasks.state import advance as advance_task

if TYPE_CHECKING:
    from davinci_sim.study.batch import TrialBatch

#: Ticks of one trial in a row (each trial's first step of a chunk is the cold one).
CHUNK_TICKS = 50

_STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION

#: The batch's arrays a chunk writes (restored when it stops).
_BATCH = ("Q", "V", "xipos", "bias", "q_ref", "qd_ref", "tau_ff", "T_psm", "J_psm", "T_mtm",
          "J_mtm", "twist_mtm", "ghost", "jaw_catching_up", "jaw_sent", "requested",
          "wrench_sent", "_bad_since", "active", "fault", "T_hand")  # fmt: skip
#: The wrist's turns of a trainee without any (the chunk's arguments keep their types).
_NO_KNOTS, _NO_TURNS = np.zeros(2), np.zeros((2, 3))
#: The trainees' arrays a chunk writes.
_TRAINEE = ("co_contraction", "_obs", "t_reach", "reach_from", "reach_time", "t_follow",
            "_v_plan", "feedforward_force", "last_tremor_force", "x_eq", "v_eq")  # fmt: skip


def can_chunk(batch: TrialBatch) -> bool:
    """Whether :func:`advance` can run ``batch``: its tick is compiled, numba has the chunk
    and no trial has contacts (measured, or in its last step: a scene whose objects rest in
    contact ticks one tick at a time rather than stopping every chunk at its first tick)."""
    return (
        batch_compiled.CHUNK is not None
        and batch._compiled is not None
        and not batch.n_contacts.any()
        and batch.trainee.dt == batch.dt
        and not any(batch.datas[i].ncon for i in np.flatnonzero(batch.active).tolist())
        and _ncon_addresses(batch) is not None
    )


def advance(batch: TrialBatch, ticks: int = CHUNK_TICKS) -> int:
    """Up to ``ticks`` ticks of ``batch`` (fewer at the end of the trainees' drawn noise or
    where a tick needs Python); returns how many."""
    tr = batch.trainee
    white = tr._noise.ahead(ticks)
    K = white.shape[1]
    saved = _save(batch)
    while True:
        stopped, records = _chunk(batch, K, white)
        if stopped < 0:
            break
        _restore(batch, saved)
        if stopped == 0:  # (the chunk's first tick needs Python)
            batch.tick()
            return 1
        K = stopped  # (every trial ran these ticks without stopping: run them again)
    tr._noise.skip(K)
    tr.k += K
    _tasks(batch, K, saved[("b", "fault")], *records)
    return K


def _chunk(batch: TrialBatch, K: int, white: np.ndarray) -> tuple[int, tuple]:
    """One compiled chunk of K ticks; the tick it stopped before (−1: none) and the
    records."""
    n = batch.n
    tr = batch.trainee
    Y, F = np.empty((n, 3)), np.empty((n, 3))
    feel = tr.mechanisms.stiffening_gain > 0
    tr_args = tr.row_args(Y, F, feel, np.zeros((n, 6)))
    impedance, R, p = batch_compiled.hand_constants(batch)
    wrist = tr.wrist
    turning = wrist is not None
    hand = (batch.T_hand, impedance, R, p, batch.xipos, batch.R_hand0,
            wrist.progress if turning else _NO_KNOTS, wrist.turn if turning else _NO_TURNS,
            turning, float(tr.path.length))  # fmt: skip
    xfrc = np.empty((n, 6))
    tip, force, master = np.empty((K, n, 3)), np.empty((K, n, 3)), np.empty((K, n, 3))
    alive = np.empty((K, n), dtype=bool)
    params = tr.params
    row, stopped = batch_compiled.CHUNK.chunk_rows(
        K, float(batch.time), float(batch.dt), np.ascontiguousarray(batch.t_end, dtype=float),
        batch_compiled.teleop_args(batch), batch_compiled.physics_args(batch, xfrc), tr_args,
        int(tr.k), float(tr.dt), np.ascontiguousarray(white[:, :K]),
        owned(params.stiffness), owned(params.damping), hand, _ncon_addresses(batch), tip,
        force, master, alive,
    )  # fmt: skip
    return (-1 if row < 0 else int(stopped)), (tip, force, master, alive)


def _tasks(batch: TrialBatch, K: int, fault0, tip, force, master, alive) -> None:
    """The task on each of the K ticks' samples, in order (:meth:`TrialBatch._task`), the
    tick counts and the trials' ends; what a trial did after its task ended is dropped
    (``fault0``: the faults before the chunk)."""
    T = batch.T_task_camera
    counted = np.zeros(batch.n, dtype=np.int64)
    ended = np.zeros(batch.n, dtype=bool)
    if not _tasks_compiled(batch, K, tip, force, master, alive, counted, ended):
        _tasks_python(batch, K, T, tip, force, master, alive, counted, ended)
    batch.ticks += counted
    # A trial that its task ended keeps no fault from the ticks the chunk ran after it.
    batch.fault[ended & ~fault0] = False
    batch.active &= ~ended


def _tasks_compiled(batch: TrialBatch, K: int, tip, force, master, alive, counted,
                    ended) -> bool:  # fmt: skip
    """:func:`_tasks_python` in one compiled call (``chunk_rows.task_rows``) for a path
    task scoring its own declaration; False (nothing done) for any other."""
    from davinci_sim.tasks.task import PathTask

    metrics, task, n = batch.metrics, batch.task, batch.n
    if not path_row.COMPILED or type(task) is not PathTask or not metrics.floats:
        return False
    constants = path_row._constants(task)
    prev = metrics._prev
    fields = ("time", "tip", "force", "clutch", "visible", "master", "contacts", "tool_force")
    if constants is None or (prev is not None and any(getattr(prev, k) is None for k in fields)):
        return False
    if prev is None:
        kept = (np.empty(n), np.empty((n, 3)), np.empty((n, 3)), np.empty(n, dtype=bool),
                np.empty(n, dtype=bool), np.empty((n, 3)), np.empty(n, dtype=np.int64),
                np.empty(n))  # fmt: skip
    else:
        kept = tuple(np.array(getattr(prev, k)) for k in fields)
    camera = batch.camera  # (path_row's pinhole: focal length, half baseline, image size)
    lens = np.array([camera.focal_px, camera.baseline_m / 2.0, camera.width, camera.height], float)
    state = path_row.next_state(batch.state)
    sample = (np.empty(n), np.empty((n, 3)), np.empty(n, dtype=bool), np.empty(n, dtype=bool))
    prev_in = metrics._prev_in.copy()
    batch.time = batch_compiled.CHUNK.task_rows(
        K, float(batch.time), float(batch.dt), np.ascontiguousarray(batch.t_end, dtype=float),
        np.ascontiguousarray(batch.T_task_camera, dtype=float),
        lens,
        constants, prev is not None, tuple(state), tip, force, master, alive,
        np.ascontiguousarray(batch.n_contacts, dtype=np.int64),
        np.ascontiguousarray(batch.contact_force, dtype=float), kept, running(metrics), prev_in,
        ended, counted, sample,
    )  # fmt: skip
    batch.state = state
    metrics._prev = Sample(*kept[:4], visible=kept[4], master=kept[5], contacts=kept[6],
                           tool_force=kept[7])  # fmt: skip
    metrics._prev_in = prev_in
    return True


def _tasks_python(batch: TrialBatch, K: int, T, tip, force, master, alive, counted,
                  ended) -> None:  # fmt: skip
    """The task on each tick's sample through :func:`~davinci_sim.tasks.state.advance`."""
    for j in range(K):
        batch.time += batch.dt
        mask = alive[j] & ~ended  # (the trials this tick ran, as the tick's active rows)
        counted += mask
        p_camera = tip[j]
        sample = Sample.of(
            batch.time, rotate_rows(T[:3, :3], p_camera) + T[:3, 3], force[j],
            visible=in_left_image(p_camera, batch.camera), master=master[j],
            contacts=batch.n_contacts, tool_force=batch.contact_force,
        )  # fmt: skip
        batch.state, _ = advance_task(batch.task, batch.state, batch.metrics, sample, mask)
        done = (batch.state.phase >= Phase.FINISHED) | (batch.time >= batch.t_end - 1e-9)
        ended |= done & mask


def _save(batch: TrialBatch) -> dict:
    """Copies of what a chunk writes: the batch's and the trainees' arrays, the velocity
    filter, and each running trial's MuJoCo state."""
    tr, vf = batch.trainee, batch.velocity
    saved: dict = {("b", k): getattr(batch, k).copy() for k in _BATCH}
    saved.update({("t", k): getattr(tr, k).copy() for k in _TRAINEE})
    saved["qfrc"] = tuple(a.copy() for a in batch._qfrc)
    saved["vf"] = (vf._p.copy(), vf._v.copy(), vf._started.copy())
    saved["motor"] = tr._motor.state.copy()
    tremor = tr._tremor
    saved["tremor"] = (tremor._x.copy(), tremor._y1.copy(), tremor._y2.copy())
    size = mujoco.mj_stateSize(batch.models[0], _STATE_SPEC)
    mj = {}
    for i in np.flatnonzero(batch.active).tolist():
        state = np.empty(size)
        mujoco.mj_getState(batch.models[i], batch.datas[i], state, _STATE_SPEC)
        mj[i] = state
    saved["mj"] = mj
    return saved


def _restore(batch: TrialBatch, saved: dict) -> None:
    """Back to :func:`_save`'s copies, in place (the kernels hold the arrays)."""
    tr, vf = batch.trainee, batch.velocity
    for (where, name), a in ((k, v) for k, v in saved.items() if isinstance(k, tuple)):
        np.copyto(getattr(batch if where == "b" else tr, name), a)
    for a, b in zip(batch._qfrc, saved["qfrc"], strict=True):
        np.copyto(a, b)
    for a, b in zip((vf._p, vf._v, vf._started), saved["vf"], strict=True):
        np.copyto(a, b)
    np.copyto(tr._motor.state, saved["motor"])
    tremor = tr._tremor
    for a, b in zip((tremor._x, tremor._y1, tremor._y2), saved["tremor"], strict=True):
        np.copyto(a, b)
    for i, state in saved["mj"].items():
        mujoco.mj_setState(batch.models[i], batch.datas[i], state, _STATE_SPEC)


def _ncon_addresses(batch: TrialBatch) -> np.ndarray | None:
    """The address of each trial's contact count (cached by the data it belongs to), or
    None where MuJoCo's ``mjData`` layout is not the one known (no chunks then)."""
    cache = batch.__dict__.setdefault("_ncon_cache", {})
    out = np.empty(batch.n, dtype=np.intp)
    for i, d in enumerate(batch.datas):
        if id(d) not in cache:
            cache[id(d)] = contact_count_address(d)
        a = cache[id(d)]
        if a is None:
            return None
        out[i] = a
    return out
