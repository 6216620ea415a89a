"""The robot for Foxglove/RViz over rosbridge (bridge/robot_node.py): ``/robot_description``
latched and as a parameter, ``/tf_static`` + ``/tf`` a connected tree rooted at ``world``
covering every URDF link (with the dVRK's ``measured_cp`` frames in it), and
``/joint_states`` whose values put through the URDF's FK give that same ``/tf``."""

import io

import numpy as np
import pytest
import roslibpy
import yourdfpy
from bridge_helpers import ros_client, wait_for

from davinci_sim.bridge import dvrk_messages as m
from davinci_sim.bridge.dvrk_node import DvrkNode
from davinci_sim.bridge.robot_node import RobotNode
from davinci_sim.kinematics.arms import load_arm
from davinci_sim.sim.handle import ThreadedSimulation
from davinci_sim.sim.runtime.render import QposProbe
from davinci_sim.sim.simulation import Simulation


@pytest.fixture(scope="module")
def robot_handle():
    """PSM1 + ECM + their SUJ, the snapshots carrying qpos (as ``serve`` builds them)."""
    sim = Simulation("psm1")
    sim.add_component(QposProbe(sim))
    h = ThreadedSimulation(sim, real_time=True, snapshot_period=0.001).start()
    yield h
    h.stop()


@pytest.fixture(scope="module", params=[1, 2], ids=["ros1", "ros2"])
def robot_server(robot_handle, request):
    """The server in both dialects (ROS 1 and ROS 2 message and type names)."""
    from davinci_sim.bridge import BridgeConfig, RosbridgeServer

    sim_model = robot_handle.sim.model
    nodes = [DvrkNode(robot_handle, tf_rate=50.0), RobotNode(robot_handle, sim_model, rate=50.0)]
    server = RosbridgeServer(BridgeConfig(port=0, ros_version=request.param), nodes=nodes).start()
    yield server
    server.stop()


@pytest.fixture(scope="module")
def ros(robot_server):
    client = ros_client(robot_server.port)
    yield client
    client.close()


def subscribe(ros, name, type_name):
    got = []
    roslibpy.Topic(ros, name, type_name).subscribe(got.append)
    return got


def _pose(t: dict) -> np.ndarray:
    tr, q = t["transform"]["translation"], t["transform"]["rotation"]
    T = np.eye(4)
    T[:3, :3] = m.matrix_from_quaternion(q["x"], q["y"], q["z"], q["w"])
    T[:3, 3] = [tr["x"], tr["y"], tr["z"]]
    return T


def _stamp(t: dict) -> tuple[int, int]:
    s = t["header"]["stamp"]
    return s.get("sec", s.get("secs")), s.get("nanosec", s.get("nsecs"))


@pytest.fixture(scope="module")
def description(ros):
    got = subscribe(ros, "/robot_description", "std_msgs/String")
    assert wait_for(lambda: got), "the latched description did not come on subscribe"
    return got[0]["data"]


@pytest.fixture(scope="module")
def parsed(description):
    return yourdfpy.URDF.load(io.BytesIO(description.encode()), load_meshes=False,
                              build_collision_scene_graph=False)  # fmt: skip


def test_description_is_latched_and_a_parameter(ros, description, parsed):
    assert parsed.base_link == "world"
    assert {"PSM1_yaw", "PSM1_jaw_1", "SUJ_PSM1_J0", "ECM_insertion"} <= set(
        parsed.actuated_joint_names
    )
    value = roslibpy.Param(ros, "/robot_description").get(timeout=5)
    assert value == description
    # a second, later subscriber gets it too (latched)
    again = subscribe(ros, "/robot_description", "std_msgs/String")
    assert wait_for(lambda: again) and again[0]["data"] == description
    # each arm alone, its joints named as its measured_js (the dVRK's per-arm launch files)
    arm = subscribe(ros, "/PSM1/robot_description", "std_msgs/String")
    js = subscribe(ros, "/PSM1/measured_js", "sensor_msgs/JointState")
    assert wait_for(lambda: arm and js)
    psm1 = yourdfpy.URDF.load(io.BytesIO(arm[0]["data"].encode()), load_meshes=False)
    assert set(js[-1]["name"]) <= set(psm1.actuated_joint_names)
    assert set(psm1.link_map) < set(parsed.link_map)  # the same frames
    assert roslibpy.Param(ros, "/SUJ/PSM1/robot_description").get(timeout=5).startswith("<?xml")


