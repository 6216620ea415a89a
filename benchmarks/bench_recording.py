"""Recording to MCAP (:mod:`davinci_sim.records.recording`, ``study/recording.py``): what a
recording costs and how large its files are.

* a session's snapshot (``serve --record``; the task scene ``psm1_ecm_mtmr`` with the seed
  task: 5 arms, console, teleoperation, haptics, task): the write of one snapshot's messages
  (in the recorder's thread, not the loop's), the messages and compressed bytes per
  snapshot, so per simulated second at the 100 Hz publish rate; the snapshot itself is
  timed apart (the loop takes it whether or not anyone records);
* the input log: the cost of logging one call in the loop (``execute`` with and without it);
* a stereo pair as two JPEG ``foxglove.CompressedImage`` (640x480);
* a study trial (the batch engine, ``study --record``): the recorder's time per batch tick
  and trial, and the bytes per simulated second of a trial;
* replay: mode 1 and mode 2 of a short recorded session, simulated seconds per wall second.

``python benchmarks/bench_recording.py`` writes ``results/recording.json``.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

import davinci_sim  # noqa: E402, F401  (sets MUJOCO_GL)
from common import summary, time_each, write  # noqa: E402
from davinci_sim.records.mcap_file import McapWriter, read_mcap  # noqa: E402
from davinci_sim.records.messages import write_images, write_snapshot  # noqa: E402
from davinci_sim.records.recording import recording_description  # noqa: E402
from davinci_sim.sim.handle import execute, take_snapshot  # noqa: E402
from davinci_sim.system import SystemDescription, TaskDescription, build_system  # noqa: E402

SHORT_TASK = str(Path(__file__).resolve().parents[1] / "tests" / "study" / "short_path.yaml")


def session_figures(folder: Path, n: int = 300) -> dict:
    description = recording_description(
        SystemDescription(
            scene="psm1_ecm_mtmr", task=TaskDescription("seed_path"), home=True, runner="none"
        )
    )
    system = build_system(description)
    sim = system.sim
    for _ in range(200):
        sim.tick()
    figures: dict = {}
    snaps = []

    def snapshot() -> None:
        sim.tick()
        snaps.append(take_snapshot(sim))

    ticks = time_each(sim.tick, 50, warmup=5)
    figures.update(summary(ticks, "tick"))
    figures.update(summary(time_each(snapshot, n, warmup=0), "tick_and_snapshot"))
    path = folder / "session.mcap"
    with McapWriter(path) as w:
        it = iter(snaps)
        before = w.messages
        figures.update(
            summary(
                time_each(lambda: write_snapshot(w, next(it)), n - 10, warmup=10), "write_snapshot"
            )
        )
        figures["messages_per_snapshot"] = (w.messages - before) / n
    size = path.stat().st_size
    figures["bytes_per_snapshot"] = size / n
    figures["kB_per_simulated_s_at_100Hz"] = size / n * 100 / 1000
    figures["write_us_per_1ms_tick_at_100Hz"] = figures["write_snapshot_median_us"] / 10
    # the input log: one call through execute, with the log and without it
    T = sim.arms["PSM1"].measured_cp().T.copy()
    with_log = time_each(lambda: execute(sim, "PSM1", "servo_cp", (T,), {}), 500, warmup=50)
    log = sim.components["inputs"]
    sim.remove_component("inputs")
    without = time_each(lambda: execute(sim, "PSM1", "servo_cp", (T,), {}), 500, warmup=50)
    sim.add_component(log)
    figures.update(summary(with_log, "call_logged"))
    figures.update(summary(without, "call_unlogged"))
    # a stereo pair (the scene's own renders)
    from davinci_sim.sim.runtime.render import StereoFrame

    left, right = sim.render_stereo()
    frame = StereoFrame(left, right, sim.tick_count, sim.time, 1, 0.0)
    images = folder / "images.mcap"
    with McapWriter(images) as w:
        figures.update(
            summary(time_each(lambda: write_images(w, frame), 30, warmup=3), "write_stereo_jpeg")
        )
    # (the file holds the same pair 33 times, which zstd shrinks: the JPEGs' own size)
    jpeg = [m["data"] for _, m in read_mcap(images).topic("/endoscope/left/compressed")][0]
    figures["jpeg_bytes_per_stereo_pair"] = 2 * len(jpeg) * 3 / 4  # (base64: 4 chars, 3 bytes)
    system.stop()
    return figures


def study_figures(folder: Path) -> dict:
    from davinci_sim.study import TrialSpec
    from davinci_sim.study.batch import TrialBatch
    from davinci_sim.study.recording import BatchRecorder

    specs = [
        TrialSpec(SHORT_TASK, subject=s, condition=0, B=40.0, G_max=5.0, seed=5, timeout=2.0)
        for s in range(8)
    ]
    batch = TrialBatch(specs)
    recorder = BatchRecorder(folder / "trials", specs)
    spent = [0.0, 0]

    def on_tick(b) -> None:
        t0 = time.perf_counter()
        recorder.tick(b)
        spent[0] += time.perf_counter() - t0
        spent[1] += int(b.active.sum())

    def on_row(i: int, row: dict) -> None:
        t0 = time.perf_counter()
        recorder.row(i, row)
        spent[0] += time.perf_counter() - t0

    t0 = time.perf_counter()
    rows = batch.run(on_row=on_row, on_tick=on_tick)
    wall = time.perf_counter() - t0
    batch._setup.sim.close()
    recorder.close()
    files = sorted((folder / "trials").iterdir())
    size = sum(f.stat().st_size for f in files)
    sim_s = sum(r["sim_time"] for r in rows)
    return {
        "study_trials": len(specs),
        "study_recorder_us_per_trial_tick": 1e6 * spent[0] / max(spent[1], 1),
        "study_recorder_share_of_batch_wall": spent[0] / wall,
        "study_kB_per_simulated_trial_s": size / sim_s / 1000,
        "study_messages_per_trial": int(
            np.mean([sum(map(len, read_mcap(f).messages.values())) for f in files])
        ),
    }


def replay_figures(folder: Path) -> dict:
    from davinci_sim.records.recording import SessionRecorder
    from davinci_sim.records.replay import load_recording, replay_inputs, replay_states

    description = recording_description(
        SystemDescription(scene="psm1", home=True, runner="thread", real_time=False)
    )
    system = build_system(description, start=True)
    path = folder / "replay.mcap"
    recorder = SessionRecorder(path, description).attach(system.handle)
    while system.handle.snapshot().time < 3.0:
        time.sleep(0.01)
    recorder.stop()
    system.stop()
    recording = load_recording(path)
    span = (recording.ticks[-1] - recording.ticks[0]) * 1e-3
    figures = {"replay_recorded_s": float(recording.ticks[-1]) * 1e-3}
    t0 = time.perf_counter()
    check = replay_inputs(recording)
    figures["replay_inputs_sim_s_per_wall_s"] = figures["replay_recorded_s"] / (
        time.perf_counter() - t0
    )
    figures["replay_inputs_bit_equal"] = check.bit_equal
    t0 = time.perf_counter()
    check = replay_states(recording)
    figures["replay_states_sim_s_per_wall_s"] = span / (time.perf_counter() - t0)
    figures["replay_states_bit_equal"] = check.bit_equal
    return figures


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        figures = session_figures(folder)
        figures.update(study_figures(folder))
        figures.update(replay_figures(folder))
    write("recording", figures)


if __name__ == "__main__":
    main()
