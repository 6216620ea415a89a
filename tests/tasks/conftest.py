"""Shared setup of the task tests."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # offscreen rendering; must precede mujoco's import
