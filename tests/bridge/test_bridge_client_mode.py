"""Client mode against the project's own server standing in for a real dVRK's rosbridge."""

import threading
import time

import numpy as np
import pytest
import roslibpy
from bridge_helpers import ROS_CONNECT_TIMEOUT, wait_for

from davinci_sim.bridge import dvrk_messages as m
from davinci_sim.bridge.client_mode import ClientModeConfig, RosClientMode
from davinci_sim.sim.handle import ThreadedSimulation
from davinci_sim.sim.simulation import Simulation


class FakeConsole:
    """The real system: an MTM publishing its state at 100 Hz, pedals, and listeners."""

    def __init__(self, ros, names):
        self.ros = ros
        self.names = names
        self.q = np.zeros(len(names))
        self.T = np.eye(4)
        self.T[:3, 3] = (-0.18, 0.02, 0.4)
        self.js = roslibpy.Topic(ros, "/MTMR/measured_js", "sensor_msgs/JointState")
        self.cp = roslibpy.Topic(ros, "/MTMR/measured_cp", "geometry_msgs/PoseStamped")
        self.grip = roslibpy.Topic(ros, "/MTMR/gripper/measured_js", "sensor_msgs/JointState")
        self.clutch = roslibpy.Topic(ros, "/footpedals/clutch", "sensor_msgs/Joy")
        for t in (self.js, self.cp, self.grip, self.clutch):
            t.advertise()
        self.wrenches, self.sim_js, self.sim_state = [], [], []
        roslibpy.Topic(ros, "/MTMR/body/servo_cf", "geometry_msgs/WrenchStamped").subscribe(
            self.wrenches.append
        )
        roslibpy.Topic(ros, "/sim/PSM1/measured_js", "sensor_msgs/JointState").subscribe(
            self.sim_js.append
        )
        roslibpy.Topic(ros, "/sim/PSM1/operating_state", "crtk_msgs/OperatingState").subscribe(
            self.sim_state.append
        )
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self):
        while not self._stop.wait(0.01):
            self.js.publish(roslibpy.Message({"name": self.names, "position": self.q.tolist()}))
            self.cp.publish(roslibpy.Message({"header": {"frame_id": "HRSV"},
                                              "pose": m.pose(self.T)}))  # fmt: skip
            self.grip.publish(roslibpy.Message({"name": ["gripper"], "position": [0.5]}))

    def stop(self):
        self._stop.set()
        self._thread.join(2)


@pytest.fixture
def remote(make_server, make_ros):
    server = make_server()  # a bare rosbridge: the remote ROS system
    return server, make_ros(server)


@pytest.fixture
def fake_console(remote):
    """``fake_console(names)`` → a :class:`FakeConsole` on the remote, stopped after the
    test even when it fails (before, a failure between its start and the test's ``try``
    left it publishing 300 messages a second for the rest of the worker's session), and
    before the remote's client closes."""
    fakes = []

    def make(names):
        fakes.append(FakeConsole(remote[1], names))
        return fakes[-1]

    yield make
    for fake in fakes:
        fake.stop()


