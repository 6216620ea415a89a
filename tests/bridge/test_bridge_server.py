"""The rosbridge v2 server with unmodified roslibpy clients (and raw websockets for the rest)."""

import asyncio
import json
import socket
import struct
import threading
import time
from unittest import mock

import cbor2
import pytest
import roslibpy
import roslibpy.ros2
from bridge_helpers import ROS_CONNECT_TIMEOUT, wait_for

from davinci_sim.bridge.rosbridge import codec
from davinci_sim.bridge.rosbridge.core import ServiceFailure


def test_rosapi_with_roslibpy(make_server, make_ros):
    server = make_server()
    ros = make_ros(server)
    assert "/rosout" in ros.get_topics()  # roslibpy's own tests assert this
    services = ros.get_services()
    assert "/rosapi/topics" in services and "/rosapi/get_ros_version" in services
    assert ros.get_topic_type("/rosout") == "rcl_interfaces/msg/Log"
    assert ros.get_service_type("/rosapi/topics") == "rosapi_msgs/srv/Topics"
    assert "/rosapi" in ros.get_nodes()
    assert ros.get_param("/rosdistro") == "humble"
    assert ros.get_param("/not/set") is None
    ros.set_param("/gain", {"kp": 2.5})
    assert ros.get_param("/gain") == {"kp": 2.5}
    assert "/gain" in ros.get_params()
    ros.delete_param("/gain")
    assert ros.get_param("/gain") is None
    details = ros.get_message_details("geometry_msgs/PoseStamped")
    assert details["typedefs"][0]["fieldnames"] == ["header", "pose"]
    version = roslibpy.Service(ros, "/rosapi/get_ros_version", "rosapi/GetROSVersion").call({})
    assert version["version"] == 2


def test_ros1_dialect_get_time_and_header_seq(make_server, make_ros):
    server = make_server(ros_version=1)
    ros = make_ros(server)
    before = time.time()
    t = ros.get_time()  # roslibpy parses only the ROS 1 shape (rosbridge.md 2.1)
    assert before - 1e-3 <= t.to_sec() <= time.time() + 1e-3  # the wall clock, now
    assert ros.get_topic_type("/rosout") == "rosgraph_msgs/Log"
    got = []
    topic = roslibpy.Topic(ros, "/points", "geometry_msgs/PointStamped")
    topic.subscribe(got.append)
    time.sleep(0.2)
    header = roslibpy.Header(seq=None, stamp=roslibpy.Time(10, 20), frame_id="world")
    topic.publish(roslibpy.Message({"header": header, "point": {"x": 1, "y": 2, "z": 3}}))
    assert wait_for(lambda: got)
    assert got[0]["header"] == {"seq": 0, "stamp": {"secs": 10, "nsecs": 20}, "frame_id": "world"}
    assert got[0]["point"] == {"x": 1.0, "y": 2.0, "z": 3.0}


def test_publish_loops_back_to_subscribers(make_server, make_ros):
    """roslibpy's own test_topic: pub/sub on one connection, PointStamped with secs/nsecs."""
    server = make_server()
    ros, other = make_ros(server), make_ros(server)
    mine, theirs = [], []
    listener = roslibpy.Topic(ros, "/chatter", "std_msgs/String")
    listener.subscribe(mine.append)
    roslibpy.Topic(other, "/chatter", "std_msgs/String").subscribe(theirs.append)
    time.sleep(0.3)
    for _ in range(3):
        listener.publish(roslibpy.Message({"data": "hello world"}))
    assert wait_for(lambda: len(mine) >= 3 and len(theirs) >= 3)
    assert mine[0] == {"data": "hello world"}
    points = []
    p = roslibpy.Topic(ros, "/points", "geometry_msgs/PointStamped")
    p.subscribe(points.append)
    time.sleep(0.2)
    p.publish(roslibpy.Message({
        "header": roslibpy.ros2.Header(stamp=roslibpy.Time(1, 2), frame_id="a"),
        "point": {"x": 1.5, "y": 0, "z": -2},
    }))  # fmt: skip
    assert wait_for(lambda: points)
    assert points[0]["header"] == {"stamp": {"sec": 1, "nanosec": 2}, "frame_id": "a"}


