"""The web console's messages: every field checked before anything acts on it."""

import json
import math

import pytest

from davinci_sim.web.protocol import MAX_MESSAGE, OPS, ProtocolError, parse_message


def msg(**fields) -> str:
    return json.dumps(fields)


def test_good_messages_parse_to_their_checked_fields():
    c = parse_message(msg(op="input", mtm="MTMR", axes=[1, -0.5, 0], gripper=0.3))
    assert c.op == "input" and c.args == {"mtm": "MTMR", "axes": [1.0, -0.5, 0.0], "gripper": 0.3}
    squeezed = parse_message(msg(op="input", mtm="MTMR", axes=[0, 0, 0], gripper=-0.2617))
    assert squeezed.args["gripper"] == -0.2617  # the page's "closed", -15°
    c = parse_message(msg(op="condition", condition={"type": "viscous", "B": 40, "G_max": 5}))
    assert c.args["condition"] == {"type": "viscous", "B": 40.0, "G_max": 5.0}
    assert parse_message(msg(op="condition", condition="B=40")).args == {"condition": "B=40"}
    assert parse_message(msg(op="control", take=True)).args == {"take": True}
    assert parse_message(msg(op="teleop", scale=0.5)).args == {"scale": 0.5}
    assert parse_message(msg(op="trainee", name="  Ada ")).args == {"name": "Ada"}
    c = parse_message(msg(op="input", mtm="MTML", axes=[0, 0, 0], turn=[0, 1, -0.25]))
    assert c.args["turn"] == [0.0, 1.0, -0.25]


@pytest.mark.parametrize(
    "text, words",
    [
        ("not json", "not JSON"),
        ("[1, 2]", "JSON object"),
        (msg(op="fly"), "unknown op"),
        (msg(axes=[0, 0, 0]), "unknown op"),
        (msg(op="input", mtm="MTMR", axes=[0, 0, 0], speed=3), "unknown fields"),
        (msg(op="input", mtm="MTMR"), "'axes' is required"),
        (msg(op="input", mtm="PSM1", axes=[0, 0, 0]), "mtm must be one of"),
        (msg(op="input", mtm="MTMR", axes=[2, 0, 0]), "axes[0] must be in [-1, 1]"),
        (msg(op="input", mtm="MTMR", axes=[0, 0]), "list of 3"),
        (msg(op="input", mtm="MTMR", axes=["0", 0, 0]), "must be a number"),
        (msg(op="input", mtm="MTMR", axes=[True, 0, 0]), "must be a number"),
        ('{"op": "input", "mtm": "MTMR", "axes": [NaN, 0, 0]}', "not a number"),
        ('{"op": "input", "mtm": "MTMR", "axes": [Infinity, 0, 0]}', "not a number"),
        (msg(op="input", mtm="MTMR", axes=[0, 0, 0], gripper=3), "gripper must be in"),
        # Squeezed past -15° (the page's "closed": the jaw's goal -20°) is beyond the range.
        (msg(op="input", mtm="MTMR", axes=[0, 0, 0], gripper=-0.3), "gripper must be in"),
        (msg(op="input", mtm="MTMR", axes=[0, 0, 0], turn=[0, 2, 0]), "turn[1] must be in"),
        (msg(op="input", mtm="MTMR", axes=[0, 0, 0], turn=[0, 0]), "turn must be a list"),
        (msg(op="button", name="self_destruct", pressed=True), "name must be one of"),
        (msg(op="button", name="clutch", pressed=1), "true or false"),
        (msg(op="teleop", scale=0), "scale must be in (0, 1]"),
        (msg(op="teleop", scale=1.5), "scale must be in"),
        (msg(op="condition", condition={"B": 40}), "needs a 'type'"),
        (msg(op="condition", condition={"type": "viscous", "B": -1}), "B: a fixture"),
        (msg(op="condition", condition=3), "a name or a fixture entry"),
        (msg(op="trainee", name="x" * 65), "longer than 64"),
        (msg(op="trainee", name="a\nb"), "control characters"),
        (msg(op="synthetic", action="start", subject=-1), "subject must be >= 0"),
        (msg(op="arms", action="explode"), "action must be one of"),
        (msg(op="advance", seconds=-0.1), "seconds must be in (0, 10]"),
        (msg(op="advance"), "'seconds' is required"),
    ],
)
def test_bad_messages_are_refused_with_a_reason(text, words):
    with pytest.raises(ProtocolError) as e:
        parse_message(text)
    assert words in str(e.value)


def test_binary_and_oversized_messages_are_refused():
    with pytest.raises(ProtocolError, match="text"):
        parse_message(b'{"op": "ping", "t": 1}')
    with pytest.raises(ProtocolError, match="limit"):
        parse_message(msg(op="trainee", name="x", pad="y" * MAX_MESSAGE))


def test_every_op_accepts_its_required_fields_only_message():
    samples = {
        "hello": {}, "control": {"take": False}, "input": {"mtm": "MTML", "axes": [0, 0, 0]},
        "button": {"name": "camera", "pressed": False}, "condition": {"condition": "x"},
        "task": {"action": "reset"}, "exercise": {"task": "ring_walk"},
        "trainee": {"name": ""}, "teleop": {},
        "arms": {"action": "home"}, "recover": {}, "synthetic": {"action": "stop"},
        "ping": {"t": 1.5}, "advance": {"seconds": 0.04},
        "study": {"action": "start", "subjects": 1, "repetitions": 1}, "view": {"stereo": True},
    }  # fmt: skip
    assert set(samples) == set(OPS)
    for op, fields in samples.items():
        assert parse_message(msg(op=op, **fields)).op == op
    assert math.isfinite(parse_message(msg(op="ping", t=1e12)).args["t"])