def test_tf_tree_is_connected_complete_and_matches_the_urdf(ros, parsed, robot_handle):
    static = subscribe(ros, "/tf_static", "tf2_msgs/TFMessage")
    tf = subscribe(ros, "/tf", "tf2_msgs/TFMessage")
    states = subscribe(ros, "/joint_states", "sensor_msgs/JointState")
    # a joint_states message and the robot's /tf message of the same stamp
    robot_links = set(parsed.link_map)

    def matched():
        for js in reversed(states[-5:]):
            for msg in reversed(tf[-10:]):
                ts = msg["transforms"]
                if ts and ts[0]["child_frame_id"] in robot_links and _stamp(ts[0]) == _stamp(js):
                    return js, msg
        return None

    assert wait_for(lambda: static and matched())
    assert wait_for(lambda: any(t["child_frame_id"] == "PSM1"
                                for msg in tf[-10:] for t in msg["transforms"]))  # fmt: skip
    js, robot_tf = matched()
    dvrk_tf = next(msg for msg in reversed(tf) if msg["transforms"][0]["child_frame_id"]
                   not in robot_links)  # fmt: skip
    edges = static[-1]["transforms"] + robot_tf["transforms"] + dvrk_tf["transforms"]
    parent = {}
    for t in edges:
        child = t["child_frame_id"]
        assert child not in parent, f"{child} has two parents"
        parent[child] = (t["header"]["frame_id"], _pose(t))
    frames = set(parent) | {p for p, _ in parent.values()}
    roots = frames - set(parent)
    assert roots == {"world"}
    # every URDF link is a frame; the dVRK's measured_cp frames and the images' frames too
    assert robot_links <= frames
    assert {"PSM1", "ECM", "SUJ/PSM1", "SUJ/ECM", "ECM_left", "ECM_right"} <= frames

    def world_pose(frame):
        T = np.eye(4)
        while frame != "world":
            p, T_p = parent[frame]
            T = T_p @ T
            frame = p
        return T

    # /joint_states: every moving joint of the URDF; its FK is the published tree
    assert set(js["name"]) == set(parsed.actuated_joint_names)
    values = dict(zip(js["name"], js["position"], strict=True))
    parsed.update_cfg(values)
    for link in robot_links:
        np.testing.assert_allclose(world_pose(link), parsed.get_transform(link, "world"),
                                   atol=1e-8, err_msg=link)  # fmt: skip
        # (10 nm: a chain of ~12 transforms whose quaternions went through JSON)
    # the joint values are the simulation's: measured_js (encoder noise aside)
    arm = robot_handle.snapshot().arms["PSM1"]
    ours = [values[f"PSM1_{n}"] for n in arm.measured_js.name]
    assert np.allclose(ours, arm.measured_js.position, atol=1e-3)
    # measured_cp's frames sit where the URDF's tool tip is: Cart and ECM are the same
    # frames in both (the arms are idle, so the two messages, a few ms apart, agree)
    T_tip = parsed.get_transform("PSM1_wrist_yaw_link", "world") @ load_arm("PSM1").chain.T_last_tip
    np.testing.assert_allclose(world_pose("PSM1"), T_tip, atol=1e-6)


def test_no_qpos_in_the_snapshots_is_said_once_and_publishes_nothing(caplog):
    sim = Simulation("psm1")
    h = ThreadedSimulation(sim, real_time=True, snapshot_period=0.001).start()
    try:
        from davinci_sim.bridge import BridgeConfig, RosbridgeServer

        node = RobotNode(h, sim.model, rate=100.0)
        server = RosbridgeServer(BridgeConfig(port=0), nodes=[node]).start()
        client = ros_client(server.port)
        try:
            tf = subscribe(client, "/tf", "tf2_msgs/TFMessage")
            description = subscribe(client, "/robot_description", "std_msgs/String")
            assert wait_for(lambda: description)  # the description does not need qpos
            assert wait_for(lambda: "carry no qpos" in caplog.text)
            assert not tf and node.published == 0
            assert caplog.text.count("carry no qpos") == 1
        finally:
            client.close()
            server.stop()
    finally:
        h.stop()
    with pytest.raises(ValueError, match="rate"):
        RobotNode(h, sim.model, rate=0)


def test_serve_publishes_the_robot(make_ros):
    """``davinci-sim serve`` (no images) runs the robot node with qpos in its snapshots."""
    from bridge_helpers import serving

    from davinci_sim.bridge.app import ServeOptions
    from davinci_sim.bridge.rosbridge.config import BridgeConfig

    options = ServeOptions(scene="psm1", images="none", bridge=BridgeConfig(port=0))
    with serving(options) as server:
        ros = make_ros(server)
        description = subscribe(ros, "/robot_description", "std_msgs/String")
        states = subscribe(ros, "/joint_states", "sensor_msgs/JointState")
        assert wait_for(lambda: description and states, 10)
        assert "PSM1_wrist_yaw" in description[0]["data"]
        assert "PSM1_wrist_yaw" in states[-1]["name"]
