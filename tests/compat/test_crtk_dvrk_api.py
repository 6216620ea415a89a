"""The crtk/dvrk compatibility API against a running simulation, over both transports: the
in-process bridge (no socket) and the rosbridge server (a websocket). One simulation serves
both; every test runs once per transport and checks what the API returns against the
simulator's own state (its snapshots)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from transports import FAIL_AFTER

from davinci_sim.bridge.rosbridge.config import BridgeConfig
from davinci_sim.bridge.rosbridge.server import RosbridgeServer
from davinci_sim.compat import dvrk_api as dvrk
from davinci_sim.compat import kdl as PyKDL
from davinci_sim.compat import ral as ral_module
from davinci_sim.compat.crtk_utils import joystick_button
from davinci_sim.compat.inprocess import InProcessBridge, dvrk_nodes
from davinci_sim.compat.ral import ral as make_ral
from davinci_sim.compat.run import echo_arm_messages
from davinci_sim.compat.transport import RosbridgeClient, WebSocketConnection
from davinci_sim.system import ConsoleDescription, SystemDescription, build_system


@pytest.fixture(scope="module")
def system():
    description = SystemDescription(scene="psm1_ecm_mtmr", keyframe="home",
                                    console=ConsoleDescription(), runner="thread",
                                    snapshot_period=0.01)  # fmt: skip
    system = build_system(description, start=True)
    servers = [
        InProcessBridge(system.handle).start(),
        RosbridgeServer(BridgeConfig(port=0), nodes=dvrk_nodes(system.handle)).start(),
    ]
    yield system, servers
    system.stop()
    for s in servers:
        s.stop()


@pytest.fixture(scope="module", params=["in-process", "rosbridge"])
def ral(request, system):
    _, (in_process, server) = system
    if request.param == "in-process":
        client = RosbridgeClient(in_process.connect())
    else:
        client = RosbridgeClient(WebSocketConnection(server.url))
    ral_module.set_client(client)
    yield make_ral(f"test_{request.param}")
    ral_module.set_client(None)
    client.close()


@pytest.fixture(scope="module")
def psm(ral):
    psm = dvrk.psm(ral, "PSM1")
    psm.check_connections(10)
    assert psm.enable(10) is True
    assert psm.home(30) is True
    return psm


def snap(system):
    return system[0].handle.snapshot()


def now(system, target, method):
    """The simulator's value now (asked from its loop; a snapshot may be 10 ms old)."""
    return system[0].handle.call(target, method).result(5.0)


def settle(seconds=0.05):
    time.sleep(seconds)


def test_home_and_states_match_the_simulator(system, psm):
    assert psm.operating_state() == "ENABLED" and psm.is_homed() and psm.is_enabled()
    assert psm.enable(1) is True and psm.home(1) is True  # already there: True at once
    settle(0.1)
    p, v, e, t = psm.measured_js()
    assert isinstance(p, np.ndarray) and p.shape == (6,) and v.shape == (6,) and e.shape == (6,)
    assert t == pytest.approx(time.time(), abs=5.0)  # stamped with the wall clock
    arm = snap(system).arms["PSM1"]
    assert np.allclose(psm.measured_jp()[0], arm.measured_js.position, atol=1e-3)
    assert np.allclose(psm.setpoint_jp()[0], arm.setpoint_js.position, atol=1e-3)
    cp, _ = psm.measured_cp()
    assert isinstance(cp, PyKDL.Frame)
    assert np.allclose(cp.array, arm.measured_cp.T, atol=1e-3)
    local, _ = psm.local.measured_cp()
    assert np.allclose(local.array, arm.local_measured_cp.T, atol=1e-3)
    assert psm.measured_cv()[0].shape == (6,)
    jaw, _ = psm.jaw.measured_jp()
    assert jaw.shape == (1,)
    J, _ = psm.body.jacobian()
    assert J.shape == (6, 6)
    fk = psm.forward_kinematics(psm.measured_jp()[0])
    assert np.allclose(fk.array, arm.measured_cp.T, atol=1e-3)


def test_move_jp_and_move_jr_wait_until_the_goal(system, psm):
    goal = np.copy(psm.setpoint_jp()[0])
    goal[0] += 0.15
    handle = psm.move_jp(goal)
    assert handle.is_busy() is True  # nothing newer than the command yet
    assert handle.wait() is True
    assert handle.is_busy() is False
    assert np.allclose(now(system, "PSM1", "setpoint_jp"), goal, atol=1e-6)
    assert np.allclose(psm.measured_jp()[0], goal, atol=2e-3)
    delta = np.zeros(6)
    delta[0] = -0.15
    assert psm.move_jr(delta).wait() is True
    assert now(system, "PSM1", "setpoint_jp")[0] == pytest.approx(goal[0] - 0.15)
    assert psm.insert_jp(0.13).wait() is True
    assert now(system, "PSM1", "setpoint_jp")[2] == pytest.approx(0.13)


