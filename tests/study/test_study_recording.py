"""``study --record``: each trial of the batch engine in its own MCAP file, the trial's
states as the batch computed them, and the rows unchanged by the recording."""

from __future__ import annotations

import json

import numpy as np
import pytest

from davinci_sim.records.dataset import to_dataset
from davinci_sim.records.mcap_file import read_mcap
from davinci_sim.study import TrialSpec
from davinci_sim.study.batch import run_batch
from davinci_sim.study.recording import trial_file
from davinci_sim.study.runner import run_chunk


@pytest.fixture(scope="module")
def recorded(short_task, tmp_path_factory):
    folder = tmp_path_factory.mktemp("trials")
    specs = [
        TrialSpec(short_task, subject=s, condition=c, B=B, G_max=G, seed=5, timeout=t)
        for s, c, B, G, t in ((0, 0, 0.0, 0.0, 0.4), (1, 1, 40.0, 5.0, 0.25))
    ]
    rows = run_chunk(specs, "batch", record=str(folder))
    return folder, specs, rows


def test_recording_changes_no_row(recorded):
    _, specs, rows = recorded
    plain = run_batch(specs)
    for a, b in zip(rows, plain, strict=True):
        for key, value in a.items():
            if key == "wall_time":
                continue
            assert value == b[key] or (value != value and b[key] != b[key]), key


def test_each_trial_is_an_episode_file(recorded, tmp_path):
    folder, specs, rows = recorded
    files = sorted(folder.iterdir())
    assert [f.name for f in files] == sorted(trial_file(s) for s in specs)
    for spec, row in zip(specs, rows, strict=True):
        c = read_mcap(folder / trial_file(spec))
        assert c.complete and c.metadata["davinci_sim"]["kind"] == "episodes"
        assert json.loads(c.metadata["davinci_sim"]["trial"])["subject"] == spec.subject
        assert "task.yaml" in c.attachments
        steps = [m for _, m in c.topic("/episode/step")]
        # one step every 10 ticks of the trial (and its first observation), then the end
        assert len(steps) == pytest.approx(spec.timeout / 0.01 + 2, abs=2)
        assert steps[0]["action"] is None and steps[-1]["truncated"] != steps[-1]["terminated"]
        tips = np.array([s["observation"]["tip_pos"] for s in steps])
        assert np.all(np.isfinite(tips)) and np.ptp(tips, axis=0).max() > 1e-5  # it moved
        ((_, result),) = c.topic("/task/results")
        assert result["payload"]["samples"] == row["samples"]
        assert c.schemas["/PSM1/measured_cp"] == "foxglove.PoseInFrame"
        _, last = c.topic("/PSM1/measured_cp")[-1]
        p = last["pose"]["position"]
        assert [p["x"], p["y"], p["z"]] == steps[-2]["observation"]["tip_pos"]
    out = tmp_path / "trials.hdf5"
    summary = to_dataset(sorted(folder.iterdir()), out)
    assert summary.demos == 2
