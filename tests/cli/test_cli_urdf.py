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


def test_urdf_of_one_arm_and_a_bad_arm(capsys):
    assert main(["urdf", "--scene", "psm1", "--arm", "PSM1"]) == 0
    out = capsys.readouterr().out
    assert '<robot name="PSM1">' in out and 'joint name="wrist_yaw"' in out
    assert "SUJ_PSM1" not in out and "ECM_" not in out
    assert main(["urdf", "--scene", "psm1", "--arm", "PSM7"]) == 2
    err = capsys.readouterr().err
    assert "PSM7" in err and "SUJ/PSM1" in err
