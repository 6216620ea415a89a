"""Message definitions as data: both dialects, validation with defaults, CBOR, rosapi typedefs."""

import math
import struct

import pytest

from davinci_sim.bridge.rosbridge.convert import (
    MessageError,
    default_message,
    from_wire,
    to_cbor_value,
    typedefs,
)
from davinci_sim.bridge.rosbridge.dialect import ROS1, ROS2, TypeNameError, split_type
from davinci_sim.bridge.rosbridge.types import TypeRegistry, UnknownTypeError, parse_definition


@pytest.fixture(scope="module")
def ros1():
    return TypeRegistry(ROS1)


@pytest.fixture(scope="module")
def ros2():
    return TypeRegistry(ROS2)


def test_type_names_in_both_spellings(ros2):
    assert split_type("sensor_msgs/JointState") == ("sensor_msgs/JointState", None)
    assert split_type("/sensor_msgs/msg/JointState") == ("sensor_msgs/JointState", "msg")
    assert split_type("rosapi_msgs/srv/Topics") == ("rosapi/Topics", "srv")
    assert ros2.message("sensor_msgs/msg/JointState") is ros2.message("sensor_msgs/JointState")
    assert ros2.wire_name("sensor_msgs/JointState") == "sensor_msgs/msg/JointState"
    assert ros2.wire_name("rosapi/Topics", "srv") == "rosapi_msgs/srv/Topics"
    assert ROS1.type_name("sensor_msgs/JointState") == "sensor_msgs/JointState"
    for bad in ("JointState", "a/b/c/d", "pkg/foo/Type", "", 3):
        with pytest.raises(TypeNameError):
            split_type(bad)
    with pytest.raises(UnknownTypeError, match="unknown message type 'foo_msgs/Bar'.*known types"):
        ros2.message("foo_msgs/Bar")
    with pytest.raises(UnknownTypeError):
        ros2.message("std_srvs/srv/Trigger")  # a service, not a message


def test_dialect_specific_fields(ros1, ros2):
    assert ros1.message("std_msgs/Header").field_names == ("seq", "stamp", "frame_id")
    assert ros2.message("std_msgs/Header").field_names == ("stamp", "frame_id")
    assert "K" in ros1.message("sensor_msgs/CameraInfo").field_names
    assert "k" in ros2.message("sensor_msgs/CameraInfo").field_names
    assert default_message(ros2, ros2.message("geometry_msgs/Quaternion"))["w"] == 1.0
    assert default_message(ros1, ros1.message("geometry_msgs/Quaternion"))["w"] == 0.0
    assert ros1.service("rosapi/GetParam").request.field_names == ("name", "default")
    assert ros2.service("rosapi/GetParam").request.field_names == ("name", "default_value")


