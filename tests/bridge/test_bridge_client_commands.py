"""Client mode takes commands from the remote: the built-in server stands in for the dVRK's
rosbridge, a roslibpy client on it plays the dVRK scripts, and a second simulation served by
the built-in server gives the refusals a command gets there."""

import numpy as np
import pytest
import roslibpy
from bridge_helpers import ROS_CONNECT_TIMEOUT, wait_for

from davinci_sim.bridge import dvrk_messages as m
from davinci_sim.bridge.client_mode import ClientModeConfig, RosClientMode
from davinci_sim.bridge.dvrk_node import DvrkNode
from davinci_sim.sim.handle import ThreadedSimulation
from davinci_sim.sim.simulation import Simulation


class Remote:
    """A client of a rosbridge server: publishes commands, collects messages."""

    def __init__(self, ros):
        self.ros = ros
        self.got: dict[str, list] = {}
        self._pubs: dict[str, roslibpy.Topic] = {}

    def listen(self, name, type_name):
        self.got[name] = []
        roslibpy.Topic(self.ros, name, type_name).subscribe(self.got[name].append)

    def pub(self, name, type_name, msg):
        topic = self._pubs.get(name)
        if topic is None:
            topic = self._pubs[name] = roslibpy.Topic(self.ros, name, type_name)
            topic.advertise()
        topic.publish(roslibpy.Message(msg))


def _js(position, name=()):
    return {"name": list(name), "position": list(position)}


@pytest.fixture
def sim_psm1():
    handles = []

    def make():
        h = ThreadedSimulation(Simulation("psm1"), real_time=True).start()
        handles.append(h)
        return h

    yield make
    for h in handles:
        h.stop()


def _homed(handle, arm="PSM1"):
    s = handle.snapshot().arms[arm].operating_state
    return s.is_homed and not s.is_busy


@pytest.mark.parametrize("ros_version", [1, 2])
def test_a_remote_script_commands_the_simulated_psm(make_server, make_ros, sim_psm1, ros_version):
    """Namespace ``/``: the simulated PSM1 answers to the dVRK's own topic names, as a real
    PSM1 would; state_command, move_jp, servo_jp, jaw and move_cp on the remote move it (a
    ROS 1 and a ROS 2 remote)."""
    remote_server = make_server(ros_version=ros_version)
    handle = sim_psm1()
    remote = Remote(make_ros(remote_server))
    config = ClientModeConfig(remote_server.url, namespace="/", mtms=(), ros_version=ros_version)
    client = RosClientMode(handle, config)
    try:
        client.start(ROS_CONNECT_TIMEOUT)
        remote.listen("/PSM1/operating_state", "crtk_msgs/OperatingState")
        remote.listen("/PSM1/measured_js", "sensor_msgs/JointState")
        remote.pub("/PSM1/state_command", "crtk_msgs/StringStamped", {"string": "enable"})
        remote.pub("/PSM1/state_command", "crtk_msgs/StringStamped", {"string": "home"})

        def remote_homed():
            states = remote.got["/PSM1/operating_state"]
            return states and states[-1]["is_homed"] and not states[-1]["is_busy"]

        assert wait_for(remote_homed, 15)  # the state the remote sees, published back
        goal = [0.2, -0.1, 0.1, 0.3, 0.1, -0.1]
        remote.pub("/PSM1/move_jp", "sensor_msgs/JointState", _js(goal))

        def remote_at(q, atol):
            js = remote.got["/PSM1/measured_js"]
            return js and np.allclose(js[-1]["position"], q, atol=atol)

        assert wait_for(lambda: remote_at(goal, 2e-3) and _homed(handle), 10)
        # servo_jp with named joints in another order
        names = list(handle.snapshot().arms["PSM1"].measured_js.name)
        q = [0.21, -0.1, 0.1, 0.3, 0.1, -0.1]
        remote.pub("/PSM1/servo_jp", "sensor_msgs/JointState", _js(q[::-1], names[::-1]))
        assert wait_for(lambda: np.allclose(
            handle.snapshot().arms["PSM1"].setpoint_js.position, q, atol=1e-9), 5)  # fmt: skip
        remote.pub("/PSM1/jaw/move_jp", "sensor_msgs/JointState", _js([0.7]))
        assert wait_for(
            lambda: abs(handle.snapshot().arms["PSM1"].jaw_measured_js.position[0] - 0.7) < 0.02,
            10,
        )
        # move_cp: 5 mm along x of the current setpoint
        T = handle.snapshot().arms["PSM1"].setpoint_cp.T.copy()
        T[0, 3] += 0.005
        remote.pub("/PSM1/move_cp", "geometry_msgs/PoseStamped", {"pose": m.pose(T)})
        p_goal = T[:3, 3]
        assert wait_for(
            lambda: np.allclose(handle.snapshot().arms["PSM1"].measured_cp.T[:3, 3], p_goal,
                                atol=5e-4), 10)  # fmt: skip
        # the simulator took none of its own messages as input
        assert not set(client.received) & client.published_names
        assert client.received["/PSM1/state_command"] == 2 and client.errors == 0
    finally:
        client.stop()