def test_one_message_per_topic_per_connection(make_server, make_raw):
    server = make_server()
    sub = make_raw(server, level=None)
    for i in (1, 2, 3):
        sub.send({"op": "subscribe", "topic": "/t", "type": "std_msgs/Int32", "id": f"s{i}"})
    pub = make_raw(server, level=None)
    pub.send({"op": "advertise", "topic": "/t", "type": "std_msgs/msg/Int32"})
    time.sleep(0.1)
    for k in range(5):
        pub.send({"op": "publish", "topic": "/t", "msg": {"data": k}})
    got = [sub.recv() for _ in range(5)]
    assert [m["msg"]["data"] for m in got] == [0, 1, 2, 3, 4]
    assert all(set(m) == {"op", "topic", "msg"} for m in got)  # no id (rosbridge.md 1.3)
    with pytest.raises(TimeoutError):
        sub.recv(0.3)
    # unsubscribing one id keeps the others; the last one ends the subscription
    sub.send({"op": "unsubscribe", "topic": "/t", "id": "s1"})
    sub.send({"op": "unsubscribe", "topic": "/t", "id": "s2"})
    time.sleep(0.1)
    pub.send({"op": "publish", "topic": "/t", "msg": {"data": 9}})
    assert sub.recv()["msg"]["data"] == 9
    sub.send({"op": "unsubscribe", "topic": "/t", "id": "s3"})
    time.sleep(0.1)
    pub.send({"op": "publish", "topic": "/t", "msg": {"data": 10}})
    with pytest.raises(TimeoutError):
        sub.recv(0.3)


class VirtualClock:
    """``time.monotonic`` of the sessions, moved by the test (not by the machine's load)."""

    def __init__(self) -> None:
        self.now = 1000.0

    def monotonic(self) -> float:
        return self.now


def test_throttle_rate_and_queue_length(make_server, make_raw, monkeypatch):
    """On a virtual clock: 20 messages 30 ms apart; a throttle of 100 ms passes one per
    100 ms and drops the rest (rosbridge.md 1.3); with a queue of 2 the queue is drained at
    one per 100 ms and the latest message is kept."""
    from types import SimpleNamespace

    from davinci_sim.bridge.rosbridge import session

    clock = VirtualClock()
    monkeypatch.setattr(session, "time", SimpleNamespace(monotonic=clock.monotonic))
    server = make_server()
    throttled = make_raw(server, level=None)
    throttled.send({"op": "subscribe", "topic": "/n", "type": "std_msgs/Int32",
                    "throttle_rate": 100})  # fmt: skip
    queued = make_raw(server, level=None)
    queued.send({"op": "subscribe", "topic": "/n", "type": "std_msgs/Int32",
                 "throttle_rate": 100, "queue_length": 2})  # fmt: skip
    witness = make_raw(server, level=None)  # unthrottled: tells when a message was routed
    witness.send({"op": "subscribe", "topic": "/n", "type": "std_msgs/Int32", "id": "w"})
    pub = make_raw(server, level=None)
    pub.send({"op": "advertise", "topic": "/n", "type": "std_msgs/Int32"})
    assert wait_for(lambda: len(server.stats()["sessions"]) == 4)
    # publish until the witness gets one: the three subscriptions are then in place
    k = -1
    while True:
        pub.send({"op": "publish", "topic": "/n", "msg": {"data": k}})
        try:
            if witness.recv(0.5)["msg"]["data"] == k:
                break
        except TimeoutError:
            pass
    clock.now += 1.0  # what the warm-up let through is long past
    drain = _drain
    drain(throttled, 0.3), drain(queued, 0.3), drain(witness, 0.3)
    for k in range(20):  # virtual time 0, 30, 60 ... 570 ms
        clock.now = 2000.0 + 0.03 * k
        pub.send({"op": "publish", "topic": "/n", "msg": {"data": k}})
        assert witness.recv_until(lambda m, k=k: m["msg"]["data"] == k)  # routed at clock.now
    for _ in range(10):  # let the queue drain: one per 100 ms of virtual time
        clock.now += 0.1
        time.sleep(0.15)
    a = drain(throttled, 2.0)
    assert a == [0, 4, 8, 12, 16]  # accepted at 0, 120, 240, 360, 480 ms
    b = drain(queued, 2.0)
    assert b == sorted(b) and b[-1] == 19 and len(b) <= 2 + 6, b  # one per 100 ms + queue


