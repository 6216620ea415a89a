"""Hostile input (issue 11, item 4): the one list of the hostile cases, over rosbridge on
loopback (the huge values over the dVRK's UDP stream too), each bounded (a few MB at most,
deadlines only).

One simulation (PSM1, the ECM and their setup joints, real time) and one server take every
case in turn, as a scene under attack would. After each case the scene must be as it was
apart from what a valid command asked: the simulation still runs, no arm is in FAULT, the
arms the case did not address did not move or change state, and the addressed arm did not
move when its command was refused.

Where each case is also checked closer to its cause: the value checks in
``tests/sim/test_arm_api.py`` (``test_huge_finite_values_are_refused_with_the_field_named``,
``test_home_on_a_homed_enabled_arm_is_a_no_op_and_the_next_move_goes``), the server's
limits in ``test_bridge_bad_input.py`` and the token in ``test_bridge_server.py``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from bridge_helpers import RawClient, enable_and_home, wait_for

from davinci_sim.bridge import BridgeConfig, RosbridgeServer
from davinci_sim.bridge.dvrk_node import DvrkNode
from davinci_sim.bridge.rosbridge.session import MAX_PENDING_CLIENTS, MAX_REPORT
from davinci_sim.sim.handle import ThreadedSimulation
from davinci_sim.sim.simulation import Simulation

LIMIT = 4_000_000  # max_message_size: a few MB, so the cases stay quick
ARMS = ("PSM1", "ECM", "SUJ/PSM1", "SUJ/ECM")


@pytest.fixture(scope="module")
def scene():
    h = ThreadedSimulation(Simulation("psm1"), real_time=True, snapshot_period=0.001).start()
    server = RosbridgeServer(BridgeConfig(port=0, max_message_size=LIMIT),
                             nodes=[DvrkNode(h, rate=100.0)]).start()  # fmt: skip
    try:
        enable_and_home(h, "PSM1")
        enable_and_home(h, "ECM")
        yield h, server
    finally:
        server.stop()
        h.stop()


@pytest.fixture
def client(scene):
    """A raw client asking for status ops; a /rosout reader."""
    _, server = scene
    c = RawClient(server, "info")
    yield c
    c.close()


def settle(h, arm="PSM1"):
    assert wait_for(lambda: not h.snapshot().arms[arm].operating_state.is_busy, 20)


def state_of(h):
    """Each arm's setpoint and operating state (what must not change unless commanded)."""
    arms = h.snapshot().arms
    return {
        name: (arms[name].setpoint_js.position.copy(), arms[name].operating_state.state,
               arms[name].operating_state.is_homed)
        for name in ARMS
    }  # fmt: skip


def assert_scene_unharmed(h, before, moved=()):
    """The simulation still runs, nothing is in FAULT, and every arm not in ``moved`` has
    the setpoint, state and homing it had ``before``."""
    t = h.snapshot().time
    assert wait_for(lambda: h.snapshot().time > t + 0.05), "the simulation stopped"
    after = state_of(h)
    for name in ARMS:
        q0, state0, homed0 = before[name]
        q1, state1, homed1 = after[name]
        assert state1 != "FAULT", f"{name} is in FAULT"
        if name not in moved:
            assert (state1, homed1) == (state0, homed0), name
            assert np.allclose(q0, q1, atol=1e-9), f"{name} moved: {q0} -> {q1}"


def publish(c, topic, type_, msg, **extra):
    c.send({"op": "advertise", "topic": topic, "type": type_})
    c.send({"op": "publish", "topic": topic, "msg": msg, **extra})


def error_status(c, words):
    """The next status at level error; it must contain ``words``."""
    status = c.status(10)
    assert status["level"] == "error" and words in status["msg"], status
    return status


# ---------------------------------------------------------------- huge finite values
def test_a_tiny_trajectory_ratio_is_refused_and_the_next_move_jp_goes(scene, client):
    """``set_ratio 1e-320`` then ``move_jp`` used to make the physics diverge and reset the
    scene (PSM1 and the SUJ arms in FAULT)."""
    h, _ = scene
    settle(h)
    before = state_of(h)
    publish(client, "/PSM1/trajectory_j/set_ratio", "std_msgs/Float64", {"data": 1e-320})
    error_status(client, "ratio must be in [0.001, 1]")
    goal = before["PSM1"][0] + [0.05, -0.05, 0.01, 0.1, 0.05, 0.0]
    publish(client, "/PSM1/move_jp", "sensor_msgs/JointState", {"position": goal.tolist()})
    assert wait_for(lambda: np.allclose(h.snapshot().arms["PSM1"].setpoint_js.position, goal,
                                        atol=1e-6), 20), "the move did not arrive"  # fmt: skip
    settle(h)
    assert_scene_unharmed(h, before, moved=("PSM1",))


