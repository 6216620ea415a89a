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
