"""``davinci-sim run``: the example dVRK scripts (examples/dvrk_scripts, written in dvrk_python's
style) run unchanged in a subprocess against a simulation in that process (no server); what
they print is checked (``test_run_connect.py``: the same over rosbridge, and the simulator's
state after them)."""

from __future__ import annotations

from script_runs import SCRIPTS, check, check_psm_moves, run

SCENE = ["--scene", "psm1_ecm_mtmr"]


def test_psm_homing_moves_and_jaw_in_process():
    v = check(run(["--scene", "psm1", str(SCRIPTS / "psm_moves.py"), "-a", "PSM1"]))
    check_psm_moves(v)


def test_mtm_wrench_in_process():
    v = check(run([*SCENE, "--no-console", str(SCRIPTS / "mtm_wrench.py")]))
    assert float(v["dz_under_force_mm"]) < -5.0  # -3 N along z: the handle goes down
    assert v["measured_cf_len"] == "6" and v["jacobian_shape"] == "6x7"
    assert v["gripper_measured_js_len"] == "1"
    assert float(v["drift_after_hold_mm"]) < 1.0


def test_console_events_in_process():
    v = check(run([*SCENE, str(SCRIPTS / "console_events.py")]))
    assert v["power_on_enabled"] == "True" and v["system_home_homed"] == "True"
    assert v["console_scale"] == "0.35" and v["teleop_scale"] == "0.25"
    for name in ("operator_present", "clutch", "camera"):
        assert v[f"{name}_pressed_released"] == "True True"
    assert v["teleop_enabled"] == "True" and v["teleop_enabled_after_stop"] == "False"
    assert v["power_off_disabled"] == "True"
