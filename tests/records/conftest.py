"""Shared setup of the trainee records' tests."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # offscreen rendering; must precede mujoco's import