def test_client_mode_drives_the_simulated_mtm_and_publishes_states(remote, fake_console):
    server, remote_ros = remote
    handle = ThreadedSimulation(Simulation("psm1_ecm_mtmr"), real_time=True).start()
    names = list(handle.snapshot().arms["MTMR"].measured_js.name)
    fake = fake_console(names)
    wrench = np.array([1.0, 0.0, -2.0, 0.0, 0.0, 0.0])
    client = RosClientMode(
        handle,
        ClientModeConfig(server.url, mtms=("MTMR",), rate=50),
        wrench_source=lambda snap: {"MTMR": wrench},
    )
    try:
        client.start(ROS_CONNECT_TIMEOUT)
        assert client.mode == {"MTMR": "joints"}  # no network device in this simulation
        assert wait_for(lambda: handle.snapshot().arms["MTMR"].operating_state.is_homed, 10)
        fake.q = np.array([0.1, 0.2, -0.1, 0.3, 0.2, 0.1, 0.4])
        assert wait_for(
            lambda: np.allclose(handle.snapshot().arms["MTMR"].measured_js.position, fake.q,
                                atol=5e-3), 10)  # fmt: skip
        assert wait_for(
            lambda: abs(handle.snapshot().arms["MTMR"].gripper_measured_js.position[0] - 0.5)
            < 0.02, 5)  # fmt: skip
        # simulated PSM state on the remote, under /sim
        assert wait_for(lambda: len(fake.sim_js) > 10 and fake.sim_state, 5)
        assert fake.sim_js[-1]["name"][2] == "insertion"
        assert fake.sim_state[-1]["state"] == "DISABLED"
        # the guidance wrench, rotated into the handle's frame
        R = m.matrix_from_quaternion(0.0, 0.0, np.sin(0.25), np.cos(0.25))  # 0.5 rad about z
        fake.T[:3, :3] = R
        expected = R.T @ wrench[:3]

        def rotated() -> bool:  # (once the rotated handle pose has reached the client mode)
            if not fake.wrenches:
                return False
            w = fake.wrenches[-1]["wrench"]
            return np.allclose([w["force"][k] for k in "xyz"], expected, atol=1e-6)

        assert wait_for(rotated, 10)
        # the wrench goes to zero: one zero is sent, then nothing
        wrench[:] = 0.0
        assert wait_for(lambda: fake.wrenches[-1]["wrench"]["force"]["x"] == 0.0, 5)
        n = len(fake.wrenches)
        time.sleep(0.3)
        assert len(fake.wrenches) == n
        assert client.received.get("/MTMR/measured_js", 0) > 10 and client.errors == 0
    finally:
        fake.stop()
        client.stop()
        handle.stop()


def test_client_mode_pushes_into_a_network_device(remote, fake_console):
    network = pytest.importorskip("davinci_sim.devices.network")
    server, remote_ros = remote
    sim = Simulation("psm1_ecm_mtmr")
    sim.add_component(network.NetworkDevice("MTMR/device", watchdog=None))
    handle = ThreadedSimulation(sim, real_time=True).start()
    fake = fake_console(list(handle.snapshot().arms["MTMR"].measured_js.name))
    client = RosClientMode(handle, ClientModeConfig(server.url, mtms=("MTMR",)))
    try:
        client.start(ROS_CONNECT_TIMEOUT)
        assert client.mode == {"MTMR": "device"}

        def device_input():
            return handle.snapshot().extras["MTMR/device"].input

        assert wait_for(lambda: device_input() is not None, 5)
        assert np.allclose(device_input().T_hrsv_tip, fake.T)
        assert wait_for(lambda: abs(device_input().gripper - 0.5) < 1e-9, 5)
        fake.clutch.publish(roslibpy.Message({"buttons": [1]}))
        assert wait_for(lambda: device_input().buttons.get("clutch") is True, 5)
        # the wrench the simulation sends to the device goes to the real MTM
        # (after the device's own safety limits: the rate limit may clamp a step)
        handle.call("MTMR/device", "servo_cf", [0.0, 0.0, 1.5, 0.0, 0.0, 0.0]).result(5)
        assert wait_for(lambda: fake.wrenches, 5)
        sent = handle.snapshot().extras["MTMR/device"].wrench
        assert 0 < sent[2] <= 1.5
        assert fake.wrenches[-1]["wrench"]["force"]["z"] == pytest.approx(sent[2])
    finally:
        fake.stop()
        client.stop()
        handle.stop()


def test_config_is_checked():
    with pytest.raises(ValueError, match="ws://"):
        ClientModeConfig("http://localhost:9090")
    with pytest.raises(ValueError, match="namespace"):
        ClientModeConfig("ws://localhost:9090", namespace="sim")


