"""``crtk.ral`` and the message plumbing without a simulation: names, argument parsing,
messages read as ROS messages, rates, and the rosbridge ops a client sends."""

from __future__ import annotations

import json
import sys
import threading
import time

import numpy as np
import pytest

from davinci_sim.compat import crtk_utils
from davinci_sim.compat import kdl as K
from davinci_sim.compat import ral as ral_module
from davinci_sim.compat.ral import Message, Rate, _type_name, ral, stamp_of
from davinci_sim.compat.transport import RosbridgeClient


class Pipe:
    """A connection that records what the client sends and lets the test answer."""

    def __init__(self, ros_version: int = 2) -> None:
        self.sent: list[dict] = []
        self.on_frame = None
        self.ros_version = ros_version

    def start(self, on_frame, on_close) -> None:
        self.on_frame = on_frame

    def send(self, text: str) -> None:
        op = json.loads(text)
        self.sent.append(op)
        if op["op"] == "call_service":  # rosapi: everything is connected
            values = {"subscribers": ["/x"], "publishers": ["/x"], "version": self.ros_version}
            self.on_frame(json.dumps({"op": "service_response", "id": op["id"],
                                      "values": values, "result": True}))  # fmt: skip

    def close(self) -> None:
        pass


@pytest.fixture
def pipe():
    p = Pipe()
    return p, RosbridgeClient(p)


def test_names_and_children(pipe):
    _, client = pipe
    r = ral("node", node=client)
    psm = r.create_child("PSM1")
    jaw = psm.create_child("/jaw")
    assert r.node_name() == "node" and psm.namespace() == "PSM1" and jaw.namespace() == "PSM1/jaw"
    assert jaw.publisher("servo_jp", "sensor_msgs/JointState").topic_name == "/PSM1/jaw/servo_jp"
    assert psm.subscriber("/measured_js", "x/Y", lambda m: None).topic_name == "/PSM1/measured_js"
    with pytest.raises(RuntimeError, match="already has child"):
        r.create_child("PSM1")
    r.check_connections(1.0)  # every topic answered as connected


def test_parse_argv_strips_ros_arguments():
    argv = ["-a", "PSM1", "--ros-args", "-r", "__ns:=/x", "--", "-i", "0.01", "__name:=n"]
    assert ral.parse_argv(argv) == ["-a", "PSM1", "-i", "0.01"]


def test_messages_read_as_ros_messages():
    m = Message({"header": {"stamp": {"sec": 3, "nanosec": 500_000_000}}, "data": 2.0})
    assert m.data == 2.0 and m.header.stamp.sec == 3 and stamp_of(m) == 3.5
    assert stamp_of({"header": {"stamp": {"secs": 1, "nsecs": 250_000_000}}}) == 1.25  # ROS 1
    m.data = 4.0
    assert m.to_dict()["data"] == 4.0
    with pytest.raises(AttributeError):
        m.missing  # noqa: B018


def test_type_names_from_strings_and_message_classes():
    class Joy:  # what a ROS 2 message class looks like from outside
        __module__ = "sensor_msgs.msg._joy"

    class Bool:
        _type = "std_msgs/Bool"  # ROS 1

    assert _type_name("std_msgs/Empty") == "std_msgs/Empty"
    assert _type_name(Joy) == "sensor_msgs/Joy" and _type_name(Bool) == "std_msgs/Bool"


