"""Every bad input gets a clear error; the connection, other clients and the simulation go on."""

import json
import socket
import time

import numpy as np
import pytest
import roslibpy
from bridge_helpers import enable_and_home, ros_client, wait_for
from websockets.sync.client import connect


@pytest.fixture
def setup(handle, make_server, make_raw, make_ros):
    """A server with the dVRK API, a raw client asking for status, a roslibpy bystander."""
    server = make_server(handle, max_message_size=64_000)
    bad = make_raw(server)
    bystander = make_ros(server)
    seen = []
    roslibpy.Topic(bystander, "/PSM1/measured_js", "sensor_msgs/JointState").subscribe(seen.append)
    assert wait_for(lambda: seen)
    return server, bad, bystander, seen


def still_fine(server, bad, seen, handle):
    """The offending connection answers, the bystander still receives, the sim still ticks."""
    r = bad.call("/rosapi/nodes", id="alive")
    assert r["result"] is True
    n, t = len(seen), handle.snapshot().time
    assert wait_for(lambda: len(seen) > n + 5)
    assert wait_for(lambda: handle.snapshot().time > t + 0.05)


@pytest.mark.parametrize(
    "frame, expected",
    [
        ("{not json", "bad message: malformed JSON"),
        ('{"op": "publish", "topic": "/PSM1/servo_jp", "msg": {"position": [NaN]}}',
         "NaN and infinity are not accepted"),
        ('{"op": "publish", "topic": "/x", "msg": {"data": Infinity}}', "not valid JSON"),
        ('{"op": "publish", "topic": "/x", "msg": {"data": 1e999}}', "overflows to infinity"),
        ('{"op": "teleport", "id": "t1"}', "unknown op 'teleport'"),
        ('{"op": "subscribe", "topic": 5}', "field 'topic' must be string"),
        ('{"op": "subscribe", "topic": "/a", "queue_length": "10"}', "'queue_length' must be"),
        ('[1, 2]', "must be a JSON object"),
        ('{"topic": "/a"}', "no 'op'"),
        ('{"op": "subscribe", "topic": "/a", "type": "foo_msgs/Bar"}',
         "unknown message type 'foo_msgs/Bar'"),
        ('{"op": "subscribe", "topic": "/a", "type": "Bar"}', "bad type name 'Bar'"),
        ('{"op": "subscribe", "topic": "/nobody/knows"}', "unknown topic /nobody/knows"),
        ('{"op": "subscribe", "topic": "bad name!", "type": "std_msgs/String"}',
         "invalid topic name"),
        ('{"op": "publish", "topic": "/never/advertised", "msg": {}}', "cannot infer the type"),
        ('{"op": "advertise", "topic": "/PSM1/measured_js", "type": "std_msgs/String"}',
         "has type sensor_msgs/msg/JointState (set by the simulator (/davinci_sim))"),
        ('{"op": "subscribe", "topic": "/PSM1/servo_jp", "type": "std_msgs/String"}',
         "cannot be used as std_msgs/String"),
        ('{"op": "publish", "topic": "/PSM1/servo_jp", "msg": {"position": "fast"}}',
         "msg.position: expected an array of float64"),
        ('{"op": "publish", "topic": "/PSM1/servo_cp", "msg": {"pose": {"orient": {}}}}',
         "unknown field 'orient' for geometry_msgs/Pose"),
        ('{"op": "unsubscribe", "topic": "/never"}', "not subscribed to /never"),
        ('{"op": "service_response", "service": "/s", "id": "zz", "values": {}}',
         "no pending call"),
        ('{"op": "set_level", "level": "loud"}', "level must be one of"),
        ('{"op": "fragment", "id": 1, "data": "x", "num": 3, "total": 2}', "inconsistent"),
        ('{"op": "subscribe", "topic": "/a", "type": "std_msgs/String", "compression": "zip"}',
         "unknown compression 'zip'"),
    ],
)  # fmt: skip
def test_bad_frames_are_answered_and_nothing_breaks(setup, handle, frame, expected):
    server, bad, _, seen = setup
    before = handle.snapshot().arms["PSM1"].setpoint_js.position.copy()
    bad.send(frame)
    status = bad.status()
    assert status["level"] == "error"
    assert expected in status["msg"], status["msg"]
    still_fine(server, bad, seen, handle)
    assert np.array_equal(before, handle.snapshot().arms["PSM1"].setpoint_js.position)


def test_status_echoes_the_id_and_is_sent_only_when_asked(setup, make_raw):
    server, bad, *_ = setup
    bad.send({"op": "teleport", "id": "my-id"})
    assert bad.status()["id"] == "my-id"
    quiet = make_raw(server, level=None)  # never sent set_level: no status ops
    quiet.send("{broken")
    quiet.send({"op": "call_service", "service": "/rosapi/nodes", "id": "q"})
    assert quiet.recv()["op"] == "service_response"  # the first thing it gets
    bad.send({"op": "set_level", "level": "none"})
    bad.send({"op": "teleport"})
    assert bad.call("/rosapi/nodes")["op"] == "service_response"  # no status before it


def test_oversized_messages_are_refused(setup, handle):
    server, bad, _, seen = setup
    big = json.dumps({"op": "publish", "topic": "/x", "msg": {"data": "z" * 70_000}})
    bad.send(big)
    assert "exceeds the limit of 64000 bytes" in bad.status()["msg"]
    # the same through fragments
    for k in range(3):
        bad.send({"op": "fragment", "id": "f", "num": k, "total": 3, "data": big[:30_000]})
    assert "exceeds the limit" in bad.status()["msg"]
    still_fine(server, bad, seen, handle)