def test_a_remote_console_teleoperates_the_simulated_psm(
    remote, fake_console, make_server, make_ros
):
    """The whole chain: real MTM pose (remote topics) → client mode → network device →
    simulated teleoperation (enabled through the local console topics) → PSM motion, seen
    on the local bridge's dVRK topics."""
    setup = pytest.importorskip("davinci_sim.console.setup")
    network = pytest.importorskip("davinci_sim.devices.network")
    from davinci_sim.bridge.console_node import ConsoleNode
    from davinci_sim.bridge.dvrk_node import DvrkNode

    remote_server, remote_ros = remote
    sim = Simulation("psm1_ecm_mtmr", keyframe="surgical")
    device = network.NetworkDevice("MTMR/device", watchdog=0.5)
    setup.install_console(sim, devices={"MTMR": device})
    handle = ThreadedSimulation(sim, real_time=True).start()
    local = make_server(nodes=[DvrkNode(handle), ConsoleNode(handle)])
    ros = make_ros(local)
    fake = fake_console(list(handle.snapshot().arms["MTMR"].measured_js.name))
    client = RosClientMode(handle, ClientModeConfig(remote_server.url, mtms=("MTMR",)))
    try:
        client.start(ROS_CONNECT_TIMEOUT)
        assert client.mode == {"MTMR": "device"}
        following, cp, clutch = [], [], []
        roslibpy.Topic(ros, "/MTMR_PSM1/following", "std_msgs/Bool").subscribe(following.append)
        roslibpy.Topic(ros, "/PSM1/measured_cp", "geometry_msgs/PoseStamped").subscribe(cp.append)
        roslibpy.Topic(ros, "/console/clutch", "sensor_msgs/Joy").subscribe(clutch.append)

        def pub(name, type_name, msg):
            roslibpy.Topic(ros, name, type_name).publish(roslibpy.Message(msg))

        time.sleep(0.3)
        pub("/PSM1/state_command", "crtk_msgs/StringStamped", {"string": "enable"})
        pub("/PSM1/state_command", "crtk_msgs/StringStamped", {"string": "home"})
        assert wait_for(lambda: handle.snapshot().arms["PSM1"].operating_state.is_homed, 10)
        pub("/console/teleop/enable", "std_msgs/Bool", {"data": True})
        pub("/console/emulate_operator_present", "sensor_msgs/Joy", {"buttons": [1]})
        assert wait_for(lambda: following and following[-1]["data"], 10), following
        time.sleep(0.3)
        p0 = m.pose_matrix(cp[-1]["pose"])[:3, 3]
        p0_sim = handle.snapshot().arms["PSM1"].measured_cp.T[:3, 3]
        start = fake.T[:3, 3].copy()
        for k in range(1, 51):  # the real MTM moves 2 cm along HRSV x in 0.5 s
            fake.T[:3, 3] = start + [0.02 * k / 50, 0.0, 0.0]
            time.sleep(0.01)

        def moved():
            return m.pose_matrix(cp[-1]["pose"])[:3, 3] - p0

        def state():  # what each part saw, for a failure's message
            s = handle.snapshot()
            device, teleop = s.extras["MTMR/device"], s.extras["MTMR_PSM1"]
            return (f"seen {moved()}, in the simulation "
                    f"{s.arms['PSM1'].measured_cp.T[:3, 3] - p0_sim}; teleop "
                    f"{teleop.current_state} following={teleop.following}; device stale="
                    f"{device.stale} age={device.input_age}; sim t={s.time:.2f}; received "
                    f"{client.received}")  # fmt: skip

        # scale 0.2: 4 mm, along the camera's x (motion in the display = motion in the image);
        # waited for whole: on a busy machine the tool is still on its way when its motion
        # first passes 3 mm
        def arrived():
            d = moved()
            return abs(np.linalg.norm(d) - 0.004) <= 0.001 and d[0] > 0.003

        assert wait_for(arrived, 10), state()
        moved = moved()
        assert abs(np.linalg.norm(moved) - 0.004) <= 0.001 and moved[0] > 0.003
        fake.clutch.publish(roslibpy.Message({"buttons": [1]}))  # the real clutch pedal
        assert wait_for(lambda: clutch and clutch[-1]["buttons"] == [1], 5)
    finally:
        fake.stop()
        client.stop()
        handle.stop()
