"""The dVRK CRTK API over rosbridge with roslibpy (dvrk.md §2)."""

import math
import time
from concurrent.futures import Future

import numpy as np
import pytest
import roslibpy
from bridge_helpers import FAIL_AFTER, enable_and_home, wait_for

from davinci_sim.bridge import dvrk_messages as m
from davinci_sim.bridge.dvrk_node import DvrkNode
from davinci_sim.sim.simulation import Simulation
from davinci_sim.sim.types import OperatingState


def subscribe(ros, name, type_name):
    got = []
    roslibpy.Topic(ros, name, type_name).subscribe(got.append)
    return got


def publish(ros, name, type_name, msg):
    roslibpy.Topic(ros, name, type_name).publish(roslibpy.Message(msg))


def test_topics_types_and_services_of_every_arm(handle, make_server, make_ros):
    server = make_server(handle)
    ros = make_ros(server)
    topics = set(ros.get_topics())
    for arm in ("PSM1", "ECM"):
        for suffix in ("measured_js", "setpoint_js", "measured_cp", "setpoint_cp",
                       "local/measured_cp", "local/setpoint_cp", "measured_cv",
                       "local/measured_cv", "operating_state", "state_command", "error",
                       "warning", "status", "servo_jp", "move_jp", "servo_cp", "move_cp",
                       "hold", "free", "body/servo_cf", "spatial/servo_cf",
                       "body/measured_cf", "body/jacobian", "goal_reached",
                       "trajectory_j/set_ratio", "set_base_frame"):  # fmt: skip
            assert f"/{arm}/{suffix}" in topics, f"/{arm}/{suffix}"
    for suffix in ("jaw/measured_js", "jaw/setpoint_js", "jaw/servo_jp", "jaw/move_jp"):
        assert f"/PSM1/{suffix}" in topics
    for suj in ("SUJ/PSM1", "SUJ/ECM"):
        for suffix in ("measured_js", "measured_cp", "local/measured_cp", "servo_jp",
                       "operating_state", "state_command"):  # fmt: skip
            assert f"/{suj}/{suffix}" in topics
    assert "/tf" in topics
    assert ros.get_topic_type("/PSM1/measured_cp") == "geometry_msgs/msg/PoseStamped"
    assert ros.get_topic_type("/PSM1/state_command") == "crtk_msgs/msg/StringStamped"
    assert ros.get_topic_type("/PSM1/operating_state") == "crtk_msgs/msg/OperatingState"
    services = ros.get_services()
    for s in ("forward_kinematics", "local/forward_kinematics", "inverse_kinematics",
              "operating_state", "crtk_version"):  # fmt: skip
        assert f"/PSM1/{s}" in services
    assert ros.get_service_type("/PSM1/inverse_kinematics") == (
        "crtk_msgs/srv/QueryInverseKinematics"
    )
    v = roslibpy.Service(ros, "/PSM1/crtk_version", "std_srvs/Trigger").call({})
    assert v == {"success": True, "message": "1.1.0"}
    tool = subscribe(ros, "/PSM1/tool_type", "std_msgs/String")
    scope = subscribe(ros, "/ECM/endoscope_type", "std_msgs/String")
    assert wait_for(lambda: tool and scope)  # latched
    assert tool[0]["data"] == "LARGE_NEEDLE_DRIVER:400006"


def test_mtm_gripper_topics(make_server, make_ros):
    from davinci_sim.sim.handle import ThreadedSimulation

    handle = ThreadedSimulation(Simulation("psm1_ecm_mtmr"), real_time=True).start()
    try:
        server = make_server(handle)
        ros = make_ros(server)
        closed = subscribe(ros, "/MTMR/gripper/closed", "std_msgs/Bool")
        grip = subscribe(ros, "/MTMR/gripper/measured_js", "sensor_msgs/JointState")
        assert wait_for(lambda: closed and grip)
        assert grip[-1]["name"] == ["gripper"]
        handle.call("MTMR/gripper", "servo_jp", 0.8).result(5)
        assert wait_for(lambda: closed[-1] == {"data": False}, 5)
        handle.call("MTMR/gripper", "servo_jp", 0.0).result(5)
        assert wait_for(lambda: closed[-1] == {"data": True}, 5)
        assert "/MTMR/lock_orientation" in ros.get_topics()
    finally:
        handle.stop()