BAD_COMMANDS = [
    # (topic suffix, type, message): refused by the conversion (wrong joint names) ...
    ("servo_jp", "sensor_msgs/JointState", _js([0.0] * 6, ["a", "b", "c", "d", "e", "f"])),
    # ... and by the arm or its conversion: a joint far beyond its limit (nearer, it would be
    # clipped), a non-unit quaternion, two jaw values, an unknown state (a warning, as on the
    # dVRK)
    ("move_jp", "sensor_msgs/JointState", _js([0.0, 0.0, 5e3, 0.0, 0.0, 0.0])),
    ("servo_cp", "geometry_msgs/PoseStamped",
     {"pose": {"position": {"x": 0, "y": 0, "z": 0.1},
               "orientation": {"x": 0, "y": 0, "z": 0, "w": 2.0}}}),
    ("jaw/servo_jp", "sensor_msgs/JointState", _js([0.1, 0.2])),
    ("state_command", "crtk_msgs/StringStamped", {"string": "fly"}),
]  # fmt: skip


def count(remote, ns):
    return sum(len(remote.got[f"{ns}/PSM1/{e}"]) for e in ("error", "warning"))


def test_bad_commands_get_the_built_in_servers_refusals(make_server, make_ros, sim_psm1):
    """The same bad command on the built-in server and on the remote gives the same text on
    the arm's error topic, and moves neither simulated arm."""
    from bridge_helpers import enable_and_home

    remote_server = make_server()
    sim_remote, sim_local = sim_psm1(), sim_psm1()
    local_server = make_server(nodes=[DvrkNode(sim_local)])
    for h in (sim_remote, sim_local):
        enable_and_home(h)
    remote = Remote(make_ros(remote_server))
    local = Remote(make_ros(local_server))
    client = RosClientMode(sim_remote, ClientModeConfig(remote_server.url, mtms=()))
    try:
        client.start(ROS_CONNECT_TIMEOUT)
        for event in ("error", "warning"):
            remote.listen(f"/sim/PSM1/{event}", "std_msgs/String")
            local.listen(f"/PSM1/{event}", "std_msgs/String")
        remote.listen("/sim/PSM1/measured_js", "sensor_msgs/JointState")
        assert wait_for(lambda: remote.got["/sim/PSM1/measured_js"], 5)  # subscriptions ready
        before = [h.snapshot().arms["PSM1"].setpoint_js.position.copy()
                  for h in (sim_remote, sim_local)]  # fmt: skip
        for k, (suffix, type_name, msg) in enumerate(BAD_COMMANDS, start=1):
            remote.pub(f"/sim/PSM1/{suffix}", type_name, msg)
            local.pub(f"/PSM1/{suffix}", type_name, msg)
            assert wait_for(lambda k=k: count(remote, "/sim") >= k and count(local, "") >= k,
                            5), suffix  # fmt: skip
        for event in ("error", "warning"):
            got_remote = [e["data"] for e in remote.got[f"/sim/PSM1/{event}"]]
            got_local = [e["data"] for e in local.got[f"/PSM1/{event}"]]
            assert got_remote == got_local
        errors = [e["data"] for e in remote.got["/sim/PSM1/error"]]
        assert len(errors) == len(BAD_COMMANDS) - 1
        assert "joint names" in errors[0] and errors[0].startswith("PSM1: servo_jp:")
        assert "unknown state command 'fly'" in remote.got["/sim/PSM1/warning"][0]["data"]
        after = [h.snapshot().arms["PSM1"].setpoint_js.position for h in (sim_remote, sim_local)]
        assert all(np.array_equal(b, a) for b, a in zip(before, after, strict=True))
        assert client.errors >= len(BAD_COMMANDS)
    finally:
        client.stop()


