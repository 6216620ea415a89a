"""The dVRK socket-streamer UDP JSON stream (dvrk.md §5)."""

import json
import socket
import time

import numpy as np
import pytest
from bridge_helpers import enable_and_home, wait_for

from davinci_sim.bridge.udp import (
    DEFAULT_PORTS,
    StreamConfig,
    UdpStreamer,
    command_call,
    default_streams,
    parse_ports,
)


@pytest.fixture
def listener():
    """The user's side: a UDP socket the streamer sends to (like the dVRK's example.py)."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.settimeout(2.0)
    yield s
    s.close()


def receive(sock, n):
    out = []
    for _ in range(n):
        data, addr = sock.recvfrom(65536)
        out.append((json.loads(data), addr))
    return out


def test_datagrams_and_commands(handle, listener):
    port = listener.getsockname()[1]
    with UdpStreamer(handle, [StreamConfig("PSM1", port, period=0.01)]) as streamer:
        got = receive(listener, 40)
        keys = {k for msg, _ in got for k in msg}
        assert keys >= {"measured_js", "jaw/measured_js", "setpoint_cp", "jaw/setpoint_js"}
        assert all(len(msg) == 1 for msg, _ in got)  # one command per datagram
        js = next(msg["measured_js"] for msg, _ in got if "measured_js" in msg)
        assert js["Name"][2] == "insertion" and len(js["Position"]) == 6 and js["Valid"]
        cp = next(msg["setpoint_cp"] for msg, _ in got if "setpoint_cp" in msg)
        assert np.array(cp["Position"]["Rotation"]).shape == (3, 3)
        assert cp["ReferenceFrame"] == "ECM" and cp["MovingFrame"] == "PSM1_setpoint"
        addr = got[0][1]
        assert addr[1] == streamer.local_port("PSM1")
        # commands come back to the streamer's socket
        listener.sendto(b'{"state_command": "enable"}', addr)
        listener.sendto(b'{"state_command": "home"}', addr)
        events = []
        end = time.monotonic() + 10
        while time.monotonic() < end:
            msg, _ = receive(listener, 1)[0]
            if "operating_state" in msg:
                events.append(msg["operating_state"])
                if events[-1]["IsHomed"] and not events[-1]["IsBusy"]:
                    break
        assert events and events[-1]["State"] == "ENABLED"
        goal = [0.1, -0.05, 0.12, 0.0, 0.0, 0.0]
        listener.sendto(json.dumps({"servo_jp": {"Goal": goal}}).encode(), addr)
        assert wait_for(
            lambda: np.allclose(handle.snapshot().arms["PSM1"].setpoint_js.position, goal), 3
        )
        listener.sendto(b'{"hold": ""}', addr)
        # bad datagrams are counted and dropped; the stream goes on
        for bad in (b"{nope", b'{"fly": 1}', b'{"servo_jp": {"Goal": "x"}}', b"[1]"):
            listener.sendto(bad, addr)
        assert wait_for(lambda: streamer.stats()["PSM1"]["errors"] >= 4, 3)
        receive(listener, 5)
    # stop closes the socket: nothing arrives any more
    time.sleep(0.1)
    listener.settimeout(0.3)
    with pytest.raises(TimeoutError):
        while True:
            listener.recvfrom(65536)


def test_cartesian_and_jaw_commands(handle, listener):
    enable_and_home(handle)
    cfg = StreamConfig("PSM1", listener.getsockname()[1], bind_port=0)
    with UdpStreamer(handle, [cfg]) as streamer:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        dest = ("127.0.0.1", streamer.local_port("PSM1"))
        T = handle.snapshot().arms["PSM1"].setpoint_cp.T.copy()
        T[0, 3] += 0.005
        sock.sendto(json.dumps({"move_cp": {"Goal": {"Rotation": T[:3, :3].tolist(),
                                                      "Translation": T[:3, 3].tolist()}}
                                }).encode(), dest)  # fmt: skip
        sock.sendto(json.dumps({"jaw/move_jp": {"Goal": [0.6]}}).encode(), dest)
        assert wait_for(
            lambda: np.allclose(handle.snapshot().arms["PSM1"].measured_cp.T[:3, 3], T[:3, 3],
                                atol=5e-4)
            and abs(handle.snapshot().arms["PSM1"].jaw_measured_js.position[0] - 0.6) < 0.02,
            5,
        )  # fmt: skip
        sock.close()


def test_config_helpers():
    assert DEFAULT_PORTS["PSM1"] == 48051 and DEFAULT_PORTS["ECM"] == 48053
    assert DEFAULT_PORTS["MTML"] == 48054
    assert parse_ports("PSM1=49051, ECM=49053") == {"PSM1": 49051, "ECM": 49053}
    with pytest.raises(ValueError, match="ARM=PORT"):
        parse_ports("PSM1:1")
    assert [s.port for s in default_streams(["PSM1", "ECM"], {"ECM": 1234})] == [48051, 1234]
    with pytest.raises(ValueError, match="no UDP port"):
        default_streams(["SUJ/PSM1"])
    with pytest.raises(ValueError, match="bad port"):
        StreamConfig("PSM1", 0)
    assert command_call("PSM1", "jaw/servo_jp", {"Goal": [0.3]}) == ("PSM1/jaw", "servo_jp", (0.3,))
    with pytest.raises(ValueError, match="3 values"):
        command_call("PSM1", "servo_cp", {"Goal": {"Rotation": [[1, 0, 0]] * 3,
                                                   "Translation": [1, 2]}})  # fmt: skip


def test_unknown_arm_fails_at_start(handle):
    with pytest.raises(ValueError, match="no arm 'PSM7'"):
        UdpStreamer(handle, [StreamConfig("PSM7", 49999)]).start()


def test_stop_frees_the_command_port(handle, listener):
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    cfg = StreamConfig("PSM1", listener.getsockname()[1], bind_port=port)
    streamer = UdpStreamer(handle, [cfg]).start()
    assert streamer.local_port("PSM1") == port
    streamer.stop()
    again = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    again.bind(("127.0.0.1", port))  # raises if the streamer still held it
    again.close()