def _drain(c, timeout=0.5):
    out = []
    while True:
        try:
            out.append(c.recv(timeout)["msg"]["data"])
        except TimeoutError:
            return out


def test_client_services_are_routed_and_result_is_ignored(make_server, make_ros):
    """roslibpy's test_service: a client advertises, another calls; the provider's
    ``result: false`` is ignored, as rosbridge does (rosbridge.md 1.4)."""
    server = make_server()
    provider, caller = make_ros(server), make_ros(server)

    def add(request, response):
        response["sum"] = request["a"] + request["b"]
        return False

    service = roslibpy.Service(provider, "/test_sum_service", "example_interfaces/AddTwoInts")
    service.advertise(add)
    time.sleep(0.3)
    client = roslibpy.Service(caller, "/test_sum_service", "example_interfaces/AddTwoInts")
    assert client.call(roslibpy.ServiceRequest({"a": 2, "b": 40}), timeout=5)["sum"] == 42
    types = caller.get_service_type("/test_sum_service")
    assert types == "example_interfaces/srv/AddTwoInts"
    service.unadvertise()
    time.sleep(0.2)
    with pytest.raises(roslibpy.core.ServiceException, match="does not exist"):
        client.call(roslibpy.ServiceRequest({"a": 1, "b": 1}), timeout=5)


def test_service_errors_are_service_responses(make_server, make_raw):
    server = make_server()
    c = make_raw(server)
    r = c.call("/nope")
    assert r["result"] is False and "does not exist" in r["values"]
    r = c.call("/rosapi/topic_type", {"topic": 3})
    assert r["result"] is False and "args.topic: expected a string" in r["values"]
    r = c.call("/rosapi/topic_type", ["/rosout"])  # positional args
    assert r["result"] is True and r["values"]["type"] == "rcl_interfaces/msg/Log"
    c.send({"op": "call_service", "service": "/rosapi/nodes#legacy"})  # "service#id" form
    r = c.recv_until(lambda m: m.get("op") == "service_response")
    assert r["id"] == "legacy" and "/rosapi" in r["values"]["nodes"]


def _fibonacci_node():
    class Node:
        def attach(self, bridge):
            async def fib(goal, feedback):
                seq = [0, 1]
                for _ in range(goal["order"] - 1):
                    seq.append(seq[-1] + seq[-2])
                    feedback({"sequence": list(seq)})
                    await asyncio.sleep(0.05)
                if goal["order"] < 0:
                    raise ServiceFailure("order must be >= 0")
                return {"sequence": seq[: goal["order"] + 1]}

            bridge.provide_action("/fibonacci", "example_interfaces/action/Fibonacci", fib,
                                  node="/test")  # fmt: skip

        async def detach(self):
            pass

    return Node()


