"""The haptic loop: force fields get the tick's state and their clamped sum reaches the MTM."""

import numpy as np
import pytest
from console_helpers import teleop_sim

from davinci_sim.console import SIMULATED_SYSTEM
from davinci_sim.devices.safety import WrenchLimits
from davinci_sim.haptics import ContactFeedback, HapticState

NO_ALIGN = SIMULATED_SYSTEM.replace(align_mtm=False)


def test_a_field_sees_the_tick_state_and_its_wrench_reaches_the_mtm_clamped():
    sim, console = teleop_sim(teleop_config=NO_ALIGN, limits=WrenchLimits(max_force=2.0))
    haptics, device, psm = console.haptics, sim.components["MTMR/device"], sim.arms["PSM1"]
    seen = []

    def viscous(state: HapticState):
        seen.append(state)
        return -40.0 * state.v_camera_tip  # N·s/m on the tool velocity (camera axes)

    assert haptics.add_field(viscous, mtm="MTMR") == "viscous"
    device.move_hand(device.input().position + [0.0, 0.03, 0.0])
    sim.run_for(0.05)
    state = seen[-1]
    assert (state.mtm, state.psm) == ("MTMR", "PSM1") and state.time == pytest.approx(sim.time)
    np.testing.assert_allclose(state.T_camera_tip, psm.measured_cp().T)
    np.testing.assert_allclose(state.T_world_camera, sim.T_cart_camera())
    np.testing.assert_allclose(state.T_hrsv_mtm, device.input().T_hrsv_tip)
    assert state.jaw == pytest.approx(psm.jaw.measured_jp())
    assert not state.T_camera_tip.flags.writeable
    requested = haptics.snapshot().requested["MTMR"]
    assert requested[1] < -1.0  # the tool moves +y: the field pushes back along -y
    w = device.wrench()
    assert np.linalg.norm(w[:3]) <= 2.0 + 1e-9  # clamped by the device's limits
    np.testing.assert_allclose(
        w[:3] / np.linalg.norm(w[:3]), requested[:3] / np.linalg.norm(requested[:3])
    )
    np.testing.assert_allclose(sim.arms["MTMR"].wrench_setpoint()[1], w)
    # No following (clutch): fields are not called and the wrench is zero.
    n = len(seen)
    console.emulate_clutch([1])
    sim.run_for(0.05)
    assert len(seen) == n and not device.wrench().any()


def test_faulty_fields_are_skipped_and_reported_once_per_second():
    sim, console = teleop_sim(teleop_config=NO_ALIGN)
    haptics, device = console.haptics, sim.components["MTMR/device"]
    errors = []
    haptics.channels.subscribe(lambda ev, p: errors.append(p.text) if ev == "error" else None)

    def broken(state):
        raise RuntimeError("boom")

    haptics.add_field(broken)
    haptics.add_field(lambda state: [np.nan, 0.0, 0.0], name="nan")
    haptics.add_field(lambda state: [0.0, 0.0, 0.3], name="push")
    sim.run_for(0.5)
    np.testing.assert_allclose(device.wrench(), [0, 0, 0.3, 0, 0, 0])
    assert len(errors) == 2 and "boom" in errors[0] and "finite" in errors[1]
    sim.run_for(0.6)
    assert len(errors) == 4
    assert haptics.remove_field("broken") and haptics.remove_field("nan")
    assert not haptics.remove_field("nan")
    assert haptics.field_names() == ["push"]
    with pytest.raises(TypeError, match="callable"):
        haptics.add_field(42)
    with pytest.raises(ValueError, match="unknown MTM"):
        haptics.add_field(lambda s: [0, 0, 0], mtm="MTML")
    with pytest.raises(ValueError, match="already registered"):
        haptics.add_field(lambda s: [0, 0, 0], name="push")


def test_contact_feedback_pushes_the_hand_back_when_the_tool_presses_on_tissue():
    sim, console = teleop_sim(teleop_config=NO_ALIGN.replace(scale=1.0), contact_feedback=True)
    device = sim.components["MTMR/device"]
    p0 = device.input().position.copy()
    for dz in np.arange(0.0, 0.121, 0.005):  # the tool goes 12 cm deeper: on the phantom
        device.move_hand(p0 + [0.0, 0.0, dz])
        sim.run_for(0.1)
    assert console.psm_teleops["MTMR_PSM1"].is_following()
    f_camera = sim.T_cart_camera()[:3, :3].T @ sim.contact_force("PSM1")
    assert f_camera[2] < -2.0  # the tissue pushes the tool back towards the camera
    w = device.wrench()
    assert w[2] < -1.0  # and the hand is pushed back towards the operator (HRSV -z)
    assert np.dot(w[:3], f_camera) > 0


def test_contact_feedback_filters_and_scales():
    field = ContactFeedback(gain=0.5, cutoff_hz=30.0, dt=0.001)
    state = HapticState.from_values(T_camera_tip=np.eye(4), contact_force_camera=[0.0, 0.0, -4.0])
    first = field(state)
    assert first[2] == pytest.approx(0.5 * -4.0 * field.alpha)  # starts from zero
    for _ in range(200):
        out = field(state)
    assert out[2] == pytest.approx(-2.0, rel=1e-3)
    with pytest.raises(ValueError):
        ContactFeedback(gain=-1.0)