@pytest.mark.parametrize("rate", [50.0, 200.0])
def test_measured_js_at_the_configured_rate(handle, make_server, make_ros, rate):
    """The state topics run on a periodic task of period 1/rate (its deadlines are tested
    on a virtual clock in test_bridge_server.py); each message is a new one, stamped with
    the wall clock. The delivered rate is measured in benchmarks/bench_bridge.py."""
    node = DvrkNode(handle, rate=rate, tf_rate=25.0)
    server = make_server(nodes=[node])
    assert sorted(t.period for t in node._tasks) == [1.0 / rate, 1.0 / 25.0]
    ros = make_ros(server)
    before = time.time()
    got = subscribe(ros, "/PSM1/measured_js", "sensor_msgs/JointState")
    assert wait_for(lambda: len(got) >= 5)
    after = time.time()
    msg = got[-1]
    assert msg["name"] == ["yaw", "pitch", "insertion", "roll", "wrist_pitch", "wrist_yaw"]
    assert len(msg["position"]) == len(msg["velocity"]) == len(msg["effort"]) == 6
    stamps = [g["header"]["stamp"]["sec"] + 1e-9 * g["header"]["stamp"]["nanosec"] for g in got]
    assert all(b > a for a, b in zip(stamps, stamps[1:], strict=False))  # no duplicates
    assert before - 1e-3 <= stamps[0] and stamps[4] <= after + 1e-3  # ROS time = wall clock


def test_ros1_dialect_headers(handle, make_server, make_ros):
    server = make_server(handle, ros_version=1)
    ros = make_ros(server)
    got = subscribe(ros, "/PSM1/measured_cp", "geometry_msgs/PoseStamped")
    assert wait_for(lambda: len(got) >= 3)
    headers = [g["header"] for g in got[:3]]
    assert [h["seq"] for h in headers] == [headers[0]["seq"] + i for i in range(3)]
    assert set(headers[0]["stamp"]) == {"secs", "nsecs"}
    assert headers[0]["frame_id"] == "ECM"  # PSM poses are in the camera frame (dvrk.md 1.6)
    assert ros.get_topic_type("/PSM1/measured_cp") == "geometry_msgs/PoseStamped"


def test_an_operating_state_goes_out_after_the_snapshot_of_its_tick(handle, make_server,
                                                                     make_ros):  # fmt: skip
    """An operating-state event newer than the latest snapshot waits for the state topics of
    a snapshot that covers it (a client that sees a move end then reads joints from then);
    one no snapshot covers goes out after EVENT_HOLD_MAX anyway, and the service answers
    the newer of the snapshot and the state the topic published."""
    node = DvrkNode(handle)
    server = make_server(nodes=[node])
    ros = make_ros(server)
    order: list[str] = []  # (the client's callbacks run in arrival order)
    states, joints = [], []
    for name, type_name, got in (("operating_state", "crtk_msgs/OperatingState", states),
                                 ("measured_js", "sensor_msgs/JointState", joints)):  # fmt: skip

        def on(msg, got=got, name=name):
            got.append(msg)
            order.append(name if name == "measured_js" or not msg["is_busy"] else "busy")

        roslibpy.Topic(ros, f"/PSM1/{name}", type_name).subscribe(on)
    service = roslibpy.Service(ros, "/PSM1/operating_state", "crtk_msgs/TriggerOperatingState")

    def reply():
        r = service.call({})["operating_state"]
        return r["state"], r["is_homed"], r["is_busy"]

    def event(state, ahead: float) -> bool:
        """``state`` stamped ``ahead`` s after the latest snapshot, handled on the bridge's
        loop as events are; whether it is held (read in the same loop callback)."""

        def on_loop() -> bool:
            stamped = OperatingState(*state, timestamp=handle.snapshot().time + ahead)
            node._on_event("PSM1", "operating_state", stamped)
            return bool(node.arms["PSM1"].pending)

        done: Future = Future()
        node.loop.call_soon_threadsafe(lambda: done.set_result(on_loop()))
        return done.result(10)

    assert wait_for(lambda: handle.snapshot().time > 0.01 and states and joints)
    # An event of a tick the snapshot does not cover yet (a few ms ahead of it): held, then
    # published once a snapshot passed it, after that snapshot's joints.
    assert event(("DISABLED", False, True), 0.005)
    assert wait_for(lambda: any(s["is_busy"] for s in states))
    assert not node.arms["PSM1"].pending
    assert order[order.index("busy") - 1] == "measured_js"  # the snapshot's joints first
    # An event no snapshot will cover (a clock far ahead): out after the hold, and the
    # service answers it, the newer of the two.
    assert event(("ENABLED", True, False), 1e3)
    assert wait_for(lambda: states[-1]["state"] == "ENABLED")
    assert reply() == ("ENABLED", True, False)


