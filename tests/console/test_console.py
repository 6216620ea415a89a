"""The console: pedal events with the Joy convention, selection, quick tap, camera pedal."""

import numpy as np
import pytest
from console_helpers import events_of

from davinci_sim.console import install_console
from davinci_sim.sim.simulation import Simulation


@pytest.fixture(scope="module")
def full():
    """The full system with a console (console logic only: few ticks per test)."""
    sim = Simulation("full", keyframe="surgical")
    console = install_console(sim)
    return sim, console


def fresh():
    sim = Simulation("full", keyframe="surgical")
    return sim, install_console(sim)


def test_components_are_registered_in_haptic_loop_order(full):
    sim, _ = full
    assert list(sim.components) == [
        "MTML/device",
        "MTMR/device",
        "console",
        "MTMR_PSM1",
        "MTML_PSM2",
        "MTML_PSM3",
        "MTML_MTMR_ECM",
        "haptics",
    ]
    with pytest.raises(ValueError, match="already registered"):
        install_console(sim)


def test_initial_selection_first_declared_wins(full):
    _, console = full
    # dvrk.md 2.3: MTMR_PSM1 and MTML_PSM2 selected; MTML_PSM3 shares MTML with MTML_PSM2.
    assert console.selected_teleops() == ("MTMR_PSM1", "MTML_PSM2")
    assert console.snapshot().unselected == ("MTML_PSM3",)


def test_quick_tap_on_clutch_swaps_mtml_between_psm2_and_psm3():
    sim, console = fresh()
    selected = events_of(console.channels, "teleop_selected", "teleop_unselected", "clutch")
    assert console.emulate_clutch([2])  # Joy [2]: quick tap (dvrk.md 2.3)
    assert console.selected_teleops() == ("MTMR_PSM1", "MTML_PSM3")
    assert ("clutch", [2]) in selected
    assert ("teleop_unselected", "MTML_PSM2") in selected
    assert ("teleop_selected", "MTML_PSM3") in selected
    # Emulated events are taken as they are: a quick [1] [0] is not a tap …
    console.emulate_clutch([1])
    console.emulate_clutch([0])
    assert console.selected_teleops() == ("MTMR_PSM1", "MTML_PSM3")
    # … but a raw pedal press shorter than tap_duration is, as the pedal hardware does …
    console.press("clutch")
    sim.run_for(0.1)
    console.release("clutch")
    assert console.selected_teleops() == ("MTMR_PSM1", "MTML_PSM2")
    # … and a longer one (a repositioning clutch) is not.
    console.press("clutch")
    sim.run_for(0.5)
    console.release("clutch")
    assert console.selected_teleops() == ("MTMR_PSM1", "MTML_PSM2")
    joy = [p for ev, p in selected if ev == "clutch"]
    assert joy == [[2], [1], [0], [1], [0], [2], [1], [0]]


def test_clutch_goes_to_every_teleoperation():
    sim, console = fresh()
    console.emulate_clutch(True)
    assert all(t.is_clutched() for t in console.teleops().values())
    assert console.is_pressed("clutch") and console.snapshot().buttons["clutch"]
    console.emulate_clutch("released")
    assert not any(t.is_clutched() for t in console.teleops().values())


def test_select_unselect_and_bad_names():
    sim, console = fresh()
    assert console.select_teleop("MTML_PSM3")
    assert console.selected_teleops() == ("MTMR_PSM1", "MTML_PSM3")
    assert console.unselect_teleop("MTMR_PSM1")
    assert console.selected_teleops() == ("MTML_PSM3",)
    errors = events_of(console.channels, "error")
    result = console.select_teleop("MTMX_PSM9")
    assert not result and "MTML_PSM2" in result.message  # lists the known ones
    assert not console.unselect_teleop(42)
    assert console.selected_teleops() == ("MTML_PSM3",) and len(errors) == 2