def test_client_mode_refuses_to_take_its_own_messages(sim_psm1):
    """Namespace ``/`` with the simulated MTMR both following the real MTMR and published
    as an arm: it would subscribe to the topics it publishes. Refused before connecting."""
    handle = ThreadedSimulation(Simulation("psm1_ecm_mtmr"), real_time=False)
    config = ClientModeConfig("ws://127.0.0.1:1", namespace="/", mtms=("MTMR",),
                              arms=("PSM1", "MTMR"))  # fmt: skip
    with pytest.raises(ValueError, match=r"its own messages.*/MTMR/measured_js"):
        RosClientMode(handle, config)
    # the usual layouts are fine: under /sim, or at the root without the followed MTM
    RosClientMode(handle, ClientModeConfig("ws://127.0.0.1:1", mtms=("MTMR",),
                                           arms=("PSM1", "MTMR")))  # fmt: skip
    client = RosClientMode(handle, ClientModeConfig("ws://127.0.0.1:1", namespace="/"))
    assert "/PSM1/servo_jp" in client._plan and "MTMR" not in client.arms
    with pytest.raises(ValueError, match="namespace"):
        ClientModeConfig("ws://127.0.0.1:1", namespace="/sim/")


def test_remote_console_and_system_commands(make_server, make_ros):
    """``{ns}/system/home`` homes the simulated arms; ``{ns}/console/teleop/enable`` and the
    teleoperation's ``state_command`` reach the simulated console."""
    setup = pytest.importorskip("davinci_sim.console.setup")
    network = pytest.importorskip("davinci_sim.devices.network")
    remote_server = make_server()
    sim = Simulation("psm1_ecm_mtmr")
    setup.install_console(sim, devices={"MTMR": network.NetworkDevice("MTMR/device")})
    handle = ThreadedSimulation(sim, real_time=True).start()
    remote = Remote(make_ros(remote_server))
    client = RosClientMode(handle, ClientModeConfig(remote_server.url, mtms=("MTMR",)))
    try:
        client.start(ROS_CONNECT_TIMEOUT)
        assert "/sim/console/teleop/enable" in client._plan
        remote.listen("/sim/PSM1/measured_js", "sensor_msgs/JointState")
        assert wait_for(lambda: remote.got["/sim/PSM1/measured_js"], 5)  # subscriptions ready
        remote.pub("/sim/system/home", "std_msgs/Empty", {})
        assert wait_for(lambda: _homed(handle, "PSM1") and _homed(handle, "ECM"), 15)
        remote.pub("/sim/console/teleop/enable", "std_msgs/Bool", {"data": True})
        assert wait_for(lambda: handle.snapshot().extras["console"].teleop_enabled, 5)
        remote.pub("/sim/console/teleop/set_scale", "std_msgs/Float64", {"data": 0.3})
        assert wait_for(lambda: handle.snapshot().extras["console"].scale == 0.3, 5)
        # a refused console command changes nothing
        remote.pub("/sim/console/teleop/set_scale", "std_msgs/Float64", {"data": -1.0})
        assert wait_for(lambda: client.errors >= 1, 5)
        assert handle.snapshot().extras["console"].scale == 0.3
    finally:
        client.stop()
        handle.stop()


