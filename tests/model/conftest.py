"""Shared fixtures: models are built once per test session (building takes ~0.1 s)."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # offscreen rendering; must precede mujoco's import

import mujoco  # noqa: E402
import pytest  # noqa: E402

from davinci_sim.model import build_model  # noqa: E402


@pytest.fixture(scope="session")
def full_model() -> mujoco.MjModel:
    return build_model("full")
