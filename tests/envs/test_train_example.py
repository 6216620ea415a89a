"""The learning example runs: a few hundred PPO steps on the vector Reach environment (the
full run that learns is not part of the tests: see examples/train_reach.py).

It runs in its own process: torch loads triton, whose bundled LLVM crashes a process where
Mesa's llvmpipe (MuJoCo's EGL rendering, which other tests of the suite start) is loaded.
"""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys

import pytest

import davinci_sim

pytest.importorskip(
    "stable_baselines3",
    reason="the learning example needs the 'learn' extra: pip install -e '.[learn]'",
)

EXAMPLE = pathlib.Path(__file__).resolve().parents[2] / "examples" / "train_reach.py"


def test_a_few_hundred_training_steps_run_and_write_the_curve(tmp_path):
    src = str(pathlib.Path(davinci_sim.__file__).resolve().parents[1])  # (this package's)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}
    args = ["--timesteps", "256", "--envs", "4", "--eval-every", "128", "--eval-episodes", "3",
            "--out", str(tmp_path)]  # fmt: skip
    done = subprocess.run([sys.executable, str(EXAMPLE), *args], env=env, capture_output=True,
                          text=True)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    saved = json.loads((tmp_path / "curve.json").read_text())
    assert saved["timesteps"] >= 256
    assert [c["timesteps"] for c in saved["curve"]][0] == 0  # the untrained policy first
    assert len(saved["curve"]) >= 3
    assert all(0.0 <= c["success_rate"] <= 1.0 for c in saved["curve"])
    assert (tmp_path / "curve.png").stat().st_size > 1000
    assert (tmp_path / "ppo_reach.zip").exists()