def test_move_cp_and_jaw(system, psm):
    start, _ = psm.setpoint_cp()
    goal = PyKDL.Frame(start.M * PyKDL.Rotation.RotZ(math.radians(15)), start.p)
    goal.p[1] += 0.01
    assert psm.move_cp(goal).wait() is True
    T = snap(system).arms["PSM1"].measured_cp.T
    assert np.allclose(T[:3, 3], goal.p.array, atol=5e-4)
    assert np.allclose(T[:3, :3], goal.M.array, atol=5e-3)
    assert psm.jaw.open(math.radians(40)).wait() is True
    assert snap(system).arms["PSM1"].jaw_measured_js.position[0] == pytest.approx(
        math.radians(40), abs=math.radians(1)
    )
    assert psm.jaw.close().wait() is True
    assert now(system, "PSM1/jaw", "setpoint_js").position[0] == pytest.approx(
        math.radians(-20), abs=1e-6
    )
    psm.jaw.servo_jp(np.array([math.radians(10)]))
    settle(0.3)
    assert psm.jaw.setpoint_jp()[0][0] == pytest.approx(math.radians(10), abs=1e-6)


def test_servo_jp_stream_reaches_the_arm(system, ral, psm):
    start = np.array([0.0, 0.0, 0.12, 0.0, 0.0, 0.0])  # the simulated home: in free space
    assert psm.move_jp(start).wait() is True
    rate = ral.create_rate(200)
    goal = np.copy(start)
    for i in range(100):  # 0.5 s at 200 Hz
        goal[0] = start[0] + math.radians(4.0) * (1 - math.cos(math.pi * i / 99))
        psm.servo_jp(goal)
        rate.sleep()
    # the last goal becomes the setpoint (the stream's tail may still be on its way: on a
    # loaded machine the websocket's messages reach the loop a few hundred ms late)
    deadline = time.monotonic() + FAIL_AFTER
    while not np.allclose(setpoint := now(system, "PSM1", "setpoint_jp"), goal, atol=1e-9):
        assert time.monotonic() < deadline, (setpoint, goal)
        settle()
    # the arm settles on the last command (how fast depends on the machine's load: the loop
    # may run below real time, so a wall-clock profile is faster in simulated time)
    deadline = time.monotonic() + FAIL_AFTER
    while abs(psm.measured_jp()[0][0] - goal[0]) > math.radians(0.2):
        assert time.monotonic() < deadline, (psm.measured_jp()[0], goal)
        settle()


def test_sim_time_reads_the_simulations_clock(system, ral):
    """A script on simulated time (``davinci-sim run --sim-time``) reads ``/clock``: never
    ahead of the simulation, and its rate sleeps in simulated time. (A sleep after a late
    one, the clock having skipped past its period in a burst, returns at once, as ROS's
    rate does: any two sleeps in a row last at least a period, so the ten after the first
    one after ``t0`` at least five; a clean clone under load measured 0.09 s for ten.)"""
    r = make_ral("sim_time", use_sim_time=True)
    rate = r.create_rate(100.0)
    rate.sleep()  # (waits for the first /clock: the rate was made before it came)
    t0 = r.now()
    assert 0.0 < t0 <= snap(system).time + 1e-6  # (stamps are whole nanoseconds)
    for _ in range(11):
        rate.sleep()
    assert r.now() - t0 >= 0.05 - 1e-6
    assert r.now() <= snap(system).time + 1e-6


def test_refused_command_changes_nothing_and_wait_times_out(system, ral, psm):
    said: list[str] = []
    assert "/PSM1/error" in echo_arm_messages(ral._client, said.append)  # davinci-sim run's
    before = now(system, "PSM1", "setpoint_jp").copy()
    handle = psm.move_jp(np.zeros(3))  # wrong size: refused by the bridge
    assert handle.wait(timeout=0.5) is False
    assert np.allclose(now(system, "PSM1", "setpoint_jp"), before)
    assert any(s.startswith("[error] PSM1: move_jp") for s in said), said


def test_missing_arm_times_out_as_crtk(ral):
    ghost = dvrk.arm(ral, "PSM9", connection_timeout=0.2)
    with pytest.raises(TimeoutError, match="no data received yet"):
        ghost.measured_jp()
    with pytest.raises(TimeoutError, match="no data received within"):
        ghost.measured_jp(wait_timeout=0.2)
    with pytest.raises(TimeoutError, match="not connected"):
        ghost.check_connections(0.3)
    assert ghost.enable(0.2) is False
    with pytest.raises(RuntimeWarning, match="already exists"):
        ghost._crtk_utils.add_measured_js()


