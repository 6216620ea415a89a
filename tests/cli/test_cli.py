"""The davinci-sim command line."""

import numpy as np
from PIL import Image

from davinci_sim.cli import main


def test_info_lists_arms_joints_and_scenes(capsys):
    assert main(["info"]) == 0
    out = capsys.readouterr().out
    for word in ("PSM1", "ECM", "MTMR", "insertion", "wrist_roll", "SUJ/PSM3", "full", "psm1"):
        assert word in out


def test_snapshot_writes_three_images(tmp_path):
    assert main(["snapshot", "--scene", "psm1", "-o", str(tmp_path)]) == 0
    for name in ("endoscope_left", "endoscope_right", "overview"):
        img = np.asarray(Image.open(tmp_path / f"{name}.png"))
        assert img.ndim == 3 and img.std() > 5


def test_demo_runs_and_reports(capsys):
    assert main(["demo", "--scene", "psm1"]) == 0
    out = capsys.readouterr().out
    assert "servo_cp circle" in out and "bad command refused" in out and "homed=True" in out


def test_snapshot_draws_a_task_in_the_endoscope_view(tmp_path, capsys):
    plain, drawn = tmp_path / "plain", tmp_path / "task"
    assert main(["snapshot", "--scene", "psm1", "--no-home", "-o", str(plain)]) == 0
    assert main(["snapshot", "--scene", "psm1", "--no-home", "--task", "seed_path",
                 "-o", str(drawn)]) == 0  # fmt: skip
    a = np.asarray(Image.open(plain / "endoscope_left.png")).astype(int)
    b = np.asarray(Image.open(drawn / "endoscope_left.png")).astype(int)
    changed = np.any(a != b, axis=2)
    assert 100 < changed.sum() < 0.2 * changed.size  # the thin path and its markers
    magenta = (b[..., 0] > 200) & (b[..., 1] < 120) & (b[..., 2] > 180)
    assert magenta[changed].sum() > 20  # the path is drawn in the task's colour
    assert main(["snapshot", "--task", "no_such_task", "-o", str(tmp_path)]) == 2
    assert "no_such_task" in capsys.readouterr().err
