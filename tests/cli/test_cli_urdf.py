"""``davinci-sim urdf``: the robot description of a scene, to stdout or a file."""

import yourdfpy

from davinci_sim.cli import main


def test_urdf_to_stdout_and_file(tmp_path, capsys):
    assert main(["urdf", "--scene", "psm1"]) == 0
    out = capsys.readouterr().out
    assert out.startswith('<?xml version="1.0"?>') and "PSM1_wrist_yaw" in out
    assert "MTML" not in out  # the scene's arms only
    path = tmp_path / "psm1.urdf"
    assert main(["urdf", "--scene", "psm1", "-o", str(path)]) == 0
    assert path.read_text() == out
    robot = yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=False)
    assert {"PSM1_yaw", "SUJ_PSM1_J0", "ECM_roll"} <= set(robot.actuated_joint_names)