def test_ros2_actions_with_roslibpy(make_server, make_ros):
    """roslibpy 2.x's test_actions against an internal action server (rosbridge.md 1.5)."""
    server = make_server(nodes=[_fibonacci_node()])
    ros = make_ros(server)
    client = roslibpy.ActionClient(ros, "/fibonacci", "example_interfaces/action/Fibonacci")
    results, feedbacks, errors = [], [], []
    goal_id = client.send_goal(roslibpy.Goal({"order": 4}), results.append, feedbacks.append,
                               errors.append)  # fmt: skip
    client.wait_goal(goal_id, 5)
    assert results[0]["values"]["sequence"] == [0, 1, 1, 2, 3]
    assert results[0]["status"] == roslibpy.core.GoalStatus.SUCCEEDED
    assert feedbacks and feedbacks[-1]["sequence"][-1] == 3
    results.clear()
    goal_id = client.send_goal(roslibpy.Goal({"order": 100}), results.append, feedbacks.append,
                               errors.append)  # fmt: skip
    time.sleep(0.2)
    client.cancel_goal(goal_id)
    client.wait_goal(goal_id, 5)
    assert results[0]["status"] == roslibpy.core.GoalStatus.CANCELED
    goal_id = client.send_goal(roslibpy.Goal({"order": -1}), results.append, feedbacks.append,
                               errors.append)  # fmt: skip
    client.wait_goal(goal_id, 5)
    assert errors and errors[0]["status"] == roslibpy.core.GoalStatus.ABORTED


def test_client_action_server_is_routed(make_server, make_ros, make_raw):
    server = make_server()
    provider = make_raw(server, level=None)
    provider.send({"op": "advertise_action", "action": "/fib", "type":
                   "example_interfaces/action/Fibonacci"})  # fmt: skip
    time.sleep(0.1)
    ros = make_ros(server)
    client = roslibpy.ActionClient(ros, "/fib", "example_interfaces/action/Fibonacci")
    results, feedbacks = [], []
    goal_id = client.send_goal(roslibpy.Goal({"order": 2}), results.append, feedbacks.append,
                               print)  # fmt: skip
    goal = provider.recv_until(lambda m: m["op"] == "send_action_goal")
    assert goal["args"] == {"order": 2} and goal["action_type"].endswith("action/Fibonacci")
    provider.send({"op": "action_feedback", "action": "/fib", "id": goal["id"],
                   "values": {"sequence": [0, 1]}})  # fmt: skip
    provider.send({"op": "action_result", "action": "/fib", "id": goal["id"],
                   "values": {"sequence": [0, 1, 1]}, "status": 4, "result": True})  # fmt: skip
    client.wait_goal(goal_id, 5)
    assert results[0]["values"] == {"sequence": [0, 1, 1]}
    assert feedbacks == [{"sequence": [0, 1]}]
    # cancel goes to the provider with the provider's goal id
    goal_id = client.send_goal(roslibpy.Goal({"order": 5}), results.append, feedbacks.append,
                               print)  # fmt: skip
    goal = provider.recv_until(lambda m: m["op"] == "send_action_goal")
    client.cancel_goal(goal_id)
    cancel = provider.recv_until(lambda m: m["op"] == "cancel_action_goal")
    assert cancel["id"] == goal["id"]


def test_fragments_out_and_in(make_server, make_raw):
    server = make_server()
    c = make_raw(server, level=None)
    c.send({"op": "subscribe", "topic": "/big", "type": "std_msgs/String", "fragment_size": 100})
    time.sleep(0.1)
    text = json.dumps({"op": "publish", "topic": "/big", "msg": {"data": "y" * 1000}})
    pub = make_raw(server, level=None)
    pub.send({"op": "advertise", "topic": "/big", "type": "std_msgs/String"})
    # the publisher sends it in fragments too
    for f in codec.fragments(text, 300, "in-1"):
        pub.send(f)
    parts = [c.recv() for _ in range(11)]
    assert {p["op"] for p in parts} == {"fragment"} and parts[0]["total"] == 11
    whole = json.loads("".join(p["data"] for p in sorted(parts, key=lambda p: p["num"])))
    assert whole["msg"]["data"] == "y" * 1000