@pytest.mark.parametrize(
    "arm, velocity, words",
    [
        ("PSM1", [1e300, 0, 0, 0, 0, 0], "velocity[0]"),
        ("PSM1", [1e3, 0, 0, 0, 0, 0], "velocity[0]"),
        ("ECM", [1e300, 0, 0, 0], "velocity[0]"),
        ("ECM", [0, 1e3, 0, 0], "velocity[1]"),
    ],
)
def test_a_huge_servo_jp_velocity_is_refused_with_the_joint_named(scene, client, arm,
                                                                   velocity, words):  # fmt: skip
    """1e300 rad/s made MuJoCo reset the scene; 1e3 rad/s swung PSM1 into a tracking fault."""
    h, _ = scene
    settle(h, arm)
    before = state_of(h)
    q = before[arm][0].tolist()
    publish(client, f"/{arm}/servo_jp", "sensor_msgs/JointState",
            {"position": q, "velocity": velocity})  # fmt: skip
    error_status(client, words)
    assert_scene_unharmed(h, before)


def test_move_cp_to_x_1e300_names_the_field(scene, client):
    """It returned the raw ``(34, 'Numerical result out of range')``."""
    h, _ = scene
    settle(h)
    before = state_of(h)
    pose = {"position": {"x": 1e300, "y": 0.0, "z": -0.1},
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}  # fmt: skip
    publish(client, "/PSM1/move_cp", "geometry_msgs/PoseStamped", {"pose": pose})
    status = error_status(client, "beyond 10 m")
    assert "position" in status["msg"] and "Numerical result" not in status["msg"]
    assert_scene_unharmed(h, before)


# ---------------------------------------------------------------- state commands
def test_home_on_a_homed_arm_is_a_no_op(scene, client):
    """On the dVRK; it used to home again, and the next move_jp was refused."""
    h, _ = scene
    settle(h)
    before = state_of(h)
    publish(client, "/PSM1/state_command", "crtk_msgs/StringStamped", {"string": "home"})
    assert client.call("/rosapi/nodes", id="sync")["result"] is True  # the command was read
    s = h.snapshot().arms["PSM1"].operating_state
    assert s.is_homed and not s.is_busy
    assert_scene_unharmed(h, before)
    goal = before["PSM1"][0] + [-0.05, 0.05, -0.01, -0.1, -0.05, 0.0]
    publish(client, "/PSM1/move_jp", "sensor_msgs/JointState", {"position": goal.tolist()})
    assert wait_for(lambda: np.allclose(h.snapshot().arms["PSM1"].setpoint_js.position, goal,
                                        atol=1e-6), 20), "the next move was lost"  # fmt: skip
    settle(h)


# ---------------------------------------------------------------- the server's limits
def test_a_huge_op_is_echoed_cut_in_status_and_on_rosout(scene, client):
    """A 9.9 MB ``op`` came back whole in a status op and on every /rosout subscriber."""
    h, server = scene
    before = state_of(h)
    reader = RawClient(server, None)
    try:
        reader.send({"op": "subscribe", "topic": "/rosout"})
        assert client.call("/rosapi/nodes", id="sync")["result"] is True
        client.send({"op": "z" * 3_000_000, "id": "huge"})  # 3 MB, under the 4 MB limit
        status = error_status(client, "unknown op")
        assert "characters left out" in status["msg"] and len(status["msg"]) <= MAX_REPORT
        log = reader.recv_until(lambda m: m.get("op") == "publish"
                                and "unknown op" in m["msg"]["msg"], 10)  # fmt: skip
        assert len(log["msg"]["msg"]) <= MAX_REPORT + 100  # the client's name in front
    finally:
        reader.close()
    assert_scene_unharmed(h, before)


def _pending(server):
    return server.call(lambda: [(len(s._fragments), s.pending_fragment_bytes)
                                for s in server.bridge.sessions])  # fmt: skip


def test_unfinished_fragments_are_capped_per_client_by_count_and_bytes(scene, client):
    h, server = scene
    before = state_of(h)
    for k in range(120):  # 120 tiny messages that never finish: at most 100 kept
        client.send({"op": "fragment", "id": f"n{k}", "num": 0, "total": 2, "data": "x"})
    error_status(client, "dropped: too many")
    piece = "y" * 1_500_000
    for k in range(4):  # 4 x 1.5 MB pending, each message within the 4 MB limit
        client.send({"op": "fragment", "id": f"b{k}", "num": 0, "total": 3, "data": piece})
    assert client.call("/rosapi/nodes", id="sync")["result"] is True
    counts = _pending(server)
    assert max(n for n, _ in counts) <= 100
    assert max(b for _, b in counts) <= LIMIT
    assert_scene_unharmed(h, before)


def test_unfinished_fragments_are_capped_for_all_clients_together(scene):
    """40 fragment ids of 9 MB took the server from 105 to 559 MB: all clients together
    hold at most MAX_PENDING_CLIENTS x max_message_size bytes."""
    h, server = scene
    before = state_of(h)
    piece = "w" * 3_500_000
    clients = [RawClient(server, None) for _ in range(MAX_PENDING_CLIENTS + 2)]
    try:
        for k, c in enumerate(clients):
            c.send({"op": "fragment", "id": f"t{k}", "num": 0, "total": 2, "data": piece})
        for c in clients:
            assert c.call("/rosapi/nodes", id="sync")["result"] is True
        total = sum(b for _, b in _pending(server))
        assert 0 < total <= MAX_PENDING_CLIENTS * LIMIT
    finally:
        for c in clients:
            c.close()
    assert_scene_unharmed(h, before)


