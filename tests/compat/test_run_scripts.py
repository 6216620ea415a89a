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


CLOCK_PROBE = """
import crtk
ral = crtk.ral("clock_probe")
rate = ral.create_rate(100)
rate.sleep()
t0 = ral.now()
for _ in range(20):
    rate.sleep()
print("now:", t0)
print("elapsed:", ral.now() - t0)
print("done")
"""


def test_sim_time_puts_the_scripts_clock_on_the_simulation(tmp_path):
    """``--sim-time``: the script's ``now`` is the simulation's time (seconds since it
    started, not since 1970) and 20 sleeps of a 100 Hz rate last 0.2 simulated s."""
    script = tmp_path / "clock_probe.py"
    script.write_text(CLOCK_PROBE)
    v = check(run(["--scene", "psm1", "--sim-time", str(script)]))
    assert 0.0 < float(v["now"]) < 3600.0
    assert float(v["elapsed"]) >= 0.2 - 1e-6
    wall = check(run(["--scene", "psm1", str(script)]))
    assert float(wall["now"]) > 1e9  # without it, the wall clock (as on the robot)
