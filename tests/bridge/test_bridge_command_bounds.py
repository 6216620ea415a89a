"""Finite but absurd values over rosbridge reach the arm's own checks (issue 11, item 4):
refused with the field named, nothing moves, no arm faults, the physics never diverges."""

import time

import numpy as np
import pytest
from bridge_helpers import enable_and_home, wait_for


def _wrench(force=(0, 0, 0), torque=(0, 0, 0)):
    return {"wrench": {"force": dict(zip("xyz", force, strict=True)),
                       "torque": dict(zip("xyz", torque, strict=True))}}  # fmt: skip


def _pose(T):
    from davinci_sim.bridge import dvrk_messages as m

    return m.pose_stamped(m.Dialect(2), _Pose(T), 0.0, 0)["pose"]


class _Pose:
    def __init__(self, T):
        self.T, self.reference_frame, self.moving_frame = T, "ECM", "PSM1"


@pytest.mark.parametrize(
    "topic, msg, expected",
    [
        ("/PSM1/body/servo_cf", _wrench(force=(1e300, 0, 0)), "wrench[0] (fx) = 1e+300 is over"),
        ("/PSM1/spatial/servo_cf", _wrench(torque=(0, 50, 0)), "wrench[4] (ty) = 50 is over 10"),
        ("/PSM1/servo_jf", {"effort": [0, 0, 1e300, 0, 0, 0]}, "effort[2] (insertion)"),
        ("/PSM1/jaw/servo_jf", {"effort": [1e300]}, "effort[0] (jaw) = 1e+300 is over"),
        ("/ECM/servo_jp", {"position": [0, 0, 0.12, 0], "velocity": [1e300, 0, 0, 0]},
         "velocity[0] (yaw) = 1e+300 is over"),
        ("/PSM1/trajectory_j/set_ratio", {"data": 1e-320}, "ratio must be in [0.001, 1]"),
        ("/SUJ/PSM1/servo_jp", {"position": [1e300, 0, 0, 0, 0, 0]},
         "joint 'SUJ_PSM1_J0' = 1e+300 is outside its limits"),
        # JSON integers are unbounded: one no float holds is refused by the message check
        ("/PSM1/servo_jp", {"position": [10**400, 0, 0.1, 0, 0, 0]},
         "an integer of 401 digits is too large for float64"),
    ],
)  # fmt: skip
def test_absurd_values_are_refused_by_the_arm(handle, make_server, make_raw, topic, msg, expected):
    server = make_server(handle)
    raw = make_raw(server)
    for arm in ("PSM1", "ECM"):
        enable_and_home(handle, arm)
    before = {n: a.setpoint_js.position.copy() for n, a in handle.snapshot().arms.items()}
    raw.send({"op": "publish", "topic": topic, "msg": msg})
    status = raw.status()
    assert expected in status["msg"] and len(status["msg"]) < 600
    time.sleep(0.1)
    snap = handle.snapshot()
    for name, a in snap.arms.items():
        assert np.array_equal(a.setpoint_js.position, before[name]), name
        assert a.operating_state.state == "ENABLED", name


def test_a_twist_too_fast_for_the_joints_is_refused(handle, make_server, make_raw):
    """servo_cs with a twist whose joint rates exceed 10 x the dVRK limits."""
    server = make_server(handle)
    raw = make_raw(server)
    enable_and_home(handle, "PSM1")
    assert handle.call("PSM1", "move_jp", [0, 0, 0.12, 0, 0, 0]).result(5)
    assert wait_for(lambda: not handle.snapshot().arms["PSM1"].operating_state.is_busy, 10)
    T = handle.snapshot().arms["PSM1"].setpoint_cp.T
    twist = {"linear": {"x": 9.0, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 0}}
    raw.send({"op": "publish", "topic": "/PSM1/servo_cs", "msg": {
        "pose_is_valid": {"data": True}, "pose": _pose(T),
        "twist_is_valid": {"data": True}, "twist": twist}})  # fmt: skip
    assert "twist as joint velocity" in raw.status()["msg"]


def test_udp_commands_with_huge_numbers_are_refused(handle):
    """The UDP stream's commands reach the same checks; a number no float holds is a bad
    datagram, not an exception in the stream (issue 11, 4)."""
    import json
    import socket

    from davinci_sim.bridge.udp import StreamConfig, UdpStreamer

    enable_and_home(handle, "PSM1")
    before = handle.snapshot().arms["PSM1"].setpoint_js.position.copy()
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", 0))
    cfg = StreamConfig("PSM1", sink.getsockname()[1], bind_port=0)
    with UdpStreamer(handle, [cfg]) as streamer:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        dest = ("127.0.0.1", streamer.local_port("PSM1"))
        sock.sendto(b'{"servo_jp": {"Goal": [1' + b"0" * 400 + b", 0, 0.1, 0, 0, 0]}}", dest)
        T = handle.snapshot().arms["PSM1"].setpoint_cp.T
        far = {"Rotation": T[:3, :3].tolist(), "Translation": [1e300, 0, 0]}
        sock.sendto(json.dumps({"move_cp": {"Goal": far}}).encode(), dest)
        assert wait_for(lambda: streamer.stats()["PSM1"]["errors"] >= 2, 5)
        sock.sendto(json.dumps({"servo_jp": {"Goal": before.tolist()}}).encode(), dest)
        time.sleep(0.1)
        assert np.array_equal(handle.snapshot().arms["PSM1"].setpoint_js.position, before)
        assert handle.snapshot().arms["PSM1"].operating_state.state == "ENABLED"
        sock.close()
    sink.close()
