"""PSM teleoperation with dVRK semantics: mapping in the camera frame, states, clutch, jaw."""

import math

import numpy as np
import pytest
from console_helpers import events_of, rotation_about, teleop_sim

from davinci_sim.console import SIMULATED_SYSTEM, TeleopPSMConfig
from davinci_sim.geometry import so3

#: Most tests skip the MTM's slow alignment motion (~2.5 s of simulation): without
#: ``align_MTM`` the alignment offset absorbs the orientation difference (dvrk.md 4.2).
NO_ALIGN = SIMULATED_SYSTEM.replace(align_mtm=False)


def parts(sim, console, teleop="MTMR_PSM1"):
    t = console.psm_teleops[teleop]
    return t, t.device, t.psm


def test_mtm_motion_in_hrsv_moves_the_tool_tip_by_the_scale_in_the_camera_frame():
    sim, console = teleop_sim(teleop_config=NO_ALIGN)
    teleop, device, psm = parts(sim, console)
    assert psm.measured_cp().reference_frame == "ECM"  # camera frame (dvrk.md 1.6)
    p_mtm0 = device.input().position.copy()
    p_set0 = psm.setpoint_cp().position.copy()
    p_meas0 = psm.measured_cp().position.copy()
    step = np.array([0.03, -0.02, 0.025])  # left, down, away from the operator
    device.move_hand(p_mtm0 + step)
    sim.run_for(0.8)
    d_mtm = device.input().position - p_mtm0
    assert np.linalg.norm(d_mtm - step) < 0.004  # the hand moved the handle there
    # dvrk.md 4.2: p_psm = p_psm0 + scale·(p_mtm − p_mtm0), HRSV axes = camera axes.
    np.testing.assert_allclose(psm.setpoint_cp().position - p_set0, 0.2 * d_mtm, atol=1e-5)
    np.testing.assert_allclose(psm.measured_cp().position - p_meas0, 0.2 * d_mtm, atol=3e-4)
    assert teleop.is_following() and teleop.scale() == 0.2


def test_a_task_sets_the_scale_without_a_jump():
    sim, console = teleop_sim(teleop_config=NO_ALIGN)
    teleop, device, psm = parts(sim, console)
    before = psm.setpoint_cp().position.copy()
    assert teleop.set_scale(0.6)  # the seed paper's path task
    sim.run_for(0.01)
    assert np.linalg.norm(psm.setpoint_cp().position - before) < 1e-5
    p_mtm0 = device.input().position.copy()
    p0 = psm.setpoint_cp().position.copy()
    device.move_hand(p_mtm0 + [0.0, 0.02, 0.0])
    sim.run_for(0.6)
    d_mtm = device.input().position - p_mtm0
    np.testing.assert_allclose(psm.setpoint_cp().position - p0, 0.6 * d_mtm, atol=1e-5)


def test_mtm_rotation_turns_the_tool_the_same_way_in_the_camera_frame():
    sim, console = teleop_sim(teleop_config=NO_ALIGN)
    teleop, device, psm = parts(sim, console)
    R_mtm0 = device.input().rotation.copy()
    R_psm0 = psm.setpoint_cp().rotation.copy()
    target = device.input().T_hrsv_tip.copy()
    target[:3, :3] = rotation_about([0.3, 1.0, 0.2], math.radians(20)) @ R_mtm0
    device.grasp(target)
    sim.run_for(1.0)
    R_mtm = device.input().rotation
    dR_mtm = R_mtm @ R_mtm0.T
    assert so3.rotation_angle(dR_mtm) > math.radians(12)  # the hand turned the handle
    # dvrk.md 4.2: R_psm = R_mtm · offset, so R_psm·R_psm0ᵀ = R_mtm·R_mtm0ᵀ (camera = HRSV).
    dR_psm = psm.setpoint_cp().rotation @ R_psm0.T
    assert so3.angle_between(dR_psm, dR_mtm) < 1e-6
    np.testing.assert_allclose(teleop.alignment_offset(), teleop.snapshot().alignment_offset)


