"""``davinci-sim serve --task``: the session's /task topics and the CLI's checks."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import roslibpy
from bridge_helpers import serving, wait_for

from davinci_sim import cli
from davinci_sim.bridge.app import ServeOptions, task_condition
from davinci_sim.bridge.rosbridge.config import BridgeConfig
from davinci_sim.tasks import load_task

SHORT_TASK = str(Path(__file__).resolve().parents[1] / "study" / "short_path.yaml")


@pytest.mark.parametrize("runner", ["thread", "process"])
def test_serve_with_a_task_publishes_its_state_and_takes_reset(make_ros, runner):
    options = ServeOptions(scene="psm1_ecm_mtmr", images="none", task=SHORT_TASK, runner=runner,
                           condition="20:2", bridge=BridgeConfig(port=0))  # fmt: skip
    with serving(options) as server:
        ros = make_ros(server)
        states = []
        roslibpy.Topic(ros, "/task/state", "std_msgs/String").subscribe(
            lambda m: states.append(json.loads(m["data"]))
        )
        assert wait_for(lambda: states, 10)
        s = states[-1]
        assert s["task"] == "short_path" and s["condition"] == "viscous(B=20, G_max=2)"
        assert s["phase"] in ("IDLE", "READY") and s["completed"] == 0 and s["last"] == {}
        roslibpy.Topic(ros, "/task/reset", "std_msgs/Empty").publish(roslibpy.Message({}))
        topics = ros.get_topics()
        assert {"/task/state", "/task/results", "/task/reset"} <= set(topics)
        # The console was installed with the task, with its teleoperation.
        assert "/MTMR_PSM1/current_state" in topics


def test_task_conditions_by_name_or_b_and_g():
    task = load_task("seed_path")
    assert task_condition(task, "B=40") == "B=40"
    assert task_condition(task, "40:5") == {"type": "viscous", "B": 40.0, "G_max": 5.0}
    assert task_condition(task, None) is None
    with pytest.raises(ValueError, match="neither"):
        task_condition(task, "strong")


def test_cli_refuses_an_unknown_task_or_condition(capsys):
    assert cli.main(["serve", "--task", "no_such_task", "--duration", "1"]) == 2
    assert "no_such_task" in capsys.readouterr().err
    assert cli.main(["serve", "--task", "seed_path", "--condition", "x", "--duration", "1"]) == 2
    assert "neither" in capsys.readouterr().err


def test_training_dashboard_example_follows_a_session(make_ros):
    import subprocess
    import sys

    example = Path(__file__).resolve().parents[2] / "examples" / "training_dashboard.py"
    options = ServeOptions(scene="psm1_ecm_mtmr", images="none", task=SHORT_TASK,
                           bridge=BridgeConfig(port=0))  # fmt: skip
    with serving(options) as server:
        result = subprocess.run(
            [sys.executable, str(example), "--port", str(server.port), "--duration", "1.5",
             "--reset"],
            capture_output=True,
            text=True,
            timeout=60,
        )  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr
    lines = result.stdout.splitlines()
    assert "reset sent" in lines
    assert any(line.startswith("short_path [viscous(B=40, G_max=5)] repetition 1: ")
               for line in lines), lines  # fmt: skip