def test_missing_fields_get_defaults_and_times_are_normalised(ros1, ros2):
    spec = ros2.message("geometry_msgs/PoseStamped")
    msg = from_wire(ros2, spec, {"header": {"stamp": {"secs": 3, "nsecs": 5}}})
    assert msg["header"] == {"stamp": {"sec": 3, "nanosec": 5}, "frame_id": ""}
    assert msg["pose"]["orientation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
    msg = from_wire(ros1, ros1.message("std_msgs/Header"), {"stamp": {"sec": 1, "nanosec": 2}})
    assert msg == {"seq": 0, "stamp": {"secs": 1, "nsecs": 2}, "frame_id": ""}
    # roslibpy's ROS 1 Header has seq=None and may have frame_id=None: defaults
    assert (
        from_wire(ros1, ros1.message("std_msgs/Header"), {"seq": None, "frame_id": None})[
            "frame_id"
        ]
        == ""
    )
    # a ROS 1 header sent to a ROS 2 server: seq is dropped
    assert "seq" not in from_wire(ros2, ros2.message("std_msgs/Header"), {"seq": 7})


@pytest.mark.parametrize(
    "type_name, value, match",
    [
        ("std_msgs/String", {"data": 1}, r"msg\.data: expected a string"),
        ("std_msgs/String", {"dat": "x"}, r"unknown field 'dat' for std_msgs/String"),
        ("std_msgs/Float64", {"data": "1"}, r"expected a number"),
        ("std_msgs/Float64", {"data": None}, r"null is not a number"),
        ("std_msgs/Float64", {"data": True}, r"expected a number"),
        ("std_msgs/Int32", {"data": 1.5}, r"expected an integer"),
        ("std_msgs/Int32", {"data": 2**31}, r"out of range for int32"),
        ("std_msgs/UInt8", {"data": -1}, r"out of range for uint8"),
        ("std_msgs/Bool", {"data": "yes"}, r"expected true or false"),
        ("sensor_msgs/JointState", {"position": [1.0, "a"]}, r"position\[1\]: expected a number"),
        ("sensor_msgs/JointState", {"position": 1.0}, r"expected an array of float64"),
        ("sensor_msgs/CompressedImage", {"data": "not base64!"}, r"not a valid base64"),
        ("sensor_msgs/CompressedImage", {"data": [1, 300]}, r"integers in \[0, 255\]"),
        ("sensor_msgs/CameraInfo", {"k": [1.0] * 8}, r"expected 9 elements"),
        ("std_msgs/Header", {"stamp": {"sec": 1, "nsecs": 2}}, r"sec/nanosec \(ROS 2\)"),
        ("std_msgs/Header", {"stamp": {"sec": 1.5}}, r"seconds must be an integer"),
        ("geometry_msgs/Pose", [], r"expected an object for geometry_msgs/Pose"),
    ],
)
def test_bad_messages_name_the_field(ros2, type_name, value, match):
    with pytest.raises(MessageError, match=match):
        from_wire(ros2, ros2.message(type_name), value)


def test_binary_fields(ros2):
    spec = ros2.message("sensor_msgs/CompressedImage")
    assert from_wire(ros2, spec, {"data": "AAH/"})["data"] == b"\x00\x01\xff"
    assert from_wire(ros2, spec, {"data": [0, 1, 255]})["data"] == b"\x00\x01\xff"
    assert from_wire(ros2, spec, {})["data"] == b""


def test_cbor_uses_little_endian_typed_arrays(ros2):
    spec = ros2.message("sensor_msgs/JointState")
    msg = from_wire(ros2, spec, {"name": ["a", "b"], "position": [1.5, -2.0]})
    out = to_cbor_value(ros2, spec, msg)
    assert out["position"].tag == 86
    assert struct.unpack("<2d", out["position"].value) == (1.5, -2.0)
    assert out["name"] == ["a", "b"]
    joy = to_cbor_value(
        ros2,
        ros2.message("sensor_msgs/Joy"),
        {"header": msg["header"], "axes": [0.5], "buttons": [1]},
    )
    assert joy["axes"].tag == 85 and joy["buttons"].tag == 78


def test_rosapi_typedefs(ros1):
    defs = typedefs(ros1, ros1.message("geometry_msgs/PoseStamped"))
    names = [d["type"] for d in defs]
    assert names[0] == "geometry_msgs/PoseStamped"
    assert {"std_msgs/Header", "geometry_msgs/Pose", "geometry_msgs/Point"} <= set(names)
    cam = typedefs(ros1, ros1.message("sensor_msgs/CameraInfo"))[0]
    assert cam["fieldarraylen"][cam["fieldnames"].index("K")] == 9
    assert cam["fieldarraylen"][cam["fieldnames"].index("D")] == 0
    assert cam["fieldarraylen"][cam["fieldnames"].index("height")] == -1
    log = typedefs(ros1, ros1.message("rosgraph_msgs/Log"))[0]
    assert dict(zip(log["constnames"], log["constvalues"], strict=True))["ERROR"] == "8"


def test_definition_parser():
    spec = parse_definition("p/T", "int8 A=1\nfloat64[3] v  # x\nHeader h\nstring s 'd'", 2)
    assert [c.name for c in spec.constants] == ["A"]
    assert [(f.name, f.type, f.length) for f in spec.fields] == [
        ("v", "float64", 3), ("h", "std_msgs/Header", None), ("s", "string", None)]  # fmt: skip
    assert math.isfinite(1.0)
