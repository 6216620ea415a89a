"""``davinci-sim study --record DIR``: every trial of the batch engine to an MCAP file.

One file per trial (``DIR/s<subject>-c<condition>-<block>-r<repetition>.mcap``): a trial
is one episode, the unit a learner or a reviewer takes, and a file per trial opens alone in
Foxglove, is written by whichever worker process runs the trial, and survives a killed
study up to its last chunk like any recording. Each file is an episodes recording
(:class:`~davinci_sim.records.episodes.EpisodeRecorder`, so ``replay --to-dataset`` reads
it): metadata with the trial's spec (subject, condition and its fixture's parameters,
repetition, seed, timeout) and the task file attached; then, every ``period`` ticks of the
batch engine (default 10: the dVRK's 100 Hz publish rate), one step of the trial:

* observation: ``psm_joint_pos`` (rad, m), ``tip_pos`` (the PSM's tool tip in the camera
  frame, m), ``mtm_pos`` (the MTM's handle, HRSV, m), ``guidance_force`` (the fixture's
  force requested, camera frame, N), ``phase`` (the task's phase number);
* action: the PSM's joint references (the servo's ``q_ref``: what the teleoperation
  commanded, rad and m);
* reward: 1 at the step in which the trial finished the path, else 0; terminated: finished,
  truncated: the trial ended otherwise (timeout, a tracking fault);

and the same tip as ``/PSM1/measured_cp`` (``foxglove.PoseInFrame``) and ``/tf``, the
trial's whole-model joint positions (``/sim/qpos``) for Foxglove's 3-D panel; at the end,
the trial's row (``/task/results``). The live engine (``--engine live``) is not recorded.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from davinci_sim.records.episodes import EpisodeRecorder
from davinci_sim.records.jsonvalue import plain
from davinci_sim.records.mcap_schemas import numbers, pose_fields, stamp, time_ns

#: Batch ticks between two recorded steps (the dVRK's publish period at 1 kHz).
DEFAULT_PERIOD = 10
#: Chunk size of a trial's file, bytes: a batch keeps one file per trial open.
TRIAL_CHUNK = 64 * 1024


def trial_file(spec) -> str:
    """The file name of ``spec``'s recording."""
    return f"s{spec.subject:03d}-c{spec.condition}-{spec.block}-r{spec.repetition:02d}.mcap"


class BatchRecorder:
    """Records the trials of one :class:`~davinci_sim.study.batch.TrialBatch` (see the
    module docstring): :meth:`tick` after each batch tick, :meth:`row` with each trial's
    row as it ends.

    Args:
        folder: where the files go (created).
        specs: the batch's trials, in its order.
        period: batch ticks between recorded steps.
    """

    def __init__(self, folder: str | Path, specs, *, period: int = DEFAULT_PERIOD) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.specs = list(specs)
        self.period = max(1, int(period))
        self._files: dict[int, EpisodeRecorder] = {}
        self._ticks = 0

    def _open(self, i: int, batch) -> EpisodeRecorder:
        spec = self.specs[i]
        rec = EpisodeRecorder(
            self.folder / trial_file(spec), env_id="davinci-sim study trial",
            dt=self.period * batch.dt,
            extra={"trial": plain(spec), "task": spec.task, "engine": "batch",
                   "period_ticks": self.period},
            chunk_size=TRIAL_CHUNK,
        )  # fmt: skip
        from davinci_sim.records.recording import task_text

        text = task_text(spec.task)
        if text is not None:
            rec.writer.attach("task.yaml", "text/yaml", text.encode())
        self._files[i] = rec
        return rec

    def tick(self, batch) -> None:
        """After a batch tick: a step of every running trial every ``period`` ticks (and its
        first observation at its first tick)."""
        self._ticks += 1
        if self._ticks % self.period and self._ticks != 1:
            return
        from davinci_sim.tasks import Phase

        phase = batch.state.phase
        for k in np.flatnonzero(batch.active).tolist():
            i = int(batch.index[k])
            rec = self._files.get(i)
            t = float(batch.time - batch.t_start)
            obs = _observation(batch, k)
            if rec is None:
                rec = self._open(i, batch)
                rec.reset(obs, t=t)
            else:
                finished = bool(phase[k] >= Phase.FINISHED)
                rec.step(obs, batch.q_ref[k, batch.psm_act], 0.0, finished, False, t=t)
            _poses(rec, batch, k)

    def row(self, i: int, row: dict, batch=None) -> None:
        """A trial ended (``i``: its position in the batch's specs): its last step and row;
        the file is closed."""
        rec = self._files.pop(i, None)
        if rec is None:
            return
        finished = bool(row.get("finished"))
        t = float(row.get("sim_time", 0.0))
        rec.step(rec.last_observation, rec.last_action, 1.0 if finished else 0.0, finished,
                 not finished, {"row": plain(row)}, t=t)  # fmt: skip
        rec.message("/task/results", "davinci_sim.Event",
                    {"source": "study", "event": "results", "payload": plain(row)})  # fmt: skip
        rec.close()

    def close(self) -> None:
        """Close every file still open (a batch stopped before its trials ended)."""
        for rec in self._files.values():
            rec.close()
        self._files.clear()


def _observation(batch, k: int) -> dict:
    return {
        "psm_joint_pos": batch.Q[k, batch.psm_q].copy(),
        "tip_pos": batch.T_psm[k, :3, 3].copy(),
        "mtm_pos": batch.T_mtm[k, :3, 3].copy(),
        "guidance_force": batch.requested[k].copy(),
        "phase": float(batch.state.phase[k]),
    }


def _poses(rec: EpisodeRecorder, batch, k: int) -> None:
    p, q = pose_fields(batch.T_psm[k])
    pose = {"position": p, "orientation": q}
    rec.message("/PSM1/measured_cp", "foxglove.PoseInFrame", {"frame_id": "ECM", "pose": pose})
    ts = stamp(rec.now)
    transform = {"timestamp": ts, "parent_frame_id": "ECM", "child_frame_id": "PSM1",
                 "translation": p, "rotation": q}  # fmt: skip
    rec.writer.write("/tf", "foxglove.FrameTransforms", time_ns(rec.now),
                     {"transforms": [transform]})  # fmt: skip
    rec.message("/sim/qpos", "davinci_sim.Qpos",
                {"tick": int(batch.ticks[k]), "qpos": numbers(batch.Q[k])})  # fmt: skip