def test_mtm_wrench_moves_the_handle(system, ral):
    mtm = dvrk.mtm(ral, "MTMR")
    mtm.check_connections(10)
    assert mtm.enable(10) and mtm.home(30)
    z0 = snap(system).arms["MTMR"].measured_cp.T[2, 3]
    mtm.use_gravity_compensation(True)
    mtm.body_set_cf_orientation_absolute(True)
    mtm.body.servo_cf(np.array([0.0, 0.0, -3.0, 0.0, 0.0, 0.0]))
    # the handle goes down under the force (waited for: under load the loop may run below
    # real time, so a fixed wall-clock wait can see less motion)
    deadline = time.monotonic() + FAIL_AFTER
    while snap(system).arms["MTMR"].measured_cp.T[2, 3] >= z0 - 0.005:
        assert time.monotonic() < deadline, (snap(system).arms["MTMR"].measured_cp.T[2, 3], z0)
        settle()
    mtm.body.servo_cf(np.zeros(6))
    mtm.hold()
    assert mtm.gripper.measured_js()[0].shape == (1,)
    # dvrk_mtm_cartesian_impedance.py's call (a z spring at the handle's position)
    zero = {"x": 0.0, "y": 0.0, "z": 0.0}
    half = {"p": zero, "d": zero, "bias": zero, "deadband": zero}
    spring = {**half, "p": {**zero, "z": -200.0}, "d": {**zero, "z": -5.0}}
    cp, _ = mtm.measured_cp()
    gains = {
        "header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""},
        "force_orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
        "torque_orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
        "force_position": {"x": cp.p[0], "y": cp.p[1], "z": cp.p[2]},
        "position_positive": spring, "position_negative": spring,
        "orientation_positive": half, "orientation_negative": half,
    }  # fmt: skip
    mtm.servo_ci(gains)
    deadline = time.monotonic() + FAIL_AFTER
    while now(system, "MTMR", "impedance") is None and time.monotonic() < deadline:
        settle()
    g = now(system, "MTMR", "impedance")
    assert g is not None and np.allclose(g.position_positive.p, [0, 0, -200.0])
    mtm.hold()


def test_console_scale_and_pedal_events(system, ral):
    console = dvrk.console(ral)
    clutch = joystick_button(ral, "/console/clutch")
    emulate = ral.publisher("/console/emulate_clutch", "sensor_msgs/Joy")
    settle(0.2)
    console.teleop_set_scale(0.3)
    deadline = time.monotonic() + FAIL_AFTER
    while console.teleop_get_scale() != pytest.approx(0.3) and time.monotonic() < deadline:
        settle()
    assert console.teleop_get_scale() == pytest.approx(0.3)
    emulate.publish({"buttons": [1]})
    assert clutch.wait(timeout=5, value=1) is True and clutch.value() == 1
    emulate.publish({"buttons": [0]})
    assert clutch.wait(timeout=5, value=0) is True
    assert clutch.wait(timeout=0.2) is False  # no event: a time-out


def test_ecm_suj_and_teleop(system, ral):
    ecm = dvrk.ecm(ral, "ECM")
    suj = dvrk.suj(ral)
    teleop = dvrk.teleop_psm(ral, "MTMR_PSM1")
    ecm.check_connections(10)
    cp, _ = ecm.measured_cp(wait_timeout=2)
    assert np.allclose(cp.array, snap(system).arms["ECM"].measured_cp.T, atol=1e-3)
    jp, _ = suj.PSM1.measured_jp(wait_timeout=2)
    assert np.allclose(jp, snap(system).arms["SUJ/PSM1"].measured_js.position, atol=1e-6)
    assert suj.PSM1.local.measured_cp(wait_timeout=2)[0].p.Norm() > 0
    assert suj.ECM.operating_state() in ("ENABLED", "DISABLED")
    teleop.set_scale(0.15)
    deadline = time.monotonic() + FAIL_AFTER
    while teleop.get_scale() != pytest.approx(0.15) and time.monotonic() < deadline:
        settle()
    assert teleop.get_scale() == pytest.approx(0.15)
    assert now(system, "MTMR_PSM1", "snapshot").scale == pytest.approx(0.15)


def test_a_ros1_server(system):
    """The same API against a server speaking ROS 1 (stamps in ``secs``/``nsecs``)."""
    server = RosbridgeServer(
        BridgeConfig(port=0, ros_version=1), nodes=dvrk_nodes(system[0].handle)
    )
    server.start()
    client = RosbridgeClient(WebSocketConnection(server.url))
    try:
        assert client.ros_version() == 1
        psm = dvrk.psm(make_ral("ros1", node=client), "PSM1")
        psm.check_connections(10)
        assert psm.enable(10) and psm.home(30)
        goal = np.copy(psm.setpoint_jp(wait_timeout=2)[0])
        goal[3] += 0.1
        assert psm.move_jp(goal).wait() is True
        assert now(system, "PSM1", "setpoint_jp")[3] == pytest.approx(goal[3])
        assert psm.measured_jp()[1] == pytest.approx(time.time(), abs=5.0)  # secs/nsecs read
    finally:
        client.close()
        server.stop()