# ---------------------------------------------------------------- accepted as ROS would
@pytest.mark.parametrize(
    "msg, extra",
    [
        ({"name": [], "header": None}, {}),
        ({"header": None, "name": [], "velocity": [], "effort": []}, {}),
        ({"header": {"stamp": None, "frame_id": ""}}, {}),
        ({"name": []}, {"latch": False, "queue_size": 10, "unknown_op_field": 1}),
    ],
)
def test_extra_null_or_empty_optional_fields_are_accepted(scene, client, msg, extra):
    """``name: []`` (the arm's order), ``header: null``, empty arrays and op fields the
    server does not use are accepted as ROS would: the command moves the arm, with no
    error."""
    h, _ = scene
    settle(h)
    before = state_of(h)
    goal = before["PSM1"][0] + [0.002, -0.002, 0.0005, 0.0, 0.0, 0.0]
    publish(client, "/PSM1/servo_jp", "sensor_msgs/JointState",
            {**msg, "position": goal.tolist()}, **extra)  # fmt: skip
    assert wait_for(lambda: np.allclose(h.snapshot().arms["PSM1"].setpoint_js.position, goal,
                                        atol=1e-9), 10), "the command was not taken"  # fmt: skip
    assert client.call("/rosapi/nodes", id="sync")["result"] is True
    with pytest.raises(TimeoutError):  # and no error status
        client.recv_until(lambda m: m.get("op") == "status", 0.2)
    assert_scene_unharmed(h, before, moved=("PSM1",))


# ---------------------------------------------------------------- the same over UDP
@pytest.mark.parametrize(
    "arm, command, words",
    [
        ("PSM1", {"move_cp": {"Goal": {"Rotation": np.eye(3).tolist(),
                                       "Translation": [1e300, 0.0, 0.0]}}}, "beyond 10 m"),
        ("PSM1", {"servo_jp": {"Goal": [1e300, 0, 0, 0, 0, 0]}}, "outside its limits"),
        ("ECM", {"move_jp": {"Goal": [0, 0, 1e300, 0]}}, "outside its limits"),
    ],
)  # fmt: skip
def test_huge_values_over_udp_are_refused_with_the_field_named(scene, caplog, arm, command,
                                                                words):  # fmt: skip
    """The dVRK socket-streamer's commands reach the same checks (it has no reply channel:
    the refusal is logged and counted)."""
    import logging
    import socket

    from davinci_sim.bridge.udp import StreamConfig, UdpStreamer

    h, _ = scene
    settle(h, arm)
    before = state_of(h)
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", 0))
    cfg = StreamConfig(arm, sink.getsockname()[1], bind_port=0)
    caplog.set_level(logging.ERROR, logger="davinci_sim")
    with UdpStreamer(h, [cfg]) as streamer, sink:
        sink.sendto(json.dumps(command).encode(), ("127.0.0.1", streamer.local_port(arm)))
        assert wait_for(lambda: streamer.stats()[arm]["errors"] >= 1, 10)
    assert words in caplog.text
    assert_scene_unharmed(h, before)


# ---------------------------------------------------------------- authentication
@pytest.mark.parametrize("first", [{"op": "auth", "mac": "guess"},
                                   {"op": "call_service", "service": "/rosapi/nodes"}])  # fmt: skip
def test_a_wrong_or_missing_token_gets_a_readable_status(scene, first):
    """It used to see only service timeouts."""
    from websockets.exceptions import ConnectionClosed

    h, _ = scene
    before = state_of(h)
    guarded = RosbridgeServer(BridgeConfig(port=0, auth_token="s3cret"),
                              nodes=[DvrkNode(h, rate=100.0)]).start()  # fmt: skip
    c = RawClient(guarded, None)
    try:
        c.send(first)
        status = c.status(10)
        assert status["level"] == "error"
        assert ("invalid token" if first["op"] == "auth" else "missing token") in status["msg"]
        with pytest.raises(ConnectionClosed):
            for _ in range(10):
                c.recv(2.0)
    finally:
        c.close()
        guarded.stop()
    assert_scene_unharmed(h, before)


def test_the_scene_survived_every_case(scene):
    """Last: after all of the above, every arm is still there, none in FAULT, PSM1 and the
    ECM still enabled and homed, and the simulation runs."""
    h, _ = scene
    arms = h.snapshot().arms
    assert set(ARMS) <= set(arms)
    assert all(arms[a].operating_state.state != "FAULT" for a in ARMS)
    assert all(arms[a].operating_state.is_homed for a in ("PSM1", "ECM"))
    t = h.snapshot().time
    assert wait_for(lambda: h.snapshot().time > t + 0.05), "the simulation stopped"
