"""Client mode publishes the robot on the remote as ``robot_state_publisher`` would
(bridge/client_robot.py), for RViz through a real rosbridge: the built-in server stands in
for the remote, a roslibpy client on it plays RViz. A ROS 2 remote with namespace ``/sim``
(frames prefixed ``sim/``) and a ROS 1 remote with namespace ``/`` (plain names, and the
``/robot_description`` parameter)."""

import io
import logging

import numpy as np
import pytest
import roslibpy
import yourdfpy
from bridge_helpers import ROS_CONNECT_TIMEOUT, enable_and_home, ros_client, wait_for

from davinci_sim.bridge import BridgeConfig, RosbridgeServer
from davinci_sim.bridge import dvrk_messages as m
from davinci_sim.bridge.client_mode import ClientModeConfig, RosClientMode
from davinci_sim.bridge.client_robot import frame_prefix
from davinci_sim.bridge.robot_node import RobotNode
from davinci_sim.sim.handle import ThreadedSimulation
from davinci_sim.sim.runtime.render import QposProbe
from davinci_sim.sim.simulation import Simulation


@pytest.fixture(scope="module")
def robot_handle():
    """PSM1 + ECM + their SUJ, the snapshots carrying qpos (as ``serve`` builds them); PSM1
    enabled and homed once for the module (the tests move it)."""
    sim = Simulation("psm1")
    sim.add_component(QposProbe(sim))
    h = ThreadedSimulation(sim, real_time=True, snapshot_period=0.001).start()
    enable_and_home(h, "PSM1")
    yield h
    h.stop()


@pytest.fixture(scope="module", params=[(2, "/sim"), (1, "/")], ids=["ros2-sim", "ros1-plain"])
def remote(robot_handle, request):
    """The remote rosbridge (a bare built-in server), the client mode connected to it, and
    a roslibpy client on the remote (RViz's side)."""
    ros_version, namespace = request.param
    server = RosbridgeServer(BridgeConfig(port=0, ros_version=ros_version)).start()
    config = ClientModeConfig(server.url, namespace=namespace, mtms=(), ros_version=ros_version)
    client = RosClientMode(robot_handle, config).start(ROS_CONNECT_TIMEOUT)
    viewer = ros_client(server.port)
    yield client, server, viewer
    viewer.close()
    client.stop()
    server.stop()


def subscribe(ros, name, type_name):
    got = []
    roslibpy.Topic(ros, name, type_name).subscribe(got.append)
    return got


def _pose(t):
    tr, q = t["transform"]["translation"], t["transform"]["rotation"]
    T = np.eye(4)
    T[:3, :3] = m.matrix_from_quaternion(q["x"], q["y"], q["z"], q["w"])
    T[:3, 3] = [tr["x"], tr["y"], tr["z"]]
    return T


def _stamp(msg):
    s = msg["header"]["stamp"]
    return s.get("sec", s.get("secs")), s.get("nanosec", s.get("nsecs"))


def _urdf(text):
    return yourdfpy.URDF.load(io.BytesIO(text.encode()), load_meshes=False,
                              build_collision_scene_graph=False)  # fmt: skip


def test_frame_prefix():
    assert frame_prefix("/") == "" and frame_prefix("/sim") == "sim/"
    assert frame_prefix("/lab/sim") == "lab/sim/"


def test_a_late_subscriber_gets_the_description(remote, robot_handle):
    """Subscribed after client mode published it (latched on the remote): the URDF of the
    simulation's model, the same document the built-in server serves; each simulated arm's
    own description too; on ROS 1 also the parameter."""
    client, server, viewer = remote
    ns = client.prefix
    expected = RobotNode(robot_handle, robot_handle.sim.model).urdf
    first = subscribe(viewer, f"{ns}/robot_description", "std_msgs/String")
    assert wait_for(lambda: first, 10), "the latched description did not come on subscribe"
    assert first[0]["data"] == expected
    later = subscribe(viewer, f"{ns}/robot_description", "std_msgs/String")  # another viewer
    assert wait_for(lambda: later, 10) and later[0]["data"] == expected
    parsed = _urdf(expected)
    assert parsed.base_link == "world"
    assert {"PSM1_yaw", "PSM1_jaw_1", "SUJ_PSM1_J0", "ECM_insertion"} <= set(
        parsed.actuated_joint_names
    )
    arm = subscribe(viewer, f"{ns}/PSM1/robot_description", "std_msgs/String")
    assert wait_for(lambda: arm, 10)
    psm1 = _urdf(arm[0]["data"])
    names = robot_handle.snapshot().arms["PSM1"].measured_js.name
    assert set(names) <= set(psm1.actuated_joint_names)  # named as PSM1/measured_js
    if client.config.ros_version == 1:
        assert roslibpy.Param(viewer, "/robot_description").get(timeout=5) == expected
        assert roslibpy.Param(viewer, "/PSM1/robot_description").get(timeout=5) == arm[0]["data"]
    # every robot topic was planned (echo safety) and none was taken as input
    planned = {f"{ns}/robot_description", f"{ns}/PSM1/robot_description", "/tf",
               "/tf_static", f"{ns}/joint_states"}  # fmt: skip
    assert planned <= client.published_names
    assert not set(client._plan) & client.published_names


