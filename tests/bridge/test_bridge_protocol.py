"""Typed rosbridge ops, the JSON codec, fragments, PNG and CBOR frames."""

import base64
import dataclasses
import json
import math
import typing

import cbor2
import numpy as np
import pytest

from davinci_sim.bridge.rosbridge import codec
from davinci_sim.bridge.rosbridge.protocol import (
    ALL_OPS,
    OpError,
    ServiceResponseOut,
    StatusOut,
    Subscribe,
    parse_op,
    to_wire,
)


@pytest.mark.parametrize("cls", ALL_OPS, ids=lambda c: f"{c.__name__}")
def test_every_op_type_hint_resolves(cls):
    """Each op's annotations resolve at runtime (parse_op relies on them)."""
    hints = typing.get_type_hints(cls)
    assert {f.name for f in dataclasses.fields(cls)} <= set(hints)
    assert isinstance(cls.op, str)


def test_parse_op_checks_fields_like_rosbridge():
    op = parse_op({"op": "subscribe", "topic": "/a", "throttle_rate": 10, "id": "s1", "x": 1})
    assert op == Subscribe(topic="/a", throttle_rate=10, id="s1")
    with pytest.raises(OpError, match="throttle_rate.*integer.*float") as e:
        parse_op({"op": "subscribe", "topic": "/a", "throttle_rate": 10.5, "id": "s2"})
    assert e.value.id == "s2"
    with pytest.raises(OpError, match="missing required field 'topic'"):
        parse_op({"op": "subscribe"})
    with pytest.raises(OpError, match="unknown op .fly.; supported ops: action_feedback"):
        parse_op({"op": "fly"})
    with pytest.raises(OpError, match="no 'op'"):
        parse_op({"topic": "/a"})
    with pytest.raises(OpError, match="JSON object"):
        parse_op([1, 2])
    with pytest.raises(OpError, match="'latch' must be boolean"):
        parse_op({"op": "advertise", "topic": "/a", "type": "std_msgs/String", "latch": 1})


def test_to_wire_leaves_out_a_missing_id():
    assert to_wire(StatusOut("error", "bad")) == {"op": "status", "level": "error", "msg": "bad"}
    out = to_wire(ServiceResponseOut("/s", {"a": 1}, True, "c:1"))
    assert out == {"op": "service_response", "service": "/s", "values": {"a": 1},
                   "result": True, "id": "c:1"}  # fmt: skip


def test_dumps_never_emits_invalid_json():
    text = codec.dumps({"a": math.nan, "b": [1.0, math.inf, -math.inf], "c": np.array([np.nan])})
    assert json.loads(text) == {"a": None, "b": [1.0, None, None], "c": [None]}
    assert "NaN" not in text and "Infinity" not in text
    assert json.loads(codec.dumps({"d": b"\x00\x01\xff"}))["d"] == "AAH/"
    assert codec.dumps({"s": "é"}) == '{"s":"\\u00e9"}'  # ASCII only (ROS# reads ASCII)


def test_loads_is_strict_and_accepts_concatenated_objects():
    assert codec.loads_frames('{"op":"a"} {"op":"b"}') == [{"op": "a"}, {"op": "b"}]
    assert codec.loads_frames(b'{"op":"a"}') == [{"op": "a"}]
    for bad, why in [
        ('{"x": NaN}', "NaN"),
        ('{"x": -Infinity}', "Infinity"),
        ('{"x": 1e400}', "infinity"),
        ('{"x": ', "malformed"),
        ("", "empty"),
        (b"\xff\xfe", "UTF-8"),
        ("[" * 100000, "malformed"),
    ]:
        with pytest.raises(codec.DecodeError, match=why):
            codec.loads_frames(bad)


def test_fragments_reassemble():
    text = json.dumps({"op": "publish", "topic": "/t", "msg": {"data": "x" * 1000}})
    parts = codec.fragments(text, 97, "f1")
    assert len(parts) == math.ceil(len(text) / 97)
    assert all(p["total"] == len(parts) and p["id"] == "f1" for p in parts)
    assert "".join(p["data"] for p in sorted(parts, key=lambda p: p["num"])) == text


def test_png_op_carries_the_json_text():
    text = json.dumps({"op": "publish", "topic": "/t", "msg": {"data": "hello" * 50}})
    op = json.loads(codec.png_op(text))
    assert op["op"] == "png"
    assert base64.b64decode(op["data"])[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads(codec.png_decode(op)) == json.loads(text)


def test_cbor_frame_round_trip():
    frame = codec.cbor_frame({"op": "publish", "msg": {"data": b"\x01\x02", "x": math.nan}})
    back = cbor2.loads(frame)
    assert back["msg"]["data"] == b"\x01\x02" and math.isnan(back["msg"]["x"])