def test_after_a_stall_of_the_bridge_a_move_end_still_follows_its_joints(handle, make_server,
                                                                          make_ros):  # fmt: skip
    """The bridge's loop stalls while the simulation runs on (a busy machine): an event of a
    tick the simulation's latest snapshot covers, but whose joints the clients were not sent
    yet, waits for the state topics of a snapshot that covers it. (It went out at once, ahead
    of them: a script that waited for a move's end read the joints from before the move.)"""
    node = DvrkNode(handle)
    server = make_server(nodes=[node], stamp_clock="sim")
    ros = make_ros(server)
    got: list = []  # (the client's callbacks run in arrival order)
    for name, type_name in (("operating_state", "crtk_msgs/OperatingState"),
                            ("measured_js", "sensor_msgs/JointState")):  # fmt: skip
        roslibpy.Topic(ros, f"/PSM1/{name}", type_name).subscribe(
            lambda msg, name=name: got.append((name, msg)))  # fmt: skip
    assert wait_for(lambda: {n for n, _ in got} == {"operating_state", "measured_js"})

    def on_loop() -> tuple[float, bool]:
        # This loop stalls until the simulation, running on, is 5 ms of simulated time past
        # the states it sent (a fixed 50 ms of wall time was not enough on a loaded machine,
        # where the simulation ran at 0.17x real time).
        deadline = time.monotonic() + FAIL_AFTER
        while handle.snapshot().time < node.state_time + 0.005 and time.monotonic() < deadline:
            time.sleep(0.001)
        t = handle.snapshot().time - 0.002  # (covered by the latest snapshot, not yet sent)
        assert t > node.state_time
        node._on_event("PSM1", "operating_state", OperatingState("DISABLED", False, True, t))
        return t, bool(node.arms["PSM1"].pending)

    done: Future = Future()
    node.loop.call_soon_threadsafe(lambda: done.set_result(on_loop()))
    t_event, held = done.result(10)
    assert held
    assert wait_for(lambda: any(n == "operating_state" and m["is_busy"] for n, m in got))
    i = next(k for k, (n, m) in enumerate(got) if n == "operating_state" and m["is_busy"])
    before = [m for n, m in got[:i] if n == "measured_js"][-1]  # the joints the client holds
    stamp = before["header"]["stamp"]
    assert stamp["sec"] + 1e-9 * stamp["nanosec"] >= t_event - 1e-9


def test_enable_home_and_operating_state(handle, make_server, make_ros):
    server = make_server(handle)
    ros = make_ros(server)
    states = subscribe(ros, "/PSM1/operating_state", "crtk_msgs/OperatingState")
    assert wait_for(lambda: states)  # latched: the current state at once
    assert (states[0]["state"], states[0]["is_homed"]) == ("DISABLED", False)
    status = subscribe(ros, "/PSM1/status", "std_msgs/String")
    time.sleep(0.2)
    publish(ros, "/PSM1/state_command", "crtk_msgs/StringStamped", {"string": "enable"})
    assert wait_for(lambda: states[-1]["state"] == "ENABLED")
    publish(ros, "/PSM1/state_command", "crtk_msgs/StringStamped", {"string": "home"})
    assert wait_for(lambda: states[-1]["is_homed"] and not states[-1]["is_busy"], 10)
    assert any(s["is_busy"] for s in states)  # homing is a motion
    assert any("homed" in s["data"] for s in status)
    service = roslibpy.Service(ros, "/PSM1/operating_state", "crtk_msgs/TriggerOperatingState")
    reply = service.call({})["operating_state"]
    assert (reply["state"], reply["is_homed"], reply["is_busy"]) == ("ENABLED", True, False)
    # an unsupported state command: a warning, no change
    warnings = subscribe(ros, "/PSM1/warning", "std_msgs/String")
    time.sleep(0.2)
    publish(ros, "/PSM1/state_command", "crtk_msgs/StringStamped", {"string": "resume"})
    assert wait_for(lambda: warnings)
    assert "not supported in state ENABLED" in warnings[0]["data"]