def test_a_huge_bad_value_is_not_echoed_back_whole(setup, handle):
    server, bad, _, seen = setup
    huge_op = "x" * 60_000  # under the 64 kB limit: read, refused as an unknown op
    bad.send({"op": huge_op, "id": "h"})
    status = bad.status()
    assert "unknown op" in status["msg"] and "characters left out" in status["msg"]
    assert len(status["msg"]) <= 600
    still_fine(server, bad, seen, handle)


def test_unfinished_fragmented_messages_are_bounded_per_client(setup, handle):
    server, bad, _, seen = setup
    piece = "y" * 30_000
    for k in range(6):  # six messages of 2 x 30 kB, each within the 64 kB limit, never finished
        bad.send({"op": "fragment", "id": f"m{k}", "num": 0, "total": 2, "data": piece})
    assert "dropped: too many bytes" in bad.status()["msg"]
    sessions = server.call(lambda: list(server.bridge.sessions))
    assert max(s.pending_fragment_bytes for s in sessions) <= 64_000
    still_fine(server, bad, seen, handle)


def test_invalid_commands_move_nothing(setup, handle, make_raw):
    server, bad, bystander, seen = setup
    enable_and_home(handle)
    errors = []
    roslibpy.Topic(bystander, "/PSM1/error", "std_msgs/String").subscribe(
        lambda m: errors.append(m["data"])
    )
    time.sleep(0.2)
    before = handle.snapshot().arms["PSM1"].setpoint_js.position.copy()
    bad.send({"op": "advertise", "topic": "/PSM1/servo_cp", "type": "geometry_msgs/PoseStamped"})
    # a zero quaternion: refused by the bridge, reported on the arm's error topic too
    bad.send({"op": "publish", "topic": "/PSM1/servo_cp", "msg": {"pose": {"orientation":
              {"x": 0, "y": 0, "z": 0, "w": 0}}}})  # fmt: skip
    assert "must be a unit quaternion" in bad.status()["msg"]
    # far out of joint limits (a goal near them is clipped): refused by the arm on its error
    # channel
    bad.send({"op": "publish", "topic": "/PSM1/move_jp",
              "msg": {"position": [9e3, 0, 0.1, 0, 0, 0]}})  # fmt: skip
    assert "outside its limits" in bad.status()["msg"]
    # the wrong number of joints, and joint names that are not the arm's
    bad.send({"op": "publish", "topic": "/PSM1/servo_jp", "msg": {"position": [0.1]}})
    assert "must have 6 values" in bad.status()["msg"]
    bad.send({"op": "publish", "topic": "/PSM1/servo_jp",
              "msg": {"name": ["a", "b"], "position": [0.1, 0.2]}})  # fmt: skip
    assert "do not match the arm's joints" in bad.status()["msg"]
    assert wait_for(lambda: any("unit quaternion" in e for e in errors))
    assert wait_for(lambda: any("outside its limits" in e for e in errors))
    time.sleep(0.1)
    after = handle.snapshot().arms["PSM1"]
    assert np.array_equal(before, after.setpoint_js.position)
    assert not after.operating_state.is_busy
    still_fine(server, bad, seen, handle)


def test_slow_client_gets_a_bounded_queue(handle, make_server, make_ros):
    """A client that never reads: its queue stays bounded (oldest dropped), others go on."""
    server = make_server(handle, rate=1000, send_queue_length=20)
    s = socket.socket()
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    s.connect(("127.0.0.1", server.port))
    ws = connect(server.url, sock=s, compression=None)
    with ws:
        for topic in (
            "measured_js",
            "setpoint_js",
            "measured_cp",
            "setpoint_cp",
            "local/measured_cp",
            "measured_cv",
        ):
            ws.send(json.dumps({"op": "subscribe", "topic": f"/PSM1/{topic}"}))
        ok = make_ros(server)
        seen = []
        roslibpy.Topic(ok, "/PSM1/measured_js", "sensor_msgs/JointState").subscribe(seen.append)

        def slow():
            return [x for x in server.stats()["sessions"] if x["dropped"] > 0]

        assert wait_for(slow, 20), server.stats()
        stats = slow()[0]
        assert all(sub["queued"] <= 20 for sub in stats["subscriptions"].values())
        n = len(seen)
        assert wait_for(lambda: len(seen) > n + 100, 5)  # the good client still streams
        t = handle.snapshot().time
        assert wait_for(lambda: handle.snapshot().time > t + 0.1)


def test_client_disconnecting_mid_stream(handle, make_server, make_ros):
    server = make_server(handle, rate=500)
    for _ in range(3):
        c = ros_client(server.port)
        got = []
        roslibpy.Topic(c, "/PSM1/measured_js", "sensor_msgs/JointState").subscribe(got.append)
        roslibpy.Topic(c, "/PSM1/measured_cp", "geometry_msgs/PoseStamped").subscribe(got.append)
        assert wait_for(lambda got=got: len(got) > 20)
        c.close()  # while messages are flowing
    raw = socket.create_connection(("127.0.0.1", server.port))
    raw.sendall(b"GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\n")  # half a handshake
    raw.close()
    assert wait_for(lambda: len(server.stats()["sessions"]) == 0, 10)
    ros = make_ros(server)
    got = []
    roslibpy.Topic(ros, "/PSM1/measured_js", "sensor_msgs/JointState").subscribe(got.append)
    assert wait_for(lambda: len(got) > 50, 5)