def _tree(static, tf_msg):
    parent = {}
    for t in static["transforms"] + tf_msg["transforms"]:
        child = t["child_frame_id"]
        assert child not in parent, f"{child} has two parents"
        parent[child] = (t["header"]["frame_id"], _pose(t))
    return parent


def _world_pose(parent, frame):
    T = np.eye(4)
    while frame != "world":
        p, T_p = parent[frame]
        T = T_p @ T
        frame = p
    return T


def _pair(states, tf):
    """The latest joint_states and /tf message of the same stamp (one tick)."""
    for js in reversed(states[-5:]):
        for msg in reversed(tf[-10:]):
            if msg["transforms"] and _stamp(msg["transforms"][0]) == _stamp(js):
                return js, msg
    return None


def test_tf_tree_is_connected_complete_and_moves_with_the_arm(remote, robot_handle):
    """``/tf_static`` + ``/tf``: one tree rooted at ``world`` with every URDF link (prefixed
    with the namespace's tf prefix), whose transforms are the URDF's FK at the
    ``joint_states`` of the same stamp; those follow the simulated PSM1 when it moves."""
    client, server, viewer = remote
    ns, prefix = client.prefix, client.robot.frame_prefix
    parsed = _urdf(client.robot.urdfs[f"{ns}/robot_description"])
    static = subscribe(viewer, "/tf_static", "tf2_msgs/TFMessage")
    tf = subscribe(viewer, "/tf", "tf2_msgs/TFMessage")
    states = subscribe(viewer, f"{ns}/joint_states", "sensor_msgs/JointState")
    assert wait_for(lambda: static and _pair(states, tf), 10)

    def check(js, tf_msg):
        parent = _tree(static[-1], tf_msg)
        frames = set(parent) | {p for p, _ in parent.values()}
        assert frames - set(parent) == {"world"}  # connected, one root
        links = {prefix + link for link in parsed.link_map}
        assert links <= frames  # complete
        assert set(js["name"]) == set(parsed.actuated_joint_names)
        parsed.update_cfg(dict(zip(js["name"], js["position"], strict=True)))
        for link in parsed.link_map:
            np.testing.assert_allclose(_world_pose(parent, prefix + link),
                                       parsed.get_transform(link, "world"), atol=1e-7,
                                       err_msg=link)  # fmt: skip
            # (100 nm: measured ~1e-11 m at home and 1e-9 to 1.75e-8 m after PSM1's move,
            # a chain of ~12 transforms through quaternions in JSON and the URDF's rpy; a /tf
            # and joint_states of different ticks would differ by µm)
        return dict(zip(js["name"], js["position"], strict=True))

    check(*_pair(states, tf))
    # move PSM1: the remote's joint_states (and the tree, through the FK) follow
    arm = robot_handle.snapshot().arms["PSM1"]
    goal = np.array(arm.setpoint_js.position, dtype=float)
    goal[0] = -0.2 if goal[0] > 0 else 0.2  # (another goal for each remote of the module)
    robot_handle.call("PSM1", "move_jp", goal).result(5)
    names = [f"PSM1_{n}" for n in arm.measured_js.name]

    def at_goal():
        pair = _pair(states, tf)
        if pair is None:
            return False
        values = dict(zip(pair[0]["name"], pair[0]["position"], strict=True))
        return np.allclose([values[n] for n in names], goal, atol=2e-3)

    assert wait_for(at_goal, 10), "joint_states did not follow the simulated PSM1"
    check(*_pair(states, tf))

    def as_simulated():
        # (the latest pair against the simulation now: the move's last millimetres may be
        # between them on a busy machine, so wait for the two to meet)
        pair = _pair(states, tf)
        values = dict(zip(pair[0]["name"], pair[0]["position"], strict=True))
        now = robot_handle.snapshot().arms["PSM1"].measured_js.position
        return np.allclose([values[n] for n in names], now, atol=2e-3)

    assert wait_for(as_simulated, 10), "joint_states are not the simulated PSM1's"
    assert client.errors == 0 and client.robot.published > 0


