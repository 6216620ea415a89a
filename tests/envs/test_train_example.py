"""The learning example runs: a few hundred PPO steps on the vector Reach environment (the
full run that learns is not part of the tests: see examples/train_reach.py)."""

from __future__ import annotations

import importlib.util
import json
import pathlib

import pytest

pytest.importorskip(
    "stable_baselines3",
    reason="the learning example needs the 'learn' extra: pip install -e '.[learn]'",
)

EXAMPLE = pathlib.Path(__file__).resolve().parents[2] / "examples" / "train_reach.py"


def test_a_few_hundred_training_steps_run_and_write_the_curve(tmp_path):
    spec = importlib.util.spec_from_file_location("train_reach", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    result = module.main(["--timesteps", "256", "--envs", "4", "--eval-every", "128",
                          "--eval-episodes", "3", "--out", str(tmp_path)])  # fmt: skip
    assert result["timesteps"] >= 256
    saved = json.loads((tmp_path / "curve.json").read_text())
    assert [c["timesteps"] for c in saved["curve"]][0] == 0  # the untrained policy first
    assert len(saved["curve"]) >= 3
    assert all(0.0 <= c["success_rate"] <= 1.0 for c in saved["curve"])
    assert (tmp_path / "curve.png").stat().st_size > 1000
    assert (tmp_path / "ppo_reach.zip").exists()