def test_rate_keeps_its_period_and_catches_up(monkeypatch):
    """On a virtual clock (a test asserts no wall-clock duration): sleeps fill each period
    up to its end; a late iteration starts the schedule again from now, without sleeping."""
    from davinci_sim.compat import ral as ral_module

    clock = {"t": 10.0}
    slept = []

    def sleep(dt):
        slept.append(dt)
        clock["t"] += dt

    monkeypatch.setattr(ral_module.time, "monotonic", lambda: clock["t"])
    monkeypatch.setattr(ral_module.time, "sleep", sleep)
    rate = Rate(100.0)
    clock["t"] += 0.004  # the loop's own work
    rate.sleep()
    assert clock["t"] == pytest.approx(10.01)  # the end of the first period
    for _ in range(4):
        rate.sleep()
    assert clock["t"] == pytest.approx(10.05)  # never faster than asked
    clock["t"] += 0.05  # a late iteration
    rate.sleep()
    assert slept[-1] == pytest.approx(0.01)  # (the previous sleep); none now
    assert len(slept) == 5 and clock["t"] == pytest.approx(10.10)
    rate.sleep()
    assert clock["t"] == pytest.approx(10.11)  # a new schedule from the late one
    with pytest.raises(ValueError):
        Rate(0.0)


def test_sim_time_follows_the_servers_clock(pipe, monkeypatch):
    """With ``use_sim_time`` (here from ROS's argument), ``now`` and a rate read ``/clock``:
    a sleep ends once the clock passes the period's end, never on the wall clock."""
    p, client = pipe

    def clock(t: float) -> None:
        sec = int(t)
        msg = {"clock": {"sec": sec, "nanosec": round((t - sec) * 1e9)}}
        p.on_frame(json.dumps({"op": "publish", "topic": "/clock", "msg": msg}))

    monkeypatch.setattr(sys, "argv", ["x.py", "--ros-args", "-p", "use_sim_time:=true"])
    r = ral("node", node=client).create_child("PSM1")
    assert {"op": "subscribe", "topic": "/clock"}.items() <= p.sent[-1].items()
    assert r.now() == 0.0  # (no clock yet: ROS's time 0)
    clock(2.0)
    assert r.now() == 2.0
    rate = r.create_rate(100.0)  # periods end at 2.01, 2.02
    passes: list[float] = []
    sleeper = threading.Thread(target=lambda: [passes.append(rate.sleep() or r.now())
                                               for _ in range(2)], daemon=True)  # fmt: skip
    sleeper.start()
    clock(2.005)
    time.sleep(0.2)
    assert passes == []  # 0.2 s of wall time is nothing in simulated time
    clock(2.012)
    deadline = time.monotonic() + 30.0
    while not passes and time.monotonic() < deadline:
        time.sleep(0.01)
    assert passes == pytest.approx([2.012])
    clock(2.021)
    sleeper.join(30.0)
    assert passes == pytest.approx([2.012, 2.021])
    assert ral("wall", node=client, use_sim_time=False).now() == pytest.approx(time.time(), abs=5.0)


def test_sim_time_is_asked_for_by_environment_or_ros_argument(monkeypatch):
    monkeypatch.delenv(ral_module.ENV_SIM_TIME, raising=False)
    assert not ral_module.sim_time_requested(["x.py", "-a", "PSM1"])
    assert ral_module.sim_time_requested(["x.py", "--ros-args", "-p", "use_sim_time:=True"])
    assert not ral_module.sim_time_requested(["x.py", "--ros-args", "-p", "use_sim_time:=false"])
    monkeypatch.setenv(ral_module.ENV_SIM_TIME, "1")
    assert ral_module.sim_time_requested(["x.py"])