def test_cbor_and_png_compression(make_server, make_raw):
    server = make_server()
    cb = make_raw(server, level=None)
    cb.send({"op": "subscribe", "topic": "/js", "type": "sensor_msgs/JointState",
             "compression": "cbor"})  # fmt: skip
    png = make_raw(server, level=None)
    png.send({"op": "subscribe", "topic": "/js", "type": "sensor_msgs/JointState",
              "compression": "png"})  # fmt: skip
    pub = make_raw(server, level=None)
    pub.send({"op": "advertise", "topic": "/js", "type": "sensor_msgs/JointState"})
    time.sleep(0.1)
    pub.send({"op": "publish", "topic": "/js", "msg": {"name": ["a"], "position": [0.25]}})
    frame = cb.recv()
    assert isinstance(frame, bytes)
    msg = cbor2.loads(frame)
    assert msg["op"] == "publish" and msg["msg"]["name"] == ["a"]
    assert struct.unpack("<d", msg["msg"]["position"].value) == (0.25,)
    op = png.recv()
    assert op["op"] == "png"
    assert json.loads(codec.png_decode(op))["msg"]["position"] == [0.25]


def test_latched_topic_reaches_late_subscribers(make_server, make_raw):
    server = make_server()
    pub = make_raw(server, level=None)
    pub.send({"op": "advertise", "topic": "/l", "type": "std_msgs/String", "latch": True})
    pub.send({"op": "publish", "topic": "/l", "msg": {"data": "kept"}})
    time.sleep(0.1)
    late = make_raw(server, level=None)
    late.send({"op": "subscribe", "topic": "/l", "type": "std_msgs/String"})
    assert late.recv()["msg"] == {"data": "kept"}


def test_token_authentication(make_server, make_raw):
    from davinci_sim.bridge.rosbridge.auth import rosauth_mac
    from davinci_sim.bridge.rosbridge.protocol import Auth

    server = make_server(auth_token="s3cret")
    c = make_raw(server, level=None)  # no set_level: the refusal is sent anyway
    c.send({"op": "auth", "mac": "s3cret"})
    assert "/rosout" in c.call("/rosapi/topics")["values"]["topics"]
    # rosauth form: the secret never travels
    fields = dict(client="127.0.0.1", dest="127.0.0.1", rand="r4nd", t=time.time(),
                  level="admin", end=time.time() + 60)  # fmt: skip
    mac = rosauth_mac("s3cret", Auth(mac="", **fields))
    d = make_raw(server)
    d.send({"op": "auth", "mac": mac, **fields})
    assert d.call("/rosapi/nodes")["result"] is True


def test_roslibpy_authenticate_is_accepted(make_server):
    """roslibpy's ``Ros.authenticate`` (sent on connection, before anything else), with the
    rosauth MAC of integer times, as rosauth hashes them."""
    from davinci_sim.bridge.rosbridge.auth import rosauth_mac
    from davinci_sim.bridge.rosbridge.protocol import Auth

    server = make_server(auth_token="s3cret")
    now = int(time.time())
    fields = dict(client="127.0.0.1", dest="127.0.0.1", rand="r4nd", t=now, level="user",
                  end=now + 60)  # fmt: skip
    # roslibpy connects from its constructor and sends the auth from a "ready" listener that
    # authenticate() adds. In a process whose reactor already runs (earlier tests' clients),
    # the connection can be ready before that listener exists, and the auth is never sent: a
    # race in roslibpy's API, not in the server. The constructor's connect is held back until
    # the listener is in, as it is for a process's first client (reactor not yet running).
    with mock.patch.object(roslibpy.Ros, "connect"):
        ros = roslibpy.Ros("127.0.0.1", server.port)
    ros.authenticate(rosauth_mac("s3cret", Auth(mac="", **fields)), **fields)
    # run() can return before the auth listener ran (the connection is set before the
    # event): a call made then reaches the server first and is refused, as rosbridge refuses
    # it. A listener added after authenticate's runs after the auth is sent.
    auth_sent = threading.Event()
    ros.on("ready", lambda *_: auth_sent.set())
    try:
        ros.connect()
        ros.run(ROS_CONNECT_TIMEOUT)
        assert auth_sent.wait(ROS_CONNECT_TIMEOUT)
        topics = []
        ros.get_topics(lambda r: topics.append(r["topics"]))
        assert wait_for(lambda: topics, 10) and "/rosout" in topics[0]
    finally:
        ros.close()