def test_states_alignment_and_the_start_tolerance():
    sim, console = teleop_sim(start=False)  # align_MTM on (default)
    teleop, device, psm = parts(sim, console)
    states = events_of(teleop.channels, "current_state")
    console.emulate_operator_present([1])
    console.teleop_enable(True)
    assert teleop.desired_state() == "ENABLED"
    assert sim.run_until(teleop.is_following, 10)
    assert [s for _, s in states] == ["SETTING_ARMS_STATE", "ALIGNING_MTM", "ENABLED"]
    # dvrk.md 4.2: following starts once the MTM orientation is within 5° of the PSM's.
    assert so3.rotation_angle(teleop.alignment_offset()) <= math.radians(5.0) + 1e-9
    assert so3.angle_between(device.input().rotation, psm.setpoint_cp().rotation) < math.radians(5)
    console.emulate_clutch([1])
    sim.run_for(0.01)
    assert sim.arms["MTMR"].orientation_locked()  # clutch with align_MTM: orientation locked


def test_bad_commands_are_refused_and_change_nothing():
    sim, console = teleop_sim(teleop_config=NO_ALIGN)
    teleop, _, _ = parts(sim, console)
    errors = events_of(teleop.channels, "error")
    for call, arg in (
        (teleop.state_command, "fly"),
        (teleop.state_command, 3),
        (teleop.set_scale, 0.0),
        (teleop.set_scale, 1.5),
        (teleop.set_scale, "big"),
        (teleop.lock_rotation, "yes"),
        (teleop.lock_translation, None),
    ):
        result = call(arg)
        assert not result and result.message
    assert len(errors) == 7
    assert teleop.desired_state() == "ENABLED" and teleop.scale() == 0.2
    assert not teleop.rotation_locked() and not teleop.translation_locked()
    sim.run_for(0.01)
    assert teleop.is_following()
    with pytest.raises(ValueError, match="scale"):
        TeleopPSMConfig(scale=0.0)
    with pytest.raises(ValueError, match="gripper_max"):
        TeleopPSMConfig(gripper_zero=1.0, gripper_max=0.5)


def test_translation_lock_holds_the_position_and_rotation_lock_the_orientation():
    sim, console = teleop_sim(teleop_config=NO_ALIGN)
    teleop, device, psm = parts(sim, console)
    assert teleop.lock_translation(True)
    p0 = psm.setpoint_cp().position.copy()
    device.move_hand(device.input().position + [0.02, 0.02, 0.0])
    sim.run_for(0.5)
    np.testing.assert_allclose(psm.setpoint_cp().position, p0, atol=1e-6)
    assert teleop.lock_translation(False) and teleop.lock_rotation(True)
    assert sim.arms["MTMR"].orientation_locked()  # dvrk.md 4.2: the MTM holds it too
    R0 = psm.setpoint_cp().rotation.copy()
    p_mtm0 = device.input().position.copy()
    p1 = psm.setpoint_cp().position.copy()
    device.move_hand(p_mtm0 + [0.0, 0.0, 0.02])
    sim.run_for(0.5)
    assert so3.angle_between(psm.setpoint_cp().rotation, R0) < 1e-6
    d = device.input().position - p_mtm0
    np.testing.assert_allclose(psm.setpoint_cp().position - p1, 0.2 * d, atol=1e-5)
    # Unlocking the rotation re-aligns: DISABLED, then the start sequence again.
    states = events_of(teleop.channels, "current_state")
    assert teleop.lock_rotation(False)
    assert sim.run_until(teleop.is_following, 5)
    assert [s for _, s in states][0] == "DISABLED" and states[-1][1] == "ENABLED"
    assert not sim.arms["MTMR"].orientation_locked()


def test_clutch_holds_the_psm_and_reanchors_without_a_jump():
    sim, console = teleop_sim(teleop_config=NO_ALIGN)
    teleop, device, psm = parts(sim, console)
    p_psm = psm.setpoint_cp().position.copy()
    assert console.emulate_clutch([1])
    sim.run_for(0.01)
    assert not teleop.is_following() and teleop.current_state() == "ENABLED"
    # dvrk.md 4.2: the MTM orientation locks in clutch only with align_MTM or rotation lock.
    assert not sim.arms["MTMR"].orientation_locked()
    device.move_hand(device.input().position + [0.0, 0.04, 0.0])  # re-centre the hand
    sim.run_for(0.6)
    np.testing.assert_allclose(psm.setpoint_cp().position, p_psm, atol=1e-6)  # PSM held
    assert console.emulate_clutch([0])
    assert sim.run_until(teleop.is_following, 5)
    # Re-anchored: the tool did not jump by 0.2 x 4 cm.
    assert np.linalg.norm(psm.setpoint_cp().position - p_psm) < 1e-4
    p_mtm0 = device.input().position.copy()
    p0 = psm.setpoint_cp().position.copy()
    device.move_hand(p_mtm0 + [-0.02, 0.0, 0.0])
    sim.run_for(0.5)
    d = device.input().position - p_mtm0
    np.testing.assert_allclose(psm.setpoint_cp().position - p0, 0.2 * d, atol=1e-5)