def test_commands_on_the_wire(pipe):
    p, client = pipe
    r = ral("node", node=client).create_child("PSM1")

    class Device:
        pass

    device = Device()
    u = crtk_utils.utils(device, r, 1.0)
    u.add_operating_state()
    u.add_servo_jp()
    u.add_move_cp()
    u.add_servo_cf()
    device.servo_jp(np.array([0.1, 0.2]), np.array([1.0, 2.0]))
    goal = K.Frame(K.Rotation.RotZ(0.5), K.Vector(0.01, 0.02, 0.03))
    handle = device.move_cp(goal)
    device.servo_cf(np.arange(6.0))
    published = [op for op in p.sent if op["op"] == "publish"]
    assert [op["topic"] for op in published] == [
        "/PSM1/servo_jp",
        "/PSM1/move_cp",
        "/PSM1/servo_cf",
    ]
    assert published[0]["msg"]["position"] == [0.1, 0.2] and published[0]["msg"]["velocity"] == [
        1,
        2,
    ]
    pose = published[1]["msg"]["pose"]
    assert pose["position"] == {"x": 0.01, "y": 0.02, "z": 0.03}
    assert K.Equal(crtk_utils.FrameFromPoseMsg(pose), goal, 1e-12)
    assert published[2]["msg"]["wrench"]["torque"] == {"x": 3.0, "y": 4.0, "z": 5.0}
    assert "header" in published[1]["msg"]  # stamped as crtk does
    with pytest.raises(ValueError, match="6 values"):
        device.servo_cf(np.zeros(5))
    # no operating state newer than the command yet: busy, and a wait times out
    assert handle.is_busy() is True and handle.wait(timeout=0.05) is False
    # operating states arriving: busy then idle, after the command
    for busy in (True, False):
        msg = {"header": {"stamp": {"sec": int(time.time()) + 1, "nanosec": 0}},
               "state": "ENABLED", "is_homed": True, "is_busy": busy}  # fmt: skip
        p.on_frame(json.dumps({"op": "publish", "topic": "/PSM1/operating_state", "msg": msg}))
    assert handle.wait(timeout=1.0) is True and handle.is_busy() is False
    assert device.operating_state() == "ENABLED" and device.is_homed()


@pytest.mark.parametrize("ros_version", [1, 2])
def test_stamps_in_the_servers_dialect(ros_version):
    p = Pipe(ros_version)
    r = ral("node", node=RosbridgeClient(p))
    stamp = r.set_timestamp({})["header"]["stamp"]
    assert set(stamp) == ({"secs", "nsecs"} if ros_version == 1 else {"sec", "nanosec"})
    assert stamp_of({"header": {"stamp": stamp}}) == pytest.approx(time.time(), abs=5)


class PublishingPipe(Pipe):
    """A server whose ``/PSM1/measured_js`` sends its first message a little after rosapi
    was asked about it (as a ROS topic's data follows its discovery); ``/footpedals/clutch``
    never publishes."""

    def send(self, text: str) -> None:
        super().send(text)
        op = json.loads(text)
        if op["op"] == "call_service" and op["args"].get("topic") == "/PSM1/measured_js":
            frame = json.dumps({"op": "publish", "topic": "/PSM1/measured_js",
                                "msg": {"position": [1.0]}})  # fmt: skip
            threading.Timer(0.05, self.on_frame, [frame]).start()


def test_check_connections_waits_for_first_messages_of_connected_topics(monkeypatch):
    monkeypatch.setattr(ral_module, "FIRST_DATA_WAIT", 1.0)  # ample for a message 50 ms later
    pipe = PublishingPipe()
    r = ral("node", node=RosbridgeClient(pipe))
    got = []
    js = r.subscriber("/PSM1/measured_js", "sensor_msgs/JointState", got.append)
    clutch = r.subscriber("/footpedals/clutch", "sensor_msgs/Joy", got.append)
    r.check_connections(5.0)  # no error for the silent pedal
    assert js.received.is_set() and got[0].position == [1.0]  # readable right after
    assert not clutch.received.is_set()


def test_published_objects_spell_times_as_the_server_does():
    from davinci_sim.compat import msgs

    for version, keys in ((1, {"secs", "nsecs"}), (2, {"sec", "nanosec"})):
        p = Pipe(ros_version=version)
        r = ral("node", node=RosbridgeClient(p))
        msg = r.set_timestamp(msgs.message_class("geometry_msgs/PoseStamped")())
        r.publisher("/goal", "geometry_msgs/PoseStamped").publish(msg)
        sent = [op for op in p.sent if op["op"] == "publish"][0]["msg"]
        assert set(sent["header"]["stamp"]) == keys and sent["pose"]["orientation"]["w"] == 1.0