def _refused(client) -> dict:
    """The status a refused client gets, then checks that the server closed the connection
    (code 1008, policy violation)."""
    from websockets.exceptions import ConnectionClosed

    status = client.status()
    with pytest.raises(ConnectionClosed) as closed:
        for _ in range(10):
            client.recv(2.0)
    assert closed.value.rcvd.code == 1008
    return status


@pytest.mark.parametrize(
    "first, reason",
    [
        ({"op": "call_service", "service": "/rosapi/topics", "id": "x"}, "missing token"),
        ({"op": "subscribe", "topic": "/rosout"}, "missing token"),
        ({"op": "auth", "mac": "guess"}, "invalid token"),
        ({"op": "auth"}, "mac"),
    ],
)
def test_a_client_without_the_token_reads_why_before_the_connection_closes(
    make_server, make_raw, first, reason
):
    """A wrong or missing token: one ``status`` op at level error naming the reason, sent
    whatever ``set_level`` asked (roslibjs emits it; a raw client reads it), then the
    connection closes; nothing the client sent was done."""
    server = make_server(auth_token="s3cret")
    c = make_raw(server, level=None)
    c.send(first)
    status = _refused(c)
    assert status["level"] == "error" and reason in status["msg"], status
    if "id" in first:
        assert status["id"] == first["id"]
    assert server.stats()["sessions"] == [] or all(
        not s["subscriptions"] for s in server.stats()["sessions"]
    )


def test_an_expired_rosauth_mac_is_refused_with_a_status(make_server, make_raw):
    from davinci_sim.bridge.rosbridge.auth import rosauth_mac
    from davinci_sim.bridge.rosbridge.protocol import Auth

    server = make_server(auth_token="s3cret")
    expired = dict(client="127.0.0.1", dest="127.0.0.1", rand="r", t=time.time() - 120,
                   level="admin", end=time.time() - 1)  # fmt: skip
    e = make_raw(server, level=None)
    e.send({"op": "auth", "mac": rosauth_mac("s3cret", Auth(mac="", **expired)), **expired})
    assert "expired" in _refused(e)["msg"]


def test_stop_frees_the_port(make_server, make_ros):
    server = make_server()
    port = server.port
    ros = make_ros(server)
    assert ros.is_connected
    server.stop()
    assert not server.running
    s = socket.socket()
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    s.bind(("127.0.0.1", port))  # would raise if the server still held it
    s.close()


def test_a_slow_client_gets_its_messages_in_the_order_they_were_published(make_server, make_raw):
    """A client behind on a busy topic still sees an event after the samples published
    before it (a move's end after the joints of its last tick), not ahead of them."""
    from websockets.sync.client import connect

    server = make_server(send_queue_length=20)
    s = socket.socket()
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    s.connect(("127.0.0.1", server.port))
    with connect(server.url, sock=s, compression=None, max_size=None) as slow:
        slow.send(json.dumps({"op": "subscribe", "topic": "/samples", "type": "std_msgs/String"}))
        slow.send(json.dumps({"op": "subscribe", "topic": "/event", "type": "std_msgs/Int32"}))
        pub = make_raw(server, level=None)
        pub.send({"op": "advertise", "topic": "/samples", "type": "std_msgs/String"})
        pub.send({"op": "advertise", "topic": "/event", "type": "std_msgs/Int32"})
        assert wait_for(lambda: len(server.stats()["sessions"]) == 2)
        time.sleep(0.2)  # (the subscriptions are in place)

        def behind():
            return any(x["dropped"] > 0 for x in server.stats()["sessions"])

        k = 0
        while not behind() and k < 5000:  # until the slow client's queue overflows
            pub.send({"op": "publish", "topic": "/samples",
                      "msg": {"data": f"{k:06d}" + "x" * 10_000}})  # fmt: skip
            k += 1
            if k % 50 == 0:
                time.sleep(0.05)
        assert wait_for(behind), server.stats()
        pub.send({"op": "publish", "topic": "/event", "msg": {"data": k}})
        time.sleep(0.3)  # (routed: the publisher's messages are handled in order)
        got = []
        while True:
            try:
                msg = json.loads(slow.recv(2.0))
            except TimeoutError:
                break
            if msg.get("op") == "publish":
                got.append(msg)
    topics = [m["topic"] for m in got]
    assert topics[-1] == "/event" and topics.count("/event") == 1, topics[-5:]
    samples = [int(m["msg"]["data"][:6]) for m in got[:-1]]
    assert samples == sorted(samples) and samples[-1] == k - 1  # the oldest were dropped