def test_no_robot_description_publishes_none_of_it(make_server, make_ros, robot_handle):
    """``robot=False``: the arms' states go out, the robot's topics do not exist."""
    server = make_server()
    config = ClientModeConfig(server.url, mtms=(), robot=False)
    client = RosClientMode(robot_handle, config)
    assert client.robot is None and "/tf" not in client.published_names
    viewer = make_ros(server)
    js = subscribe(viewer, "/sim/PSM1/measured_js", "sensor_msgs/JointState")
    try:
        client.start(ROS_CONNECT_TIMEOUT)
        assert wait_for(lambda: len(js) > 2, 10)
        topics = server.call(lambda: set(server.bridge.topics))
        assert not {"/sim/robot_description", "/tf_static", "/sim/joint_states"} & topics
    finally:
        client.stop()


def test_a_remote_that_refuses_the_parameter_gets_a_warning(make_server, robot_handle, caplog):
    """A ROS 1 remote without ``/rosapi/set_param``: a clear warning, the topic still
    carries the description."""
    server = make_server(ros_version=1)
    server.call(lambda: server.bridge.services.pop("/rosapi/set_param"))
    config = ClientModeConfig(server.url, namespace="/", mtms=(), ros_version=1)
    with caplog.at_level(logging.WARNING, "davinci_sim.bridge.client"):
        client = RosClientMode(robot_handle, config).start(ROS_CONNECT_TIMEOUT)
    try:
        assert "refused the robot_description parameters" in caplog.text
        assert "/robot_description" in server.call(lambda: set(server.bridge.topics))
    finally:
        client.stop()


def test_the_model_is_needed_and_serve_snapshots_carry_qpos(robot_handle):
    from davinci_sim.bridge.app import ServeOptions, serve_description

    class Remote:  # a handle without an in-process simulation (e.g. the process runner's)
        def snapshot(self):
            return robot_handle.snapshot()

    with pytest.raises(ValueError, match="model"):
        RosClientMode(Remote(), ClientModeConfig("ws://127.0.0.1:9", mtms=()))
    RosClientMode(Remote(), ClientModeConfig("ws://127.0.0.1:9", mtms=(), robot=False))
    with pytest.raises(ValueError, match="tf_rate"):
        ClientModeConfig("ws://127.0.0.1:9", tf_rate=0)
    client_only = ServeOptions(scene="psm1", images="none", server=False,
                               ros_connect="ws://127.0.0.1:9")  # fmt: skip
    assert serve_description(client_only).publish_qpos
    off = ServeOptions(scene="psm1", images="none", server=False, ros_connect="ws://h:9",
                       robot_description=False)  # fmt: skip
    assert not serve_description(off).publish_qpos


def test_serve_in_client_mode_publishes_the_robot(make_server, make_ros):
    """``davinci-sim serve --ros-connect URL`` (namespace ``/sim``): the remote gets the
    description of the system's model, ``sim/``-prefixed frames and the joint states."""
    from bridge_helpers import serving

    from davinci_sim.bridge.app import ServeOptions

    remote_server = make_server()
    options = ServeOptions(scene="psm1", images="none", ros_connect=remote_server.url,
                           ros_connect_timeout=ROS_CONNECT_TIMEOUT,
                           bridge=BridgeConfig(port=0))  # fmt: skip
    with serving(options):
        viewer = make_ros(remote_server)
        description = subscribe(viewer, "/sim/robot_description", "std_msgs/String")
        states = subscribe(viewer, "/sim/joint_states", "sensor_msgs/JointState")
        tf = subscribe(viewer, "/tf", "tf2_msgs/TFMessage")
        assert wait_for(lambda: description and states and tf, 15)
        assert "PSM1_wrist_yaw" in description[0]["data"]
        assert "PSM1_wrist_yaw" in states[-1]["name"]
        frames = {t["child_frame_id"] for t in tf[-1]["transforms"]}
        assert "sim/PSM1_wrist_yaw_link" in frames