def test_move_jp_then_servo_cp_move_the_arm(handle, make_server, make_ros):
    server = make_server(handle)
    ros = make_ros(server)
    js = subscribe(ros, "/PSM1/measured_js", "sensor_msgs/JointState")
    states = subscribe(ros, "/PSM1/operating_state", "crtk_msgs/OperatingState")
    reached = subscribe(ros, "/PSM1/goal_reached", "std_msgs/Bool")
    time.sleep(0.2)
    enable_and_home(handle)
    # The homing's own end reaches the client first (it follows the simulation's by up to a
    # snapshot, more on a loaded machine): subscribed after homing, a test took it for the
    # move's end and read the joints from before the move.
    assert wait_for(lambda: reached and not states[-1]["is_busy"], 10)
    time.sleep(0.2)
    n_states, n_reached = len(states), len(reached)
    goal = [0.2, -0.1, 0.1, 0.3, 0.0, 0.0]
    publish(ros, "/PSM1/move_jp", "sensor_msgs/JointState", {"position": goal})
    assert wait_for(lambda: any(s["is_busy"] for s in states[n_states:]), 2)
    assert wait_for(lambda: len(reached) == n_reached + 1, 10)  # the move's end
    assert not states[-1]["is_busy"] and reached[-1] == {"data": True}
    assert np.allclose(js[-1]["position"], goal, atol=2e-3)
    # servo_cp: 1 cm along the camera's x, in the reference frame of measured_cp
    cp = subscribe(ros, "/PSM1/measured_cp", "geometry_msgs/PoseStamped")
    assert wait_for(lambda: cp)
    T0 = m.pose_matrix(cp[-1]["pose"])
    T = T0.copy()
    T[0, 3] += 0.01
    for _ in range(30):
        publish(ros, "/PSM1/servo_cp", "geometry_msgs/PoseStamped",
                {"header": {"frame_id": "ECM"}, "pose": m.pose(T)})  # fmt: skip
        time.sleep(0.01)
    assert wait_for(
        lambda: np.linalg.norm(m.pose_matrix(cp[-1]["pose"])[:3, 3] - T[:3, 3]) < 5e-4, 3
    )
    # the sim agrees with what was published (once settled: the topic's first sample within
    # 0.5 mm may be on the way through, on a busy machine)
    assert wait_for(
        lambda: np.allclose(handle.snapshot().arms["PSM1"].measured_cp.T[:3, 3], T[:3, 3],
                            atol=5e-4), 3
    ), handle.snapshot().arms["PSM1"].measured_cp.T[:3, 3] - T[:3, 3]  # fmt: skip


def test_jaw_and_gripper_wrench_topics(handle, make_server, make_ros):
    server = make_server(handle)
    ros = make_ros(server)
    enable_and_home(handle)
    jaw = subscribe(ros, "/PSM1/jaw/measured_js", "sensor_msgs/JointState")
    publish(ros, "/PSM1/jaw/move_jp", "sensor_msgs/JointState", {"position": [math.radians(50)]})
    assert wait_for(lambda: jaw and abs(jaw[-1]["position"][0] - math.radians(50)) < 0.02, 5)
    assert jaw[-1]["name"] == ["jaw"]
    cf = subscribe(ros, "/PSM1/body/measured_cf", "geometry_msgs/WrenchStamped")
    J = subscribe(ros, "/PSM1/body/jacobian", "std_msgs/Float64MultiArray")
    ratio = subscribe(ros, "/PSM1/trajectory_j/ratio", "std_msgs/Float64")
    publish(ros, "/PSM1/trajectory_j/set_ratio", "std_msgs/Float64", {"data": 0.5})
    assert wait_for(lambda: cf and J and ratio and ratio[-1]["data"] == 0.5, 5)
    assert [d["size"] for d in J[-1]["layout"]["dim"]] == [6, 6]
    assert len(J[-1]["data"]) == 36
    assert set(cf[-1]["wrench"]) == {"force", "torque"}


