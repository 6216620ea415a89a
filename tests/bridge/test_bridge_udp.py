"""The dVRK socket-streamer UDP JSON stream (dvrk.md §5)."""

import json
import socket
import time

import numpy as np
import pytest
from bridge_helpers import FAIL_AFTER, enable_and_home, wait_for

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
        end = time.monotonic() + FAIL_AFTER  # (a hang guard: homing waits on the loop)
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


def _errors(sock, n, timeout=FAIL_AFTER):
    """The next ``n`` ``{"error": ...}`` datagrams on ``sock`` (other keys skipped)."""
    out, end = [], time.monotonic() + timeout
    while len(out) < n and time.monotonic() < end:
        try:
            data, _ = sock.recvfrom(65536)
        except TimeoutError:
            break
        msg = json.loads(data)
        if "error" in msg:
            out.append(msg["error"])
    return out


def test_refused_datagrams_are_answered_and_change_nothing(handle, listener):
    """A bad datagram from a plain UDP socket gets an ``{"error": …}`` datagram back (to the
    stream's destination and to its sender) and runs none of its commands."""
    enable_and_home(handle)
    cfg = StreamConfig("PSM1", listener.getsockname()[1], read_commands=("measured_js",))
    with UdpStreamer(handle, [cfg]) as streamer:
        sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sender.bind(("127.0.0.1", 0))
        sender.settimeout(2.0)
        dest = ("127.0.0.1", streamer.local_port("PSM1"))
        before = handle.snapshot().arms["PSM1"].setpoint_js.position.copy()
        goal = [0.1, 0.0, 0.12, 0.0, 0.0, 0.0]
        for bad, why in [
            (b"{nope", "JSON"),
            (b'{"fly": 1}', "unknown command 'fly'"),
            # a good command beside a bad one: the datagram is refused whole
            (json.dumps({"move_jp": {"Goal": goal}, "servo_jp": {"Goal": [1, 2]}}).encode(),
             "servo_jp Goal"),
            (b'{"jaw/servo_jp": {"Goal": [0.1, 0.2]}}', "1 values"),
        ]:  # fmt: skip
            sender.sendto(bad, dest)
            assert why in _errors(sender, 1)[0]
            assert why in _errors(listener, 1)[0]
        # a well-formed command the arm refuses: the arm's own error event, to the destination
        sender.sendto(json.dumps({"move_jp": {"Goal": [0, 0, 5e3, 0, 0, 0]}}).encode(), dest)
        (text,) = _errors(listener, 1)
        assert text.startswith("PSM1: move_jp:") and "insertion" in text
        assert np.array_equal(handle.snapshot().arms["PSM1"].setpoint_js.position, before)
        assert wait_for(lambda: streamer.stats()["PSM1"]["errors"] == 5, 5)
        # the stream went on, and a good command still works
        sender.sendto(json.dumps({"move_jp": {"Goal": goal}}).encode(), dest)
        assert wait_for(
            lambda: np.allclose(handle.snapshot().arms["PSM1"].setpoint_js.position, goal), 5
        )
        sender.close()


def test_mtm_wrench_commands():
    """``body/servo_cf`` and ``spatial/servo_cf`` (``prmForceCartesianSet``: ``Force``, six
    values) reach the MTM: refused while it is disabled, applied once it is enabled."""
    from davinci_sim.sim.handle import ThreadedSimulation
    from davinci_sim.sim.simulation import Simulation

    handle = ThreadedSimulation(Simulation("psm1_ecm_mtmr"), real_time=True).start()
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", 0))
    sink.settimeout(2.0)
    cfg = StreamConfig("MTMR", sink.getsockname()[1], read_commands=("measured_js",))
    try:
        with UdpStreamer(handle, [cfg]) as streamer:
            dest = ("127.0.0.1", streamer.local_port("MTMR"))
            wrench = {"spatial/servo_cf": {"Force": [0, 0, 1.5, 0, 0, 0]}}
            sink.sendto(json.dumps(wrench).encode(), dest)
            assert "needs ENABLED" in _errors(sink, 1)[0]
            sink.sendto(b'{"body/servo_cf": {"Force": [0, 0, 1]}}', dest)
            assert "6 values" in _errors(sink, 1)[0]
            enable_and_home(handle, "MTMR")
            sink.sendto(json.dumps(wrench).encode(), dest)
            assert wait_for(lambda: np.allclose(
                handle.call("MTMR/spatial", "measured_cf").result(5), [0, 0, 1.5, 0, 0, 0],
                atol=1e-3), 5)  # fmt: skip
    finally:
        sink.close()
        handle.stop()


def test_the_node_example_commands_the_psm(handle):
    """``examples/udp_psm.js`` (the documented example in another language, plain JSON over
    UDP): homes the PSM, moves it, and gets a refusal back."""
    import shutil
    import subprocess
    from pathlib import Path

    node = shutil.which("node") or shutil.which("nodejs")
    if node is None:
        pytest.skip("Node.js is not installed")
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    example = Path(__file__).resolve().parents[2] / "examples" / "udp_psm.js"
    with UdpStreamer(handle, [StreamConfig("PSM1", port)]):
        result = subprocess.run([node, str(example), str(port)], capture_output=True, text=True,
                                timeout=90)  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == "homed" and lines[1].startswith("move_jp reached")
    assert lines[2].startswith("refused: PSM1: move_jp:") and "insertion" in lines[2]
    goal = [0.1, -0.05, 0.12, 0.0, 0.0, 0.0]  # the move went on; the refused one changed nothing
    assert wait_for(
        lambda: np.allclose(handle.snapshot().arms["PSM1"].setpoint_js.position, goal), 5
    )
