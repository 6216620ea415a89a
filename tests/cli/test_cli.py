"""The davinci-sim command line."""

import numpy as np
from PIL import Image

from davinci_sim import cli
from davinci_sim.cli import main


def test_info_lists_arms_joints_and_scenes(capsys):
    assert main(["info"]) == 0
    out = capsys.readouterr().out
    for word in ("PSM1", "ECM", "MTMR", "insertion", "wrist_roll", "SUJ/PSM3", "full", "psm1"):
        assert word in out


def test_snapshot_writes_three_images(tmp_path):
    assert main(["snapshot", "--scene", "psm1", "-o", str(tmp_path)]) == 0
    for name in ("endoscope_left", "endoscope_right", "overview"):
        img = np.asarray(Image.open(tmp_path / f"{name}.png"))
        assert img.ndim == 3 and img.std() > 5


def test_snapshot_into_an_existing_file_is_refused_in_one_line(tmp_path, capsys):
    taken = tmp_path / "notes.txt"
    taken.write_text("mine")
    assert main(["snapshot", "--scene", "psm1", "-o", str(taken)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "exists and is not a folder" in err
    assert "Traceback" not in err and taken.read_text() == "mine"
    assert main(["snapshot", "--scene", "psm1", "-o", str(taken / "below")]) == 2
    assert "cannot create the folder" in capsys.readouterr().err


def test_demo_runs_and_reports(capsys):
    assert main(["demo", "--scene", "psm1"]) == 0
    out = capsys.readouterr().out
    assert "servo_cp circle" in out and "bad command refused" in out and "homed=True" in out


def test_snapshot_draws_a_task_in_the_endoscope_view(tmp_path, capsys):
    plain, drawn = tmp_path / "plain", tmp_path / "task"
    assert main(["snapshot", "--scene", "psm1", "--no-home", "-o", str(plain)]) == 0
    assert main(["snapshot", "--scene", "psm1", "--no-home", "--task", "seed_path",
                 "-o", str(drawn)]) == 0  # fmt: skip
    a = np.asarray(Image.open(plain / "endoscope_left.png")).astype(int)
    b = np.asarray(Image.open(drawn / "endoscope_left.png")).astype(int)
    changed = np.any(a != b, axis=2)
    assert 100 < changed.sum() < 0.2 * changed.size  # the thin path and its markers
    magenta = (b[..., 0] > 200) & (b[..., 1] < 120) & (b[..., 2] > 180)
    assert magenta[changed].sum() > 20  # the path is drawn in the task's colour
    assert main(["snapshot", "--task", "no_such_task", "-o", str(tmp_path)]) == 2
    assert "no_such_task" in capsys.readouterr().err


import pytest  # noqa: E402


@pytest.mark.parametrize(
    "argv, words",
    [
        (["serve", "--rate", "0"], "--rate must be a rate > 0"),
        (["serve", "--tf-rate", "nan"], "--tf-rate must be a rate > 0"),
        (["serve", "--image-rate", "-5"], "--image-rate must be a rate > 0"),
        (["serve", "--duration", "-1"], "--duration must be a time >= 0"),
        (["serve", "--condition", "B=40"], "--condition needs --task"),
        (["serve", "--task", "seed_path", "--condition", "40:-5"], "G_max"),
        (["serve", "--task", "seed_path", "--condition", "40:x"], "neither"),
        (["serve", "--web-port", "70000"], "--web-port must be a port"),
        (["serve", "--realtime-priority", "100"], "1..99"),
        (["serve", "--ros-connect", "http://dvrk:9090"], "url must be ws://"),
        (["serve", "--ros-connect", "ws://dvrk:9090", "--namespace", "sim"], "namespace must"),
        (["study", "--conditions", ""], "B:G_max"),
        (["study", "--conditions", "40:nan"], "finite"),
        (["study", "--conditions", "40:-5"], ">= 0"),
        (["study", "--conditions", "B=1000"], "condition of the task"),
        (["study", "--fixture", "{type: magnet}"], "unknown fixture type"),
        (["study", "--fixture", "{type: spring, stiffnes: 1}"], "unknown keys"),
        (["study", "--fixture", "[1, 2]"], "mapping with a 'type'"),
        (["study", "--fixture", "{type: no_such_module:Law}"], "cannot import"),
        (["study", "--transition", "-0.001"], "transition must be"),
    ],
)
def test_bad_options_fail_in_one_line_before_any_work(argv, words, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_study_refuses_an_output_that_is_a_file_before_the_first_trial(tmp_path, capsys):
    target = tmp_path / "results.csv"
    target.write_text("keep me")
    assert main(["study", "--subjects", "1", "--repetitions", "1", "-o", str(target)]) == 2
    assert "not a folder" in capsys.readouterr().err
    assert target.read_text() == "keep me"  # nothing lost


def _listening_socket():
    import socket

    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen()
    return s


@pytest.mark.parametrize("option", ["--port", "--web-port"])
def test_serve_on_a_taken_port_names_the_option_and_this_process(option, capsys):
    """The port held by this test process: one line, before the scene is built, naming the
    port, the process that holds it (this one, by pid) and the option to change."""
    import os

    held = _listening_socket()
    try:
        port = held.getsockname()[1]
        argv = ["serve", "--scene", "psm1", "--duration", "0", "--port", "0", option, str(port)]
        assert main(argv) == 2
    finally:
        held.close()
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert f"port {port} is taken by process {os.getpid()} (" in err
    assert f"choose another with {option} PORT" in err


def test_the_taken_port_message_says_9090_is_rosbridge_s_and_works_without_a_holder():
    from davinci_sim.bridge.ports import PortHolder, port_holder, taken_port_message

    text = taken_port_message(9090, "--port", PortHolder(42, "rosbridge_websocket"))
    assert text.startswith("port 9090 is taken by process 42 (rosbridge_websocket)")
    assert "real rosbridge server's default port" in text and text.endswith("--port PORT")
    assert "rosbridge" not in taken_port_message(8080, "--web-port")
    held = _listening_socket()
    port = held.getsockname()[1]
    held.close()
    assert port_holder(port) is None  # nobody listens any more
    assert port_holder(port, proc="/nonexistent") is None


@pytest.mark.parametrize(
    "argv, words",
    [
        (["serve", "--trainee", "ana"], "--trainee needs --task"),
        (["serve", "--task", "seed_path", "--trainee", " "], "non-empty"),
        (["serve", "--task", "seed_path", "--trainee", "a\tb"], "printable"),
        (["serve", "--task", "seed_path", "--records", "{folder}"], "records file"),
        (["serve", "--stepped", "--no-web"], "the web console's pages advance"),
        (["serve", "--stepped", "--runner", "thread"], "drop --runner thread"),
    ],
)
def test_bad_records_options_fail_in_one_line_before_any_work(argv, words, capsys, tmp_path):
    argv = [a.replace("{folder}", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(
    ("argv", "console", "hands"),
    [
        # the console and pedals by default (issue 21): the scene has MTMs and PSMs
        ([], True, ()),
        (["--scene", "psm1_ecm_mtmr"], True, ()),
        (["--no-console"], False, ()),
        (["--scene", "psm1"], False, ()),  # nothing to teleoperate
        (["--console"], True, ("MTML", "MTMR")),  # asked for: the web console's hands too
        (["--console", "--no-web"], True, ()),
        (["--console", "--stepped"], True, ("MTML", "MTMR")),
    ],
)
def test_serve_serves_the_console_and_pedals_by_default(monkeypatch, argv, console, hands):
    import davinci_sim.bridge.app as app

    seen = {}

    def fake_serve(options, **kwargs):
        seen["options"] = options
        return {}

    monkeypatch.setattr(app, "serve", fake_serve)
    monkeypatch.setattr(cli, "_taken_port_problem", lambda args, web: None)
    if "--no-web" not in argv:  # no web server is built: serve() is not run
        monkeypatch.setattr("davinci_sim.web.app.web_part", lambda *a, **k: None)
    assert cli.main(["serve", "--duration", "0", *argv]) == 0
    options = seen["options"]
    assert options.console is console
    assert options.hand_inputs == hands
    stepped = "--stepped" in argv  # (the loop in its own process, ticking on request)
    assert (options.stepped, options.real_time) == (stepped, not stepped)
    assert options.runner == ("process" if "--no-web" not in argv else "thread")


def test_serve_no_console_contradicts_console_and_task(capsys):
    assert cli.main(["serve", "--no-console", "--console", "--duration", "0"]) == 2
    assert "--no-console contradicts --console" in capsys.readouterr().err
    assert cli.main(["serve", "--no-console", "--task", "seed_path", "--duration", "0"]) == 2
    assert "--no-console contradicts --task" in capsys.readouterr().err
