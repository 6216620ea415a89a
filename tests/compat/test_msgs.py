"""ROS message classes for dVRK scripts (``std_msgs.msg`` …, :mod:`davinci_sim.compat.msgs`):
the classes, their JSON form, ``ral``'s publishers and subscribers with them (in-process, a
bridge without a simulation relaying between two clients), and the import path
``davinci-sim run`` gives scripts."""

from __future__ import annotations

import importlib
import sys
import threading

import numpy as np
import pytest

from davinci_sim.bridge.rosbridge.types import UnknownTypeError
from davinci_sim.compat import msgs
from davinci_sim.compat.inprocess import InProcessBridge
from davinci_sim.compat.ral import Message, ral, stamp_of
from davinci_sim.compat.run import MSG_SHIM, ROS_SHIM, install_modules, module_choice
from davinci_sim.compat.transport import RosbridgeClient

PoseStamped = msgs.message_class("geometry_msgs/PoseStamped")
Bool = msgs.message_class("std_msgs/Bool")


def test_fields_defaults_and_nesting():
    p = PoseStamped()
    assert p.header.frame_id == "" and (p.header.stamp.sec, p.header.stamp.nanosec) == (0, 0)
    assert type(p.header.stamp) is msgs.message_class("builtin_interfaces/Time")
    q = p.pose.orientation
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)  # ROS 2's default: the identity
    assert PoseStamped().pose is not p.pose  # each object its own nested messages
    assert Bool(data=True).data is True and Bool().data is False
    assert repr(Bool()) == "std_msgs.msg.Bool(data=False)"
    assert Bool(data=True) == Bool(data=True) and Bool() != Bool(data=True)
    assert PoseStamped.get_fields_and_field_types() == {
        "header": "std_msgs/Header", "pose": "geometry_msgs/Pose"}  # fmt: skip
    js = msgs.message_class("sensor_msgs/JointState")()
    assert js.position == [] and js.name == []
    assert msgs.message_class("geometry_msgs/msg/PoseStamped") is PoseStamped
    with pytest.raises(TypeError, match="no field dat"):
        Bool(dat=True)
    with pytest.raises(UnknownTypeError):
        msgs.message_class("std_msgs/NoSuchType")


def test_json_both_ways():
    js = msgs.message_class("sensor_msgs/JointState")(name=["yaw"], position=np.array([0.5]))
    js.header.stamp.sec, js.header.stamp.nanosec = 12, 500
    wire = msgs.to_wire(js)
    assert wire["position"] == [0.5] and type(wire["position"][0]) is float
    assert wire["header"]["stamp"] == {"sec": 12, "nanosec": 500}
    back = msgs.from_wire("sensor_msgs/JointState", wire)
    assert back == msgs.message_class("sensor_msgs/JointState")(
        header=back.header, name=["yaw"], position=[0.5])  # fmt: skip
    assert stamp_of(back) == pytest.approx(12.0 + 500e-9)
    ros1 = msgs.from_wire("std_msgs/Header", {"seq": 3, "stamp": {"secs": 4, "nsecs": 5}})
    assert (ros1.stamp.sec, ros1.stamp.nanosec) == (4, 5)  # a ROS 1 server's spelling
    assert msgs.to_wire(ros1, ros_version=1)["stamp"] == {"secs": 4, "nsecs": 5}
    impedance = msgs.message_class("crtk_msgs/CartesianImpedance")()
    impedance.position_negative.p.z = -200.0
    assert msgs.to_wire(impedance)["position_negative"]["p"] == {"x": 0.0, "y": 0.0, "z": -200.0}
    with pytest.raises(TypeError):
        msgs.to_wire(Bool(data=object()))


@pytest.fixture
def clients():
    """Two clients of one in-process bridge (no simulation: it relays between them)."""
    bridge = InProcessBridge(None, nodes=[]).start()
    pair = [RosbridgeClient(bridge.connect()) for _ in range(2)]
    yield pair
    for c in pair:
        c.close()
    bridge.stop()