def test_fk_and_ik_services(handle, make_server, make_ros):
    server = make_server(handle)
    ros = make_ros(server)
    fk = roslibpy.Service(ros, "/PSM1/forward_kinematics", "crtk_msgs/QueryForwardKinematics")
    ik = roslibpy.Service(ros, "/PSM1/inverse_kinematics", "crtk_msgs/QueryInverseKinematics")
    q = [0.1, -0.2, 0.12, 0.3, 0.2, -0.1]
    r = fk.call({"jp": q})
    assert r["result"] is True
    T = m.pose_matrix(r["cp"])
    pose, _ = handle.call("PSM1", "forward_kinematics", np.array(q)).result(5)
    assert np.allclose(T, pose.T, atol=1e-9)  # the arm's own FK, with its base frame
    r = ik.call({"cp": m.pose(T), "jp": [0.0, 0.0, 0.12, 0.0, 0.0, 0.0]})
    assert r["result"] is True and np.allclose(r["jp"], q, atol=1e-5)
    local = roslibpy.Service(ros, "/PSM1/local/forward_kinematics",
                             "crtk_msgs/QueryForwardKinematics")  # fmt: skip
    r = local.call({"jp": [0.0, 0.0, 0.12]})  # 3 joints: the frame after the insertion
    assert r["result"] is True
    r = ik.call({"cp": {"position": {"x": 5.0, "y": 0, "z": 0}}, "jp": [0.0] * 6})
    assert r["result"] is False and r["message"]
    with pytest.raises(roslibpy.core.ServiceException, match="jp is empty"):
        fk.call({"jp": []})


def test_local_measured_cv_is_the_body_twist(handle, make_server, make_ros):
    """local/measured_cv (built from the snapshot) equals the arm's own body twist."""
    enable_and_home(handle)
    handle.call("PSM1", "move_jp", [0.5, 0.3, 0.15, 0.5, 0.3, 0.3]).result(5)
    time.sleep(0.3)
    snap = handle.snapshot().arms["PSM1"]
    tw = m.local_twist(snap.measured_cv, snap.measured_cp)
    assert np.linalg.norm(snap.measured_cv.twist) > 1e-3  # it is moving
    sim = Simulation("psm1")
    arm = sim.arms["PSM1"]
    sim.data.qpos[arm.qpos_addresses] = snap.measured_js.position
    sim.data.qvel[arm.dof_addresses] = snap.measured_js.velocity
    expected = arm.local.measured_cv().twist
    # same joints and rates: the measured_cv of that sim rotated into the tip frame
    ref = m.local_twist(arm.measured_cv(), arm.measured_cp())
    assert np.allclose(ref.twist, expected, atol=1e-9)
    assert np.allclose(tw.twist, expected, atol=1e-9)  # what the bridge publishes


def test_tf_and_set_base_frame(handle, make_server, make_ros):
    server = make_server(handle)
    ros = make_ros(server)
    tf = subscribe(ros, "/tf", "tf2_msgs/TFMessage")
    assert wait_for(lambda: tf)
    frames = {(t["header"]["frame_id"], t["child_frame_id"]) for t in tf[-1]["transforms"]}
    assert ("ECM", "PSM1") in frames and ("Cart", "ECM") in frames
    enable_and_home(handle)
    cp = subscribe(ros, "/PSM1/measured_cp", "geometry_msgs/PoseStamped")
    publish(ros, "/PSM1/set_base_frame", "geometry_msgs/PoseStamped",
            {"header": {"frame_id": "world"}, "pose": m.pose(np.eye(4))})  # fmt: skip
    assert wait_for(lambda: cp and cp[-1]["header"]["frame_id"] == "world")
    local = handle.snapshot().arms["PSM1"].local_measured_cp.T
    assert np.allclose(m.pose_matrix(cp[-1]["pose"])[:3, 3], local[:3, 3], atol=1e-4)


def test_quaternion_conversions_round_trip():
    rng = np.random.default_rng(0)
    for _ in range(200):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        R = m.matrix_from_quaternion(*q)
        assert np.allclose(R @ R.T, np.eye(3), atol=1e-12) and np.linalg.det(R) > 0
        assert np.allclose(m.matrix_from_quaternion(*m.quaternion_from_matrix(R)), R, atol=1e-12)
    for R in (np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])):
        assert np.allclose(m.matrix_from_quaternion(*m.quaternion_from_matrix(R)), R)
    with pytest.raises(m.CommandError, match="unit quaternion"):
        m.matrix_from_quaternion(0, 0, 0, 0.5)


