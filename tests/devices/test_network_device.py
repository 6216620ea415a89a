"""Network devices: pushed input, validation, the 30 ms watchdog with a teleoperation."""

import math
import pickle

import numpy as np
import pytest

from davinci_sim.console import SIMULATED_SYSTEM, install_console
from davinci_sim.devices import DVRK_WATCHDOG, ButtonEvent, NetworkDevice
from davinci_sim.sim.simulation import Simulation


class Remote:
    """A remote master pushing a pose every tick (1 kHz) while ``on``; registered first."""

    name = "remote"

    def __init__(self, device, T0):
        self.device = device
        self.T = T0.copy()
        self.on = True

    def pre_step(self, t):
        if self.on:
            assert self.device.push(self.T, gripper=0.2)

    def snapshot(self):
        return {"on": self.on}


def remote_sim():
    sim = Simulation("psm1_ecm_mtmr", keyframe="surgical")
    device = NetworkDevice("MTMR/device", clock=lambda: sim.time)
    console = install_console(sim, devices={"MTMR": device}, teleop_config=SIMULATED_SYSTEM)
    remote = Remote(device, sim.arms["MTMR"].measured_cp().T)
    sim.add_component(remote, before=next(iter(sim.components)))
    return sim, console, device, remote


def test_watchdog_stops_following_zeroes_the_wrench_and_following_resumes():
    sim, console, device, remote = remote_sim()
    teleop = console.psm_teleops["MTMR_PSM1"]
    assert not teleop.align_mtm()  # a network device cannot be moved: no alignment
    console.emulate_operator_present([1])
    console.teleop_enable(True)
    assert sim.run_until(teleop.is_following, 2)
    psm = sim.arms["PSM1"]
    p0 = psm.setpoint_cp().position.copy()
    remote.T[:3, 3] += [0.0, 0.0, 0.02]
    sim.run_for(0.01)
    np.testing.assert_allclose(psm.setpoint_cp().position - p0, [0, 0, 0.004], atol=1e-5)
    assert device.servo_cf([1.0, 0, 0, 0, 0, 0])
    errors = []
    device.channels.subscribe(lambda ev, p: errors.append(p.text) if ev == "error" else None)
    remote.on = False  # the remote goes silent
    sim.run_for(DVRK_WATCHDOG)  # 30 ms: still fresh (dvrk.md 1.7)
    assert teleop.is_following() and not device.is_stale()
    sim.run_for(0.002)
    assert device.is_stale() and not teleop.is_following()
    assert teleop.current_state() == "SETTING_ARMS_STATE"
    np.testing.assert_array_equal(device.wrench(), np.zeros(6))
    assert not device.servo_cf([1.0, 0, 0, 0, 0, 0])
    assert any("watchdog" in e for e in errors)
    held_q = psm.setpoint_jp().copy()
    held = psm.setpoint_cp().position.copy()
    sim.run_for(0.2)
    np.testing.assert_array_equal(psm.setpoint_jp(), held_q)  # the PSM holds
    remote.T[:3, 3] += [0.01, 0.0, 0.0]  # the hand moved while the link was down
    remote.on = True
    assert sim.run_until(teleop.is_following, 1)
    sim.run_for(0.01)
    # Re-anchored: no jump of 0.2 x 1 cm (the setup joints still settle by a few µm).
    assert np.linalg.norm(psm.setpoint_cp().position - held) < 1e-4


def test_bad_pushes_are_refused_and_change_nothing():
    device = NetworkDevice("MTMR/device")
    T = np.eye(4)
    assert device.push(T, gripper=0.3, buttons={"clutch": [1]})
    device.pre_step(0.0)
    before = device.input()
    bad = np.eye(4)
    bad[0, 0] = 2.0
    for kwargs in (
        {"T_hrsv_tip": bad},
        {"T_hrsv_tip": np.full((4, 4), np.nan)},
        {"gripper": float("nan")},
        {"twist": [0.0] * 5},
        {"twist": [1e300, 0, 0, 0, 0, 0]},  # finite but absurd (issue 11, 4)
        {"twist": [0, 0, 0, 0, 0, 1e3]},
        {"gripper": 1e300},
        {"buttons": {"clutch": "maybe"}},
        {"buttons": [1]},
    ):
        result = device.push(**kwargs)
        assert not result and result.message
    device.pre_step(0.001)
    assert device.input() is before  # nothing new was taken
    assert device.pop_button_events() == [("clutch", ButtonEvent.PRESSED)]
    assert device.input().buttons == {"clutch": True}
    with pytest.raises(ValueError, match="watchdog"):
        NetworkDevice("x", watchdog=0.0)


def test_twist_is_estimated_from_successive_poses_and_snapshot_is_picklable():
    now = [0.0]
    device = NetworkDevice("MTMR/device", clock=lambda: now[0])
    T = np.eye(4)
    device.push(T)
    device.pre_step(0.0)
    now[0] = 0.01
    T2 = np.eye(4)
    T2[:3, 3] = [0.001, 0.0, -0.002]
    c, s = math.cos(0.01), math.sin(0.01)
    T2[:2, :2] = [[c, -s], [s, c]]
    device.push(T2)
    device.pre_step(0.01)
    np.testing.assert_allclose(device.input().twist_hrsv_tip, [0.1, 0, -0.2, 0, 0, 1.0], atol=1e-9)
    device.push(twist=[1, 2, 3, 4, 5, 6])
    device.pre_step(0.011)
    np.testing.assert_array_equal(device.input().twist_hrsv_tip, [1, 2, 3, 4, 5, 6])
    assert device.input().timestamp == 0.01  # only a pose refreshes the watchdog
    snap = pickle.loads(pickle.dumps(device.snapshot()))
    assert snap.kind == "network" and snap.ready and not snap.stale
    assert snap.input_age == pytest.approx(0.001)


def test_device_buttons_reach_the_console():
    sim, console, device, remote = remote_sim()
    clutch = []
    console.channels.subscribe(lambda ev, p: clutch.append(p) if ev == "clutch" else None)
    device.push(buttons={"clutch": True})
    sim.tick()
    assert console.is_pressed("clutch")
    device.push(buttons={"clutch": False})
    sim.tick()
    # A raw press of 1 ms is a quick tap too (the pedal-hardware rule).
    assert clutch == [[1], [0], [2]]
