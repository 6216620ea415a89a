"""``davinci-sim run --connect``: the example dVRK scripts run unchanged in a subprocess against
a rosbridge server of this process (what ``davinci-sim serve`` runs); what they print and
the simulator's state after them are checked. Also: which crtk/dvrk/PyKDL a run uses, and
its errors."""

from __future__ import annotations

import math

import pytest
from script_runs import SCRIPTS, check, check_psm_moves, run

from davinci_sim.bridge.rosbridge.config import BridgeConfig
from davinci_sim.bridge.rosbridge.server import RosbridgeServer
from davinci_sim.compat.inprocess import dvrk_nodes
from davinci_sim.system import ConsoleDescription, SystemDescription, build_system


@pytest.fixture(scope="module")
def server():
    """A simulation served over rosbridge (what ``davinci-sim serve`` runs)."""
    description = SystemDescription(scene="psm1_ecm_mtmr", console=ConsoleDescription(),
                                    runner="thread", snapshot_period=0.01)  # fmt: skip
    system = build_system(description, start=True)
    server = RosbridgeServer(BridgeConfig(port=0), nodes=dvrk_nodes(system.handle)).start()
    yield system, server
    system.stop()
    server.stop()


def now(system, target, method):
    return system.handle.call(target, method).result(5.0)


def test_psm_homing_moves_and_jaw_over_rosbridge(server):
    system, rosbridge = server
    v = check(run(["--connect", rosbridge.url, str(SCRIPTS / "psm_moves.py"), "-a", "PSM1"]))
    check_psm_moves(v)
    # the simulator is where the script left it
    assert now(system, "PSM1/jaw", "setpoint_js").position[0] == pytest.approx(
        math.radians(-20.0), abs=1e-6
    )
    assert now(system, "PSM1", "setpoint_jp")[2] == pytest.approx(0.13, abs=1e-3)
    assert now(system, "PSM1", "is_homed")


def test_servo_jp_streaming_over_rosbridge(server):
    system, rosbridge = server
    v = check(run(["--connect", rosbridge.url, str(SCRIPTS / "servo_stream.py"), "-a", "PSM1"]))
    assert v["servo_jp_sent"] == "200"
    assert float(v["setpoint_error_deg"]) < 1e-3  # the last command is the arm's setpoint
    assert float(v["final_error_deg"]) < 0.5  # settled on the last command
    # the stream's last command: yaw back near its start (a full cosine period)
    last = 2 * math.radians(5.0) * 0.5 * (1 - math.cos(2 * math.pi * 199 / 200))
    assert now(system, "PSM1", "setpoint_jp")[0] == pytest.approx(last, abs=1e-6)


PROBE = """
import crtk, dvrk, PyKDL
print("crtk:", crtk.__file__)
print("dvrk:", dvrk.__file__)
print("PyKDL:", PyKDL.__file__)
print("done")
"""


def _fake_module(folder, name: str) -> None:
    (folder / name).mkdir()
    (folder / name / "__init__.py").write_text("ral = None\n")


def test_a_ros_workspace_is_not_shadowed(server, tmp_path):
    """With crtk, dvrk and PyKDL importable (a sourced ROS workspace), the script gets them
    (the choice is printed)."""
    _, rosbridge = server
    script = tmp_path / "probe.py"
    script.write_text(PROBE)
    ros = tmp_path / "ros"
    ros.mkdir()
    _fake_module(ros, "crtk")
    _fake_module(ros, "dvrk")
    (ros / "PyKDL.py").write_text("")
    real = run(["--connect", rosbridge.url, str(script)], env={"PYTHONPATH": str(ros)})
    v = check(real)
    assert "crtk, dvrk: the installed ones" in real.stdout
    assert "PyKDL: the installed one" in real.stdout
    assert all(v[name].startswith(str(ros)) for name in ("crtk", "dvrk", "PyKDL"))
    # (without them, ours: every other run here, and test_run_modules.py)
