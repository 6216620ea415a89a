"""The robot-inaccuracy option: a PSM whose links stand at its joints plus constant errors
while it reads and servoes them by its nominal kinematics (the AccelNet challenge's model)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from davinci_sim import cli
from davinci_sim.kinematics import fk
from davinci_sim.model.config import (
    MAX_JOINT_ERRORS,
    SceneConfig,
    parse_joint_errors,
    random_joint_errors,
)
from davinci_sim.sim.simulation import Simulation

ERRORS = (0.044, -0.008, 0.004)  # rad, rad, m (the challenge's condition B, in metres)


def _homed(errors) -> Simulation:
    scene = SceneConfig(arms=("PSM1", "ECM"), include_console=False, joint_errors=errors)
    sim = Simulation(scene, keyframe="surgical")
    psm = sim.arms["PSM1"]
    psm.state_command("enable")
    psm.state_command("home")
    assert sim.run_until(lambda: psm.is_homed() and not psm.is_busy(), 30.0)
    sim.run_for(0.3)
    return sim


def _tip_in_camera(sim: Simulation) -> np.ndarray:
    """Where the instrument's tip is (its MuJoCo site), camera frame, m."""
    site = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_SITE, "PSM1/tip")
    T_camera_cart = np.linalg.inv(sim.T_cart_camera())
    return T_camera_cart[:3, :3] @ sim.data.site_xpos[site] + T_camera_cart[:3, 3]


@pytest.mark.parametrize("errors", [{}, {"PSM1": ERRORS}])
def test_the_tip_stands_at_the_joints_plus_the_errors_while_the_arm_reports_its_joints(errors):
    """With errors e the tool's tip is where the nominal kinematics put the joints q + e,
    computed here from the DH chain (an independent reference), while ``measured_cp``
    reports FK(q); the arm servoes its setpoint as without errors (no fault). Without
    errors the tip is what ``measured_cp`` reports."""
    sim = _homed(errors)
    try:
        psm = sim.arms["PSM1"]
        q = psm.measured_jp()
        e = np.zeros(psm.dof)
        e[:3] = errors.get("PSM1", (0.0, 0.0, 0.0))
        T_camera_base = psm.measured_cp().T @ np.linalg.inv(fk.forward_kinematics(psm.chain, q))
        p_true = (T_camera_base @ fk.forward_kinematics(psm.chain, q + e))[:3, 3]
        np.testing.assert_allclose(_tip_in_camera(sim), p_true, atol=1e-9)
        offset = np.linalg.norm(_tip_in_camera(sim) - psm.measured_cp().T[:3, 3])
        assert offset > 0.005 if errors else offset < 1e-9  # m
        np.testing.assert_allclose(psm.setpoint_jp(), q, atol=1e-6)
        assert psm.operating_state().state == "ENABLED"
    finally:
        sim.close()


def test_scene_configs_check_and_normalise_the_errors():
    a = SceneConfig(arms=("PSM1", "PSM2", "ECM"), include_console=False,
                    joint_errors={"PSM2": (0, 0, 0.001), "PSM1": ERRORS})  # fmt: skip
    b = SceneConfig(arms=("PSM1", "PSM2", "ECM"), include_console=False,
                    joint_errors=[("PSM1", list(ERRORS)), ("PSM2", (0.0, 0.0, 0.001))])  # fmt: skip
    assert a == b and hash(a) == hash(b) and a.errors_of("PSM1") == ERRORS
    none = SceneConfig(arms=("PSM1", "ECM"), include_console=False)
    zero = SceneConfig(arms=("PSM1", "ECM"), include_console=False,
                       joint_errors={"PSM1": (0.0, 0.0, 0.0)})  # fmt: skip
    assert zero == none and none.errors_of("PSM1") == (0.0, 0.0, 0.0)
    for bad in ({"PSM2": ERRORS}, {"ECM": ERRORS}, {"PSM1": (0.1, 0.2)},
                {"PSM1": (np.nan, 0.0, 0.0)}, {"PSM1": "abc"}):  # fmt: skip
        with pytest.raises(ValueError, match="joint_errors"):
            SceneConfig(arms=("PSM1", "ECM"), include_console=False, joint_errors=bad)


def test_errors_are_parsed_and_drawn_within_the_challenges_range():
    assert parse_joint_errors(["PSM1=0.044,-0.008,0.004"]) == {"PSM1": ERRORS}
    for bad in (["PSM1=1,2"], ["ECM=0,0,0"], ["PSM1=a,b,c"], ["PSM1=0,0,0", "PSM1=0,0,0"]):
        with pytest.raises(ValueError, match="PSMn=YAW,PITCH,INSERTION"):
            parse_joint_errors(bad)
    drawn = random_joint_errors(("PSM1", "PSM2", "ECM"), seed=4)
    assert set(drawn) == {"PSM1", "PSM2"} and drawn == random_joint_errors(("PSM1", "PSM2"), 4)
    assert drawn != random_joint_errors(("PSM1", "PSM2"), 5)
    for errors in drawn.values():
        assert np.all(np.abs(errors) <= MAX_JOINT_ERRORS) and np.any(np.abs(errors) > 0)


def test_serve_takes_the_errors_and_refuses_bad_ones(monkeypatch, capsys):
    from davinci_sim.bridge import app

    seen = {}
    monkeypatch.setattr(app, "serve", lambda options, **kwargs: seen.update(o=options) or {})
    monkeypatch.setattr(cli, "_taken_port_problem", lambda args, web: None)
    argv = ["serve", "--no-web", "--duration", "0", "--scene", "psm1"]
    assert cli.main([*argv, "--joint-errors", "PSM1=0.044,-0.008,0.004"]) == 0
    assert seen["o"].scene.errors_of("PSM1") == ERRORS
    assert cli.main([*argv, "--random-joint-errors", "3"]) == 0
    assert seen["o"].scene.joint_errors == tuple(random_joint_errors(("PSM1",), 3).items())
    seen.clear()
    assert cli.main([*argv, "--joint-errors", "PSM2=0,0,0.001"]) == 2
    assert "PSM2" in capsys.readouterr().err and not seen
    assert cli.main([*argv, "--joint-errors", "PSM1=0,0,0.001", "--random-joint-errors", "1"]) == 2
    assert "give one of them" in capsys.readouterr().err and not seen