def test_jaw_follows_the_gripper_with_the_dvrk_mapping_and_rates():
    sim, console = teleop_sim(teleop_config=NO_ALIGN)
    teleop, device, psm = parts(sim, console)
    jaw = lambda: float(psm.jaw.setpoint_js().position[0])  # noqa: E731
    # dvrk.md 4.2: jaw = 80°/60° · gripper with the large needle driver.
    assert device.squeeze(math.radians(30))
    sim.run_for(0.3)
    assert jaw() == pytest.approx(math.radians(40), abs=1e-3)
    # Rate limit: the jaw goal moves at most jaw_rate·dt per tick (in gripper units).
    s = psm.jaw.spec.qmax / math.radians(60)
    device.squeeze(math.radians(5))
    values = []
    for _ in range(60):
        sim.tick()
        values.append(jaw())
    steps = np.abs(np.diff(values))
    assert steps.max() <= 4 * math.pi * sim.dt * s + 1e-9
    assert steps.max() > 0.5 * 4 * math.pi * sim.dt * s  # it did move at the limit
    # After a clutch the jaw catches up at the slow rate (36°/s).
    sim.run_for(0.2)
    console.emulate_clutch([1])
    device.squeeze(math.radians(50))
    sim.run_for(0.3)
    assert jaw() == pytest.approx(math.radians(5) * s, abs=2e-3)  # no following in clutch
    console.emulate_clutch([0])
    assert sim.run_until(teleop.is_following, 5)
    values = []
    for _ in range(200):
        sim.tick()
        values.append(jaw())
    slope = (values[-1] - values[0]) / (199 * sim.dt)
    assert slope == pytest.approx(0.2 * math.pi * s, rel=0.02)


def test_operator_activity_is_needed_to_start_with_nonzero_thresholds():
    config = SIMULATED_SYSTEM.replace(
        align_mtm=False, start_gripper_threshold=math.radians(40), warning_interval=0.2
    )
    sim, console = teleop_sim(start=False, teleop_config=config)
    teleop, device, _ = parts(sim, console)
    warnings = events_of(teleop.channels, "warning")
    console.emulate_operator_present([1])
    console.teleop_enable(True)
    sim.run_for(0.5)
    assert teleop.current_state() == "ALIGNING_MTM" and not teleop.is_following()
    assert any("pinch/twist MTM gripper" in w.text for _, w in warnings)
    device.squeeze(math.radians(45))  # a pinch of 45° > 40°
    assert sim.run_until(teleop.is_following, 2)


def test_operator_absent_keeps_aligning_and_arm_failure_disables():
    sim, console = teleop_sim(start=False, teleop_config=NO_ALIGN)
    teleop, _, psm = parts(sim, console)
    console.teleop_enable(True)
    sim.run_for(0.2)
    assert teleop.desired_state() == "ALIGNING_MTM"  # dvrk.md 2.3: no operator, align only
    assert teleop.current_state() == "ALIGNING_MTM" and not teleop.is_following()
    console.emulate_operator_present([1])
    assert sim.run_until(teleop.is_following, 2)
    errors = events_of(teleop.channels, "error")
    assert psm.state_command("disable")
    sim.run_for(0.01)
    assert teleop.current_state() == "DISABLED" and teleop.desired_state() == "DISABLED"
    assert "PSM1 is not ready anymore" in errors[0][1].text


def test_unreachable_goals_do_not_flood_the_psm_error_channel():
    sim, console = teleop_sim(teleop_config=NO_ALIGN)
    _, _, psm = parts(sim, console)
    errors = events_of(psm.channels, "error")
    far = psm.setpoint_cp().T.copy()
    # At the RCM: no IK solution (a goal past a joint limit would be clipped, as on the dVRK)
    far[:3, 3] = psm.base_frame()[0][:3, 3]
    for _ in range(500):  # 0.5 s of refused streaming commands
        assert not psm.servo_cp(far)
        sim.tick()
    assert len(errors) == 1
    sim.run_for(0.6)
    assert not psm.servo_cp(far)
    assert len(errors) == 2 and "499 more refusals" in errors[1][1].text
