"""The UDP device in the socket-streamer JSON format (dvrk.md 5), over loopback."""

import json
import socket

import numpy as np
import pytest

from davinci_sim.console import SIMULATED_SYSTEM, install_console
from davinci_sim.devices import ButtonEvent, UDPJSONDevice
from davinci_sim.devices import streamer as ss
from davinci_sim.sim.simulation import Simulation


@pytest.fixture
def client():
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(2.0)
    yield sock
    sock.close()


@pytest.fixture
def device():
    dev = UDPJSONDevice("MTMR/device", port=0)
    yield dev
    dev.close()


def pose(p):
    T = np.eye(4)
    T[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = p
    return T


def drain(device, t, tries=200):
    """Tick the device until it took a datagram (loopback delivery is not instantaneous)."""
    for i in range(tries):
        before = device.datagrams_received
        device.pre_step(t + i * 1e-6)
        if device.datagrams_received > before:
            return
    raise AssertionError("no datagram arrived")


def test_streamer_datagrams_become_the_device_input_and_wrenches_go_back(device, client):
    T = pose([0.1, -0.02, 0.35])
    message = ss.datagram(
        measured_cp=ss.encode_pose(T, "HRSV", "MTMR", 1.5),
        measured_cv=ss.encode_twist([0.1, 0, 0, 0, 0, 0.5]),
        **{"gripper/measured_js": ss.encode_joint_state(["gripper"], [0.4])},
    )
    client.sendto(message, device.address)
    drain(device, 0.0)
    inp = device.input()
    np.testing.assert_allclose(inp.T_hrsv_tip, T)
    np.testing.assert_allclose(inp.twist_hrsv_tip, [0.1, 0, 0, 0, 0, 0.5])
    assert inp.gripper == pytest.approx(0.4) and device.is_ready()
    # The wrench goes back to the sender as a streamer write command (HRSV axes).
    assert device.servo_cf([0.5, 0.0, -0.5, 0.0, 0.0, 0.0])
    device.pre_step(0.001)
    data, _ = client.recvfrom(65535)
    while True:  # the latest datagram
        client.settimeout(0.05)
        try:
            data, _ = client.recvfrom(65535)
        except TimeoutError:
            break
    obj = json.loads(data)
    assert list(obj) == ["spatial/servo_cf"]
    np.testing.assert_allclose(obj["spatial/servo_cf"]["Force"], [0.5, 0, -0.5, 0, 0, 0])
    assert obj["spatial/servo_cf"]["Mask"] == [True] * 6


def test_one_datagram_per_command_and_older_velocity_fields(device, client):
    # The streamer sends one datagram per read command (dvrk.md 5).
    client.sendto(ss.datagram(measured_cp=ss.encode_pose(pose([0, 0, 0.3]))), device.address)
    drain(device, 0.0)
    twist = {"VelocityLinear": [0, 0.2, 0], "VelocityAngular": [0, 0, 0]}
    client.sendto(ss.datagram(measured_cv=twist), device.address)
    drain(device, 0.001)
    client.sendto(ss.datagram(**{"gripper/measured_js": {"Position": [0.7]}}), device.address)
    drain(device, 0.002)
    inp = device.input()
    assert inp.gripper == pytest.approx(0.7)
    np.testing.assert_allclose(inp.twist_hrsv_tip, [0, 0.2, 0, 0, 0, 0])
    assert inp.timestamp == 0.0  # the watchdog counts from the last pose


def test_bad_datagrams_are_reported_and_change_nothing(device, client):
    client.sendto(ss.datagram(measured_cp=ss.encode_pose(pose([0, 0, 0.3]))), device.address)
    drain(device, 0.0)
    before = device.input()
    errors = []
    device.channels.subscribe(
        lambda ev, p: errors.append(p.text) if ev == "error" and "watchdog" not in p.text else None
    )
    bad_rotation = ss.encode_pose(pose([0, 0, 0.3]))
    bad_rotation["Position"]["Rotation"][0][0] = 3.0
    for data in (
        b"not json",
        b"[1, 2]",
        ss.datagram(fly={"x": 1}),
        ss.datagram(measured_cp=bad_rotation),
        ss.datagram(measured_cp={"Position": {"Rotation": [[1, 0, 0]], "Translation": [0] * 3}}),
        ss.datagram(clutch={"Type": 1}),  # ambiguous enum number (dvrk.md 7)
    ):
        client.sendto(data, device.address)
        drain(device, 1.0)
    assert device.input() is before
    assert len(errors) == 1 and "not JSON" in errors[0]  # one report per second …
    client.sendto(b"{", device.address)
    drain(device, 2.5)
    assert len(errors) == 2 and "(7 bad datagrams so far)" in errors[1]  # … with a count
    invalid = ss.encode_pose(pose([0.5, 0, 0.3]))
    invalid["Valid"] = False  # ignored, as data the dVRK cannot vouch for
    client.sendto(
        ss.datagram(measured_cp=invalid, measured_js={"Position": [0] * 7}), device.address
    )
    drain(device, 2.6)
    assert device.input() is before


def test_button_events_and_errors_of_the_codec(device, client):
    client.sendto(ss.datagram(clutch={"Type": "PRESSED"}, coag={"buttons": [2]}), device.address)
    drain(device, 0.0)
    assert device.pop_button_events() == [
        ("clutch", ButtonEvent.PRESSED),
        ("coag", ButtonEvent.CLICKED),
    ]
    with pytest.raises(ss.StreamerFormatError):
        ss.decode_twist({"Velocity": [1, 2]})
    with pytest.raises(ss.StreamerFormatError):
        ss.decode_joint_position({"Position": []})
    with pytest.raises(ss.StreamerFormatError):
        ss.encode_wrench([float("nan")] * 6)
    with pytest.raises(OSError, match="cannot bind"):
        UDPJSONDevice("other", port=device.address[1])


def test_an_external_program_teleoperates_psm1_through_udp(client):
    sim = Simulation("psm1_ecm_mtmr", keyframe="surgical")
    device = UDPJSONDevice("MTMR/device", port=0, clock=lambda: sim.time)
    try:
        console = install_console(
            sim, devices={"MTMR": device}, teleop_config=SIMULATED_SYSTEM, operator_present=True
        )
        console.teleop_enable(True)
        teleop = console.psm_teleops["MTMR_PSM1"]
        T = sim.arms["MTMR"].measured_cp().T.copy()

        def send_and_tick(n):
            for _ in range(n):
                client.sendto(ss.datagram(measured_cp=ss.encode_pose(T)), device.address)
                for _ in range(100):  # wait for loopback delivery, then tick
                    before = device.datagrams_received
                    sim.tick()
                    if device.datagrams_received > before:
                        break

        send_and_tick(20)
        assert teleop.is_following()
        psm = sim.arms["PSM1"]
        p0 = psm.setpoint_cp().position.copy()
        T[:3, 3] += [0.01, 0.0, 0.0]
        send_and_tick(5)
        np.testing.assert_allclose(psm.setpoint_cp().position - p0, [0.002, 0, 0], atol=2e-5)
    finally:
        device.close()


def test_huge_numbers_are_refused_not_raised(device, client):
    """A 400-digit integer (no float holds it) and a finite but absurd twist (issue 11, 4):
    reported, nothing taken, the device goes on."""
    client.sendto(ss.datagram(measured_cp=ss.encode_pose(pose([0, 0, 0.3]))), device.address)
    drain(device, 0.0)
    before = device.input()
    errors = []
    device.channels.subscribe(
        lambda ev, p: errors.append(p.text) if ev == "error" and "watchdog" not in p.text else None
    )
    huge = b'{"measured_cv": {"Velocity": [1' + b"0" * 400 + b", 0, 0, 0, 0, 0]}}"
    client.sendto(huge, device.address)
    drain(device, 1.0)
    client.sendto(ss.datagram(measured_cv=ss.encode_twist([1e300, 0, 0, 0, 0, 0])), device.address)
    drain(device, 2.5)
    assert device.input() is before
    assert any("finite numbers" in e and len(e) < 600 for e in errors), errors
    assert any("twist[0] (vx) = 1e+300 is over 10" in e for e in errors), errors