def test_a_remote_wrench_on_a_simulated_mtm(make_server, make_ros):
    """A simulated MTM that does not follow a real one (not in ``mtms``) is an arm like the
    others: ``{ns}/MTMR/state_command`` and ``{ns}/MTMR/spatial/servo_cf`` command it."""
    remote_server = make_server()
    handle = ThreadedSimulation(Simulation("psm1_ecm_mtmr"), real_time=True).start()
    remote = Remote(make_ros(remote_server))
    client = RosClientMode(handle, ClientModeConfig(remote_server.url, mtms=()))
    try:
        assert "MTMR" in client.arms
        client.start(ROS_CONNECT_TIMEOUT)
        remote.listen("/sim/MTMR/operating_state", "crtk_msgs/OperatingState")
        assert wait_for(lambda: remote.got["/sim/MTMR/operating_state"], 5)  # latched
        remote.pub("/sim/MTMR/state_command", "crtk_msgs/StringStamped", {"string": "enable"})
        remote.pub("/sim/MTMR/state_command", "crtk_msgs/StringStamped", {"string": "home"})
        assert wait_for(lambda: _homed(handle, "MTMR"), 15)
        wrench = [0.0, 0.0, 1.5, 0.0, 0.0, 0.0]
        remote.pub("/sim/MTMR/spatial/servo_cf", "geometry_msgs/WrenchStamped",
                   {"wrench": {"force": {"x": 0, "y": 0, "z": 1.5},
                               "torque": {"x": 0, "y": 0, "z": 0}}})  # fmt: skip

        def measured_cf():
            return handle.call("MTMR/spatial", "measured_cf").result(5)

        assert wait_for(lambda: np.allclose(measured_cf(), wrench, atol=1e-3), 5)
    finally:
        client.stop()
        handle.stop()


def test_the_streams_drop_periods_while_the_send_queue_is_full(
    make_server, make_ros, sim_psm1, monkeypatch
):
    """Streams are latest-wins: while the process's queue of sends is over
    ``MAX_BACKLOG`` (a remote that reads slower than the streams come) the client mode
    sends no state and counts the periods it skipped; once it drains, the states flow."""
    from davinci_sim.bridge import client_mode

    remote_server = make_server()
    handle = sim_psm1()
    remote = Remote(make_ros(remote_server))
    client = RosClientMode(handle, ClientModeConfig(remote_server.url, mtms=()))
    full = {"on": True}
    monkeypatch.setattr(client_mode, "send_backlog",
                        lambda: client_mode.MAX_BACKLOG + 1 if full["on"] else 0)  # fmt: skip
    try:
        client.start(ROS_CONNECT_TIMEOUT)
        remote.listen("/sim/PSM1/measured_js", "sensor_msgs/JointState")
        assert wait_for(lambda: client.skipped >= 20, 5)
        assert remote.got["/sim/PSM1/measured_js"] == []
        full["on"] = False
        assert wait_for(lambda: len(remote.got["/sim/PSM1/measured_js"]) >= 5, 5)
    finally:
        client.stop()


def test_serve_in_client_mode_takes_the_remote_commands(make_server, make_ros):
    """``davinci-sim serve --ros-connect URL --namespace /``: a script on the remote system
    homes and moves the simulated PSM1 with the dVRK's own topic names."""
    from bridge_helpers import serving

    from davinci_sim.bridge.app import ServeOptions
    from davinci_sim.bridge.rosbridge.config import BridgeConfig

    remote_server = make_server()
    options = ServeOptions(scene="psm1", images="none", ros_connect=remote_server.url,
                           ros_connect_timeout=ROS_CONNECT_TIMEOUT, namespace="/",
                           bridge=BridgeConfig(port=0))  # fmt: skip
    with serving(options):
        remote = Remote(make_ros(remote_server))
        remote.listen("/PSM1/operating_state", "crtk_msgs/OperatingState")
        remote.listen("/PSM1/measured_js", "sensor_msgs/JointState")
        remote.pub("/PSM1/state_command", "crtk_msgs/StringStamped", {"string": "enable"})
        remote.pub("/PSM1/state_command", "crtk_msgs/StringStamped", {"string": "home"})

        def homed():
            s = remote.got["/PSM1/operating_state"]
            return s and s[-1]["is_homed"] and not s[-1]["is_busy"]

        assert wait_for(homed, 15)
        goal = [0.0, 0.1, 0.1, 0.0, 0.0, 0.0]
        remote.pub("/PSM1/move_jp", "sensor_msgs/JointState", _js(goal))
        assert wait_for(lambda: np.allclose(
            remote.got["/PSM1/measured_js"][-1]["position"], goal, atol=2e-3), 10)  # fmt: skip