def test_ordered_joint_names():
    names = ("a", "b", "c")
    assert m.ordered([1, 2, 3], [], names, "p") == [1, 2, 3]
    assert m.ordered([3, 1, 2], ["c", "a", "b"], names, "p") == [1, 2, 3]
    with pytest.raises(m.CommandError, match="do not match"):
        m.ordered([1, 2, 3], ["a", "b", "x"], names, "p")
    with pytest.raises(m.CommandError, match="2 names for 3 values"):
        m.ordered([1, 2, 3], ["a", "b"], names, "p")


def test_node_options_are_checked(handle):
    with pytest.raises(ValueError, match="rate"):
        DvrkNode(handle, rate=5000)
    with pytest.raises(ValueError, match="tf_rate"):
        DvrkNode(handle, tf_rate=0)


def test_setup_joints_carry_the_dvrk_names(handle, make_server, make_ros):
    """/SUJ/<arm>/measured_js names SUJ_<arm>_J0…J5 (dvrk.md 1.6, section 6); a servo_jp
    naming them moves the joint, one with other names is refused."""
    server = make_server(handle)
    ros = make_ros(server)
    got = {arm: subscribe(ros, f"/SUJ/{arm}/measured_js", "sensor_msgs/JointState")
           for arm in ("ECM", "PSM1")}  # fmt: skip
    assert wait_for(lambda: all(got.values()), 10)
    for arm, msgs in got.items():
        assert msgs[-1]["name"] == [f"SUJ_{arm}_J{i}" for i in range(6)]
    q = list(msgs[-1]["position"])
    names = [f"SUJ_PSM1_J{i}" for i in range(6)]
    goal = [q[0] + 0.01, *q[1:]]
    errors = subscribe(ros, "/SUJ/PSM1/error", "std_msgs/String")
    publish(ros, "/SUJ/PSM1/servo_jp", "sensor_msgs/JointState",
            {"name": [f"J{i}" for i in range(6)], "position": goal})  # fmt: skip
    assert wait_for(lambda: errors, 5)
    assert "SUJ_PSM1_J0" in errors[-1]["data"]
    publish(ros, "/SUJ/PSM1/servo_jp", "sensor_msgs/JointState",
            {"name": names[::-1], "position": goal[::-1]})  # fmt: skip
    assert wait_for(
        lambda: abs(handle.snapshot().arms["SUJ/PSM1"].setpoint_js.position[0] - goal[0]) < 1e-12,
        5,
    )


def test_mtm_servo_ci_topic(make_server, make_ros):
    """``/MTMR/servo_ci`` (``crtk_msgs/CartesianImpedance``) sets the MTM's impedance: the
    quaternions as rotations, the half-plane gains per axis (dvrk_mtm_cartesian_impedance)."""
    from davinci_sim.sim.handle import ThreadedSimulation

    handle = ThreadedSimulation(Simulation("psm1_ecm_mtmr"), real_time=False).start()
    try:
        enable_and_home(handle, "MTMR", timeout=30)
        server = make_server(handle)
        ros = make_ros(server)
        zero = {"x": 0.0, "y": 0.0, "z": 0.0}
        half = {"p": zero, "d": zero, "bias": zero, "deadband": zero}
        spring = {**half, "p": {**zero, "z": -200.0}, "d": {**zero, "z": -5.0}}
        msg = {
            "force_orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
            "torque_orientation": {"x": 0.0, "y": 0.0, "z": 1.0, "w": 0.0},  # 180° about z
            "force_position": {"x": 0.01, "y": 0.02, "z": 0.03},
            "position_positive": spring, "position_negative": spring,
            "orientation_positive": half, "orientation_negative": half,
        }  # fmt: skip
        topic = roslibpy.Topic(ros, "/MTMR/servo_ci", "crtk_msgs/CartesianImpedance")
        topic.publish(roslibpy.Message(msg))
        assert wait_for(lambda: handle.call("MTMR", "impedance").result(5) is not None, 5)
        g = handle.call("MTMR", "impedance").result(5)
        assert np.allclose(g.force_position, [0.01, 0.02, 0.03])
        assert np.allclose(g.position_negative.p, [0, 0, -200.0])
        assert np.allclose(g.torque_orientation, np.diag([-1.0, -1.0, 1.0]))
    finally:
        handle.stop()
