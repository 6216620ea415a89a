"""The dVRK-style example script over rosbridge, and ``davinci-sim serve``."""

import json
import socket
import subprocess
import sys
from pathlib import Path

import pytest
import roslibpy
from bridge_helpers import serving, wait_for

from davinci_sim import cli
from davinci_sim.bridge.app import ServeOptions
from davinci_sim.bridge.rosbridge.config import BridgeConfig

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "dvrk_psm_rosbridge.py"


@pytest.mark.parametrize("ros_version", [1, 2])
def test_dvrk_style_script_runs_unchanged(handle, make_server, ros_version):
    """enable, home, move_jp + wait on is_busy, servo_cp loop, jaw, measured_cp (dvrk.md §3),
    in both dialects."""
    server = make_server(handle, ros_version=ros_version)
    result = subprocess.run(
        [sys.executable, str(EXAMPLE), "--port", str(server.port), "--arm", "PSM1"],
        capture_output=True,
        text=True,
        timeout=90,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    lines = result.stdout.splitlines()
    assert lines[-1] == "done"
    assert not any(line.startswith("FAIL") for line in lines)
    assert sum(line.startswith("ok") for line in lines) == 9


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_serve_runs_server_udp_and_stops(make_ros):
    udp_port = free_port()
    listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    listener.bind(("127.0.0.1", udp_port))
    listener.settimeout(3)
    options = ServeOptions(scene="psm1", images="none", home=True, udp=True,
                           udp_ports={"PSM1": udp_port, "ECM": free_port()},
                           bridge=BridgeConfig(port=0, ros_version=1))  # fmt: skip
    try:
        with serving(options) as server:
            ros = make_ros(server)
            states = []
            roslibpy.Topic(ros, "/PSM1/operating_state", "crtk_msgs/OperatingState").subscribe(
                states.append
            )
            assert wait_for(lambda: states and states[-1]["is_homed"], 10)  # --home
            data, _ = listener.recvfrom(65536)
            assert len(json.loads(data)) == 1
            # (the served simulation's clock, /clock, moves on after this: serve's rate has a
            # window of simulated time to measure, however loaded the machine)
            clock = []
            roslibpy.Topic(ros, "/clock", "rosgraph_msgs/Clock").subscribe(
                lambda m: clock.append(m["clock"]["secs"] + 1e-9 * m["clock"]["nsecs"])
            )
            assert wait_for(lambda: len(clock) > 1 and clock[-1] >= clock[0] + 0.05, 30)
    finally:
        listener.close()
    assert server.result["done"]["sim_over_wall"] > 0  # the loop ran (its rate: benchmarks/)
    with socket.socket() as sock:  # the port is free again
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(("127.0.0.1", server.port))


def test_cli_serve_with_duration(capsys):
    code = cli.main(["serve", "--scene", "psm1", "--port", "0", "--images", "none",
                     "--no-web", "--duration", "0.5"])  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0
    assert "rosbridge server: ws://127.0.0.1:" in out and "stopped" in out


def test_cli_serve_rejects_bad_options(capsys):
    assert cli.main(["serve", "--udp-ports", "PSM1:1", "--duration", "0"]) == 2
    assert "ARM=PORT" in capsys.readouterr().err


def test_cli_serve_starts_the_web_console_and_says_where(capsys):
    code = cli.main(["serve", "--scene", "psm1_ecm_mtmr", "--task", "seed_path", "--port", "0",
                     "--images", "none", "--web-port", "0", "--no-bedside",
                     "--realtime-priority", "50", "--duration", "2"])  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0
    assert "web console: http://127.0.0.1:" in out and "open this in a browser" in out
    assert "loop process: " in out  # SCHED_FIFO granted or the reason it was not
    assert "loop: " in out  # the process runner's period statistics


def test_cli_serve_refuses_a_taken_web_port_and_a_bad_priority(capsys):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        code = cli.main(["serve", "--scene", "psm1", "--port", "0", "--images", "none",
                         "--web-port", str(port), "--no-bedside", "--duration", "1"])  # fmt: skip
    assert code == 2
    assert "choose another with --web-port PORT" in capsys.readouterr().err
    assert cli.main(["serve", "--realtime-priority", "0", "--duration", "0"]) == 2
    assert "1..99" in capsys.readouterr().err
