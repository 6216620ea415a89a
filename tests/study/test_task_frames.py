"""A task given in the camera frame runs like the same path given in the world frame."""

from __future__ import annotations

import numpy as np
import pytest

from davinci_sim.study import TrialSpec
from davinci_sim.study.batch import run_batch
from davinci_sim.study.trial import setup_trial
from davinci_sim.tasks import load_task


def test_camera_frame_task_gives_the_world_frame_results(short_task, tmp_path):
    world = load_task(short_task)
    setup = setup_trial(world)
    T_camera_world = np.linalg.inv(setup.T_world_camera)
    setup.sim.close()
    text = open(short_task).read()
    lines = []
    for line in text.splitlines():
        if line.strip().startswith("- [") and "waypoints" in "".join(lines):
            p = np.array([float(x) for x in line.strip()[3:-1].split(",")])
            q = (T_camera_world @ np.append(p, 1.0))[:3]
            line = "  - [" + ", ".join(repr(float(x)) for x in q) + "]"
        elif line.startswith("frame:"):
            line = "frame: camera"
        lines.append(line)
    camera_file = tmp_path / "short_camera.yaml"
    camera_file.write_text("\n".join(lines) + "\n")
    assert load_task(camera_file).frame == "camera"

    def spec(task):
        return TrialSpec(
            str(task), subject=1, condition=3, B=60.0, G_max=8.0, repetition=1, order=1,
            practice=3, seed=2, timeout=10.0,
        )  # fmt: skip

    a, b = run_batch([spec(short_task)])[0], run_batch([spec(camera_file)])[0]
    assert a["finished"] and b["finished"]
    for key in ("deviation_error", "completion_time", "path_length", "peak_force"):
        assert b[key] == pytest.approx(a[key], rel=1e-3), key