def received(r: ral, topic: str, msg_type, count: int = 1):
    got: list = []
    done = threading.Event()

    def callback(msg):
        got.append(msg)
        if len(got) >= count:
            done.set()

    r.subscriber(topic, msg_type, callback)
    return got, done


def test_a_published_pose_object_arrives_as_one(clients):
    sender, receiver = ral("sender", node=clients[0]), ral("receiver", node=clients[1])
    as_object, got_object = received(receiver, "/goal", PoseStamped)
    as_message, got_message = received(receiver, "/goal", "geometry_msgs/PoseStamped")
    pub = sender.publisher("/goal", PoseStamped)
    goal = PoseStamped()
    goal.pose.position.x, goal.pose.orientation.z, goal.header.frame_id = 0.1, 0.5, "PSM1_base"
    sender.set_timestamp(goal)
    assert goal.header.stamp.sec > 0
    for _ in range(50):  # until the subscription is in place on the bridge
        pub.publish(goal)
        if got_object.wait(0.1) and got_message.wait(0.1):
            break
    assert got_object.is_set() and got_message.is_set()
    assert type(as_object[0]) is PoseStamped and as_object[0] == goal
    message = as_message[0]  # a type name: the attribute-reading wrapper
    assert isinstance(message, Message) and message.pose.position.x == 0.1
    assert message.header.frame_id == "PSM1_base"


def test_bool_and_empty_objects_are_published(clients):
    sender, receiver = ral("sender", node=clients[0]), ral("receiver", node=clients[1])
    got, done = received(receiver, "/use_gravity_compensation", Bool)
    pub = sender.publisher("/use_gravity_compensation", Bool, latch=True, queue_size=1)
    empty = sender.publisher("/unlock_orientation", msgs.message_class("std_msgs/Empty"))
    for _ in range(50):
        pub.publish(Bool(data=True))  # was: TypeError: 'Bool' object is not iterable
        empty.publish(msgs.message_class("std_msgs/Empty")())
        if done.wait(0.1):
            break
    assert got and got[0] == Bool(data=True)
    with pytest.raises(TypeError, match="ROS message object or a dict"):
        pub.publish(True)


def test_run_puts_the_packages_on_the_path_after_the_real_ones(monkeypatch):
    monkeypatch.setattr(sys, "path", list(sys.path))
    monkeypatch.setenv("DAVINCI_SIM_PYKDL", "subset")  # the frames below are the subset's
    packages = (*msgs.PACKAGES, "crtk", "dvrk", "PyKDL")
    names = [n for n in sys.modules if n.split(".")[0] in packages]
    saved = {n: sys.modules.pop(n) for n in names}
    try:
        install_modules(module_choice())
        assert sys.path[-1] == str(MSG_SHIM)  # last: an installed ROS's come first
        importlib.invalidate_caches()
        import crtk_msgs.msg
        import geometry_msgs.msg
        import std_msgs.msg

        assert std_msgs.msg.Bool is Bool and geometry_msgs.msg.PoseStamped is PoseStamped
        assert "CartesianImpedance" in crtk_msgs.msg.__all__
        from sensor_msgs.msg import JointState

        assert JointState._type == "sensor_msgs/JointState"
        sys.path.insert(0, str(ROS_SHIM))
        from crtk import msg_conversions as conversions

        from davinci_sim.compat import kdl as K

        frame = K.Frame(K.Rotation.RotZ(0.5), K.Vector(0.01, 0.02, 0.03))
        pose = conversions.FrameToPoseMsg(frame)  # a message, as crtk_python's
        assert type(pose) is geometry_msgs.msg.Pose and pose.position.y == 0.02
        assert conversions.FrameFromPoseMsg(pose) == frame
        transform = conversions.FrameToTransformMsg(frame)
        assert conversions.FrameFromTransformMsg(transform) == frame
        twist = conversions.ArrayToTwistMsg(np.arange(6.0))
        assert twist.angular.z == 5.0 and list(conversions.ArrayFromTwistMsg(twist)) == list(
            np.arange(6.0)
        )
    finally:
        for n in [n for n in sys.modules if n.split(".")[0] in packages]:
            del sys.modules[n]
        sys.modules.update(saved)