def test_thirty_concurrent_clients(make_server, make_ros):
    server = make_server()
    clients = []
    errors = []

    def connect():
        try:
            clients.append(make_ros(server))
        except Exception as e:  # pragma: no cover - reported below
            errors.append(e)

    threads = [threading.Thread(target=connect) for _ in range(30)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(20)
    assert not errors and len(clients) == 30
    counts = [0] * 30
    for i, ros in enumerate(clients):
        roslibpy.Topic(ros, "/all", "std_msgs/Int32").subscribe(
            lambda m, i=i: counts.__setitem__(i, counts[i] + 1)
        )
    time.sleep(0.5)
    pub = roslibpy.Topic(clients[0], "/all", "std_msgs/Int32")
    for k in range(10):
        pub.publish(roslibpy.Message({"data": k}))
    assert wait_for(lambda: all(c == 10 for c in counts), 10), counts
    assert len(server.stats()["sessions"]) == 30
    for ros in clients[:15]:
        ros.close()
    assert wait_for(lambda: len(server.stats()["sessions"]) == 15, 10)


def test_binary_frames_are_read_as_json(make_server, make_raw):
    server = make_server()
    c = make_raw(server)
    c.send(json.dumps({"op": "call_service", "service": "/rosapi/nodes", "id": "b"}).encode())
    r = c.recv_until(lambda m: m.get("op") == "service_response")
    assert r["result"] is True


def test_periodic_task_keeps_absolute_deadlines_on_a_virtual_loop(monkeypatch):
    """The publishers' timer (``PeriodicTask``) on a loop whose clock the test moves: one
    call per period at k·period, late wake-ups do not drift, a stall skips the missed calls
    instead of bursting."""
    from types import SimpleNamespace

    from davinci_sim.bridge.rosbridge import publisher

    class Loop:
        def __init__(self):
            self.now = 100.0
            self.timer = None

        def time(self):
            return self.now

        def call_at(self, when, fn):
            self.timer = (when, fn)
            return SimpleNamespace(cancel=lambda: None)

        def fire(self, late=0.0):  # the timer fires, ``late`` s after its deadline
            when, fn = self.timer
            self.now = when + late
            fn()
            return when

    loop = Loop()
    monkeypatch.setattr(publisher, "asyncio", SimpleNamespace(get_running_loop=lambda: loop))
    calls = []
    task = publisher.PeriodicTask(0.01, lambda: calls.append(loop.now))
    task.start()
    deadlines = [loop.fire(late=0.004 if k % 2 else 0.0) for k in range(10)]
    assert deadlines == pytest.approx([100.0 + 0.01 * (k + 1) for k in range(10)])  # no drift
    assert len(calls) == task.calls == 10 and task.skipped == 0
    loop.fire(late=0.055)  # a 55 ms stall (at 100.165 s): the deadlines missed are skipped
    assert task.skipped == 4 and task.calls == 11  # one call for the stall, not five
    assert loop.timer[0] == pytest.approx(100.16)  # back on the grid of k·period
    loop.fire()
    assert loop.timer[0] == pytest.approx(100.17) and task.skipped == 4
    with pytest.raises(ValueError):
        publisher.PeriodicTask(0.0, print)
