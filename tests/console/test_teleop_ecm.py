"""Camera control: with the camera pedal both MTMs move the ECM and the PSMs hold; the PSM
teleoperation then maps MTM motion in the new camera frame."""

import math

import numpy as np
from console_helpers import TWO_MTM_SCENE, teleop_sim

from davinci_sim.console import SIMULATED_SYSTEM


def test_camera_pedal_moves_the_camera_with_both_hands_and_the_psm_holds():
    sim, console = teleop_sim(
        TWO_MTM_SCENE, start=False, teleop_config=SIMULATED_SYSTEM.replace(align_mtm=False)
    )
    console.emulate_operator_present([1])
    console.teleop_enable(True)
    psm_teleop = console.psm_teleops["MTMR_PSM1"]
    ecm_teleop = console.ecm_teleop
    assert ecm_teleop.name == "MTML_MTMR_ECM"
    assert sim.run_until(psm_teleop.is_following, 5)
    left, right = sim.components["MTML/device"], sim.components["MTMR/device"]
    ecm, psm = sim.arms["ECM"], sim.arms["PSM1"]

    assert console.emulate_camera([1])
    assert sim.run_until(ecm_teleop.is_following, 2)
    assert psm_teleop.current_state() == "DISABLED"  # the PSM holds
    assert sim.arms["MTML"].orientation_locked() and sim.arms["MTMR"].orientation_locked()
    left.grasp(hold_orientation=False)
    right.grasp(hold_orientation=False)
    q_psm = psm.setpoint_jp().copy()
    q0 = ecm.setpoint_jp().copy()
    T_cart_camera0 = sim.T_cart_camera().copy()
    pl0, pr0 = left.input().position.copy(), right.input().position.copy()
    c0 = 0.5 * (pl0 + pr0)

    # Both hands 5 cm to the operator's right (-x in HRSV): the camera turns so that the
    # image follows the hands (it looks towards the image's left, +x of the camera).
    d = np.array([-0.05, 0.0, 0.0])
    left.move_hand(pl0 + d)
    right.move_hand(pr0 + d)
    sim.run_for(1.0)
    c = 0.5 * (left.input().position + right.input().position)
    turn = math.atan2(-c[0], c[2]) - math.atan2(-c0[0], c0[2])  # about HRSV y, seen from the eyes
    view = T_cart_camera0[:3, :3].T @ sim.T_cart_camera()[:3, 2]  # new view axis, old camera
    assert view[0] > 0.05 and abs(view[1]) < 1e-3
    assert abs(math.atan2(view[0], view[2]) - abs(turn)) < 0.01
    # Hands back and 5 cm towards the eyes: the endoscope goes in by scale x 5 cm.
    d = np.array([0.0, 0.0, -0.05])
    left.move_hand(pl0 + d)
    right.move_hand(pr0 + d)
    sim.run_for(1.0)
    c = 0.5 * (left.input().position + right.input().position)
    expected = 0.2 * (np.linalg.norm(c0) - np.linalg.norm(c))
    assert abs((ecm.setpoint_jp()[2] - q0[2]) - expected) < 2e-4 and expected > 0.009
    np.testing.assert_array_equal(psm.setpoint_jp(), q_psm)  # the PSM did not move

    # Camera released: back to the PSM, re-anchored, mapping in the *new* camera frame.
    assert console.emulate_camera([0])
    assert sim.run_until(psm_teleop.is_following, 5)
    assert ecm_teleop.current_state() == "DISABLED"
    right.grasp()
    p_mtm0 = right.input().position.copy()
    p_psm0 = psm.measured_cp().position.copy()
    right.move_hand(p_mtm0 + [0.02, 0.02, 0.0])
    sim.run_for(0.8)
    d_mtm = right.input().position - p_mtm0
    np.testing.assert_allclose(psm.measured_cp().position - p_psm0, 0.2 * d_mtm, atol=3e-4)


def test_clutch_in_camera_mode_holds_the_camera():
    sim, console = teleop_sim(TWO_MTM_SCENE, start=False)
    console.emulate_operator_present([1])
    console.teleop_enable(True)
    console.emulate_camera([1])
    ecm_teleop = console.ecm_teleop
    assert sim.run_until(ecm_teleop.is_following, 5)
    left, right = sim.components["MTML/device"], sim.components["MTMR/device"]
    console.emulate_clutch([1])
    q = sim.arms["ECM"].setpoint_jp().copy()
    left.grasp(left.input().position + [0.0, 0.04, 0.0], hold_orientation=False)
    right.grasp(right.input().position + [0.0, 0.04, 0.0], hold_orientation=False)
    sim.run_for(0.5)
    assert not ecm_teleop.is_following()
    np.testing.assert_allclose(sim.arms["ECM"].setpoint_jp(), q, atol=1e-9)
    console.emulate_clutch([0])
    assert sim.run_until(ecm_teleop.is_following, 2)
    sim.run_for(0.2)  # re-anchored: no jump of the camera
    np.testing.assert_allclose(sim.arms["ECM"].setpoint_jp(), q, atol=2e-3)