def test_teleop_enable_operator_presence_and_camera_pedal_set_the_teleop_states():
    sim, console = fresh()
    t1, t2, t3 = (console.psm_teleops[n] for n in ("MTMR_PSM1", "MTML_PSM2", "MTML_PSM3"))
    ecm = console.ecm_teleop
    assert console.teleop_enable(True)
    # dvrk.md 2.3: no operator: the selected PSM teleoperations only align.
    assert (t1.desired_state(), t2.desired_state(), t3.desired_state()) == (
        "ALIGNING_MTM",
        "ALIGNING_MTM",
        "DISABLED",
    )
    console.emulate_operator_present([1])
    assert (t1.desired_state(), t2.desired_state()) == ("ENABLED", "ENABLED")
    assert ecm.desired_state() == "DISABLED"
    console.emulate_camera([1])  # camera pedal: the ECM teleoperation, the PSMs hold
    assert (t1.desired_state(), t2.desired_state(), ecm.desired_state()) == (
        "DISABLED",
        "DISABLED",
        "ENABLED",
    )
    console.emulate_camera([0])
    assert (t1.desired_state(), ecm.desired_state()) == ("ENABLED", "DISABLED")
    assert console.teleop_enable(False)
    assert all(t.desired_state() == "DISABLED" for t in console.teleops().values())
    assert not console.teleop_enable("yes")


def test_scale_for_all_teleoperations_and_refusals():
    sim, console = fresh()
    scales = events_of(console.channels, "scale")
    assert console.set_scale(0.5)
    assert all(t.scale() == 0.5 for t in console.teleops().values())
    assert scales == [("scale", 0.5)] and console.snapshot().scale == 0.5
    for bad in (0, -1, 2.0, "x", float("nan"), 1e300, 10**400):
        assert not console.set_scale(bad)
    assert all(t.scale() == 0.5 for t in console.teleops().values())
    # The ECM teleoperation's scale has the same bounds (it took 1e300, issue 11, 4).
    ecm = console.ecm_teleop
    assert ecm.set_scale(0.2) and ecm.scale() == 0.2
    for bad in (0, -1, 1.5, 1e300, float("inf"), "x"):
        result = ecm.set_scale(bad)
        assert not result and "]0, 1]" in result.message
    assert ecm.scale() == 0.2


def test_event_forms_and_unknown_buttons():
    sim, console = fresh()
    coag = events_of(console.channels, "coag")
    for form in ([1], {"buttons": [0]}, "clicked", True):
        assert console.emulate_coag(form)
    assert [p for _, p in coag] == [[1], [0], [2], [1]]
    for bad in ([3], [], "pushed", {"axes": []}, None):
        assert not console.emulate_coag(bad)
    assert not console.button("turbo", [1])
    assert console.button("head", [1]) and console.operator_present()  # 2.2 alias


def test_install_options_and_scripted_hands():
    from davinci_sim.console.setup import add_scripted_hands
    from davinci_sim.devices import NetworkDevice

    sim = Simulation("psm1", keyframe="surgical")
    with pytest.raises(ValueError, match="nothing to teleoperate"):
        install_console(sim)
    with pytest.raises(ValueError, match="unknown MTMs"):
        install_console(sim, devices={"MTMX": NetworkDevice("x")})
    sim = Simulation("psm1_ecm_mtmr", keyframe="surgical")
    console = install_console(sim, operator_present=True, teleop_enabled=True)
    add_scripted_hands(sim, console)
    assert list(sim.components)[0] == "MTMR/device/script"
    teleop = sim.components["MTMR_PSM1"]
    assert sim.run_until(teleop.is_following, 10)
    p0 = sim.arms["PSM1"].setpoint_cp().position.copy()
    sim.run_for(0.5)  # a quarter of the 0.5 Hz circle of 2 cm: the tool moved ~0.2 x 2.8 cm
    assert 0.002 < np.linalg.norm(sim.arms["PSM1"].setpoint_cp().position - p0) < 0.01
    assert sim.components["MTMR/device/script"].snapshot()["started"]
