"""A class on one server: a system per trainee, each their own console and records, and a
lobby listing them (``davinci-sim class``)."""

from __future__ import annotations

import json
import socket
import urllib.error
import urllib.request
from pathlib import Path

import pytest
from websockets.sync.client import connect

from davinci_sim.web.classroom import ClassOptions, Classroom, serve_command

SHORT_TASK = str(Path(__file__).resolve().parents[1] / "study" / "short_path.yaml")


def free_port() -> int:
    """A port the system gives now (the class uses it and the next ones)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_each_trainee_gets_a_system_of_their_own_on_a_port_of_their_own():
    options = ClassOptions(("Ada", "Grace"), task="seed_path", port=9000, token="secret",
                           realtime_priority=50)  # fmt: skip
    commands = [serve_command(options, k) for k in range(2)]
    for k, (command, name) in enumerate(zip(commands, ("Ada", "Grace"), strict=True)):
        assert command[command.index("serve") :][:3] == ["serve", "--task", "seed_path"]
        assert command[command.index("--trainee") + 1] == name
        assert command[command.index("--web-port") + 1] == str(9001 + k)
        assert "--no-server" in command and "--realtime-priority" in command
        assert "secret" not in " ".join(command)  # (the token goes in the environment)


@pytest.mark.parametrize(
    "trainees, words",
    [((), "at least one"), (("a", "a"), "differ"), (("",), "bad trainee"), (("x" * 65,), "bad")],
)
def test_a_bad_class_is_refused(trainees, words):
    with pytest.raises(ValueError, match=words):
        ClassOptions(trainees)


def test_a_class_of_two_serves_each_trainee_their_console_and_a_lobby(tmp_path):
    options = ClassOptions(("Ada", "Grace"), task=SHORT_TASK, port=free_port(),
                           records=str(tmp_path / "records.sqlite3"))  # fmt: skip
    room = Classroom(options).start()
    try:
        assert room.wait_ready(240), room.status()
        status = json.loads(urllib.request.urlopen(room.url + "status.json").read())
        assert [(s["name"], s["state"]) for s in status] == [("Ada", "ready"), ("Grace", "ready")]
        lobby = urllib.request.urlopen(room.url).read().decode()
        for s in status:
            assert f'href="{s["url"]}"' in lobby
            with connect(f"ws://127.0.0.1:{s['port']}/ws", open_timeout=10) as ws:
                hello = json.loads(ws.recv(timeout=20))
                assert hello["trainee"] == s["name"]  # each system records its trainee
        with pytest.raises(urllib.error.HTTPError):
            urllib.request.urlopen(room.url + "nope")
    finally:
        final = room.stop()
    for s in final:
        assert s["state"] == "exited (0)"
        assert any(n.startswith("loop: ") for n in s["notes"])  # its loop's figures


def test_the_lobby_needs_the_token_when_one_is_set():
    room = Classroom(ClassOptions(("Ada",), task=SHORT_TASK, port=free_port(), token="t0k",
                                  extra=("--duration", "5")))  # fmt: skip
    room.start()
    try:
        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(room.url)
        assert e.value.code == 403
        assert urllib.request.urlopen(room.url + "?token=t0k").status == 200
    finally:
        room.stop()


@pytest.fixture(scope="module")
def two_node_cluster():
    """A local Ray cluster of two nodes with one CPU each (one for the module's tests)."""
    ray = pytest.importorskip("ray")
    from ray.cluster_utils import Cluster

    node = {"num_cpus": 1, "object_store_memory": 80 * 2**20}
    cluster = Cluster(initialize_head=True, head_node_args={**node, "include_dashboard": False})
    cluster.add_node(**node)
    cluster.wait_for_nodes()
    yield cluster
    ray.shutdown()
    cluster.shutdown()


def test_on_a_ray_cluster_each_trainee_gets_a_system_on_a_node_of_its_own(two_node_cluster):
    options = ClassOptions(("Ada", "Grace"), task=SHORT_TASK, port=free_port(),
                           ray_address=two_node_cluster.address)  # fmt: skip
    room = Classroom(options).start()
    try:
        assert room.wait_ready(240), room.status()
        status = json.loads(urllib.request.urlopen(room.url + "status.json").read())
        assert [(s["name"], s["state"]) for s in status] == [("Ada", "ready"), ("Grace", "ready")]
        nodes = {s["node"] for s in status}
        assert len(nodes) == 2 and None not in nodes  # one system per node (1 CPU each)
        lobby = urllib.request.urlopen(room.url).read().decode()
        for s in status:
            assert f'href="{s["url"]}"' in lobby
            with connect(s["url"].replace("http", "ws", 1) + "ws", open_timeout=10) as ws:
                assert json.loads(ws.recv(timeout=20))["trainee"] == s["name"]
    finally:
        final = room.stop()
    for s in final:
        assert s["state"] == "exited (0)"
        assert any(n.startswith("loop: ") for n in s["notes"])


def test_a_trainee_without_a_node_with_room_waits_and_says_so(two_node_cluster):
    options = ClassOptions(("Ada", "Grace"), task=SHORT_TASK, port=free_port(),
                           ray_address=two_node_cluster.address, cpus_per_trainee=2,
                           extra=("--duration", "60"))  # fmt: skip
    room = Classroom(options).start()
    try:
        assert not room.wait_ready(3)
        assert {s["state"] for s in room.status()} == {"waiting for a Ray node with room"}
    finally:
        final = room.stop(timeout=1)
    assert len(final) == 2
