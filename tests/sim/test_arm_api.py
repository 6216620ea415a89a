"""The dVRK/CRTK arm API on the simulated system: states, motions, frames, refusals."""

import numpy as np
import pytest
from sim_helpers import home

from davinci_sim.kinematics import fk
from davinci_sim.kinematics.arms import load_arm
from davinci_sim.sim.simulation import Simulation


def test_arms_start_disabled_and_home_to_the_dvrk_home_pose():
    sim = Simulation("psm1")
    psm = sim.arms["PSM1"]
    assert psm.operating_state().state == "DISABLED"
    assert not psm.is_homed()
    states = []
    psm.channels.subscribe(lambda ev, p: states.append(p) if ev == "operating_state" else None)
    assert psm.state_command("enable")
    assert psm.state_command("home")
    assert psm.is_busy()
    assert sim.run_until(lambda: psm.is_homed() and not psm.is_busy(), 10)
    sim.run_for(0.5)
    # dvrk.md 1.7: simulated home = zeros with insertion 0.12 m; steady state within 1e-4.
    assert np.max(np.abs(psm.measured_jp() - load_arm("PSM1").home)) < 1e-4
    assert [s.state for s in states][:1] == ["ENABLED"]
    assert any(s.is_busy for s in states) and not states[-1].is_busy and states[-1].is_homed


def test_home_on_a_homed_enabled_arm_is_a_no_op_and_the_next_move_goes():
    """The second run of an ``enable(); home(); move_jp()`` script (issue 11, 4)."""
    sim = Simulation("psm1")
    psm = sim.arms["PSM1"]
    assert psm.state_command("enable") and psm.state_command("home")
    assert sim.run_until(lambda: psm.is_homed() and not psm.is_busy(), 10)
    goal = psm.setpoint_jp() + [0.1, -0.1, 0.02, 0.2, 0.1, 0.0]
    assert psm.move_jp(goal)
    assert sim.run_until(lambda: not psm.is_busy(), 10)
    assert psm.state_command("enable") and psm.state_command("home")  # the second run
    assert psm.is_homed() and not psm.is_busy()  # no homing trajectory
    assert np.allclose(psm.setpoint_jp(), goal)  # it stays where it was
    assert psm.move_jp(goal - [0.1, -0.1, 0.02, 0.2, 0.1, 0.0])  # and the first move goes
    # A FAULT or an unhomed arm still homes.
    assert psm.state_command("unhome") and not psm.is_homed()
    assert psm.state_command("home") and psm.is_busy()


def test_home_is_refused_when_disabled_and_changes_nothing():
    sim = Simulation("psm1")
    psm = sim.arms["PSM1"]
    before = psm.setpoint_jp()
    result = psm.state_command("home")
    assert not result and "not supported in state DISABLED" in result.message
    sim.run_for(0.05)
    assert np.array_equal(before, psm.setpoint_jp())


@pytest.mark.parametrize("arm", ["PSM1", "ECM"])
def test_move_jp_reaches_goal_within_tolerance_and_limits(psm_sim, arm):
    a = psm_sim.arms[arm]
    goal = a.setpoint_jp() + (0.2 if arm == "PSM1" else 0.1)
    goal[2] = 0.15
    assert a.move_jp(goal)
    assert a.is_busy()
    max_speed = np.zeros(a.dof)
    while a.is_busy():
        psm_sim.tick()
        max_speed = np.maximum(max_speed, np.abs(a.setpoint_js().velocity))
    psm_sim.run_for(0.5)
    assert np.max(np.abs(a.measured_jp() - goal)) < 1e-4  # steady-state tracking
    assert np.all(max_speed <= a.kin.v_max * (1 + 1e-9))  # dvrk.md 1.9 limits


def test_servo_cp_moves_the_tip_in_the_camera_frame(psm_sim):
    psm = psm_sim.arms["PSM1"]
    start = psm.measured_cp()
    assert start.reference_frame == "ECM"
    goal = start.T.copy()
    goal[:3, 3] += [0.01, -0.005, 0.01]
    for _ in range(400):
        assert psm.servo_cp(goal)
        psm_sim.tick()
    psm_sim.run_for(0.3)
    reached = psm.measured_cp().T
    assert np.linalg.norm(reached[:3, 3] - goal[:3, 3]) < 1e-4
    assert np.allclose(reached[:3, :3], goal[:3, :3], atol=1e-3)


def test_measured_cp_is_base_frame_times_local(psm_sim):
    psm = psm_sim.arms["PSM1"]
    T_base, ref = psm.base_frame()
    assert ref == "ECM"
    assert np.allclose(psm.measured_cp().T, T_base @ psm.local.measured_cp().T, atol=1e-12)
    # dvrk.md 1.6 [derived]: PSM1 RCM in the camera frame with the ECM at home.
    assert np.allclose(T_base[:3, 3], [-0.0877, -0.0060, -0.0771], atol=1.5e-4)
    ecm = psm_sim.arms["ECM"]
    assert ecm.measured_cp().reference_frame == "Cart"
    assert np.allclose(ecm.measured_cp().position, [0.0560, 1.1569, 0.9088], atol=1.5e-4)


def test_moving_the_ecm_changes_psm_poses_in_the_camera_frame(psm_sim):
    psm, ecm = psm_sim.arms["PSM1"], psm_sim.arms["ECM"]
    q_before = psm.measured_jp()
    p_before = psm.measured_cp().position.copy()
    ecm.move_jr([0.1, 0.0, 0.0, 0.0])
    psm_sim.run_until(lambda: not ecm.is_busy(), 10)
    psm_sim.run_for(0.3)
    assert np.max(np.abs(psm.measured_jp() - q_before)) < 2e-4
    assert np.linalg.norm(psm.measured_cp().position - p_before) > 0.005


@pytest.mark.parametrize(
    ("command", "args", "expected"),
    [
        ("servo_jp", ([np.nan, 0, 0.12, 0, 0, 0],), "NaN"),
        ("servo_jp", ([0, 0, 0.12],), "6 values"),
        ("servo_jp", ([0, 0, 3e3, 0, 0, 0],), "outside its limits by far"),
        ("move_jp", ([np.inf, 0, 0.12, 0, 0, 0],), "NaN or inf"),
        ("servo_jr", ("abc",), "numbers"),
        ("servo_cp", (np.full((4, 4), np.nan),), "NaN"),
        ("servo_cp", (np.eye(3),), "4x4"),
        ("move_cp", (np.diag([1.0, 1.0, 2.0, 1.0]),), "rotation"),
    ],
)
def test_bad_commands_are_refused_and_change_nothing(psm_sim, command, args, expected):
    psm = psm_sim.arms["PSM1"]
    before = psm.setpoint_jp()
    result = getattr(psm, command)(*args)
    assert not result
    assert expected in result.message
    assert expected in psm.channels.last("error").text
    psm_sim.run_for(0.05)
    assert np.array_equal(before, psm.setpoint_jp())


def test_cartesian_goal_at_the_rcm_is_refused(psm_sim):
    psm = psm_sim.arms["PSM1"]
    T_base, _ = psm.base_frame()
    goal = psm.measured_cp().T.copy()
    goal[:3, 3] = T_base[:3, 3]  # the RCM itself
    before = psm.setpoint_jp()
    result = psm.servo_cp(goal)
    assert not result and "inverse kinematics" in result.message
    assert np.array_equal(before, psm.setpoint_jp())


def test_cartesian_control_needs_the_tool_past_the_cannula(psm_sim):
    psm = psm_sim.arms["PSM1"]
    psm.move_jp([0, 0, 0.03, 0, 0, 0])
    psm_sim.run_until(lambda: not psm.is_busy(), 5)
    psm_sim.run_for(0.2)
    result = psm.servo_cp(psm.measured_cp().T)
    assert not result and "inserted past the cannula" in result.message
    assert psm.jaw.move_jp(0.5)  # in joint space, as the dVRK does
    assert not psm.jaw.servo_jf(0.05)  # Cartesian effort control: not inside the cannula


def test_commands_need_an_enabled_homed_arm():
    sim = Simulation("psm1")
    psm = sim.arms["PSM1"]
    assert "ENABLED" in psm.servo_jp([0, 0, 0.12, 0, 0, 0]).message
    psm.state_command("enable")
    assert "not homed" in psm.move_jp([0, 0, 0.12, 0, 0, 0]).message
    assert "not homed" in psm.servo_cp(np.eye(4)).message


def test_pause_resume_and_disable(psm_sim):
    psm = psm_sim.arms["PSM1"]
    psm.move_jr([0.3, 0, 0, 0, 0, 0])
    psm_sim.run_for(0.1)
    assert psm.state_command("pause")
    assert psm.operating_state().state == "PAUSED" and not psm.is_busy()
    assert not psm.servo_jr([0.01, 0, 0, 0, 0, 0])
    assert psm.state_command("resume")
    assert psm.operating_state().state == "ENABLED" and psm.is_homed()
    assert psm.state_command("disable")
    assert not psm.is_homed()


def test_jaw_follows_commands(psm_sim):
    psm = psm_sim.arms["PSM1"]
    assert psm.jaw.move_jp(np.radians(60))
    psm_sim.run_until(lambda: not psm.is_busy(), 5)
    psm_sim.run_for(0.3)
    assert psm.jaw.measured_js().position[0] == pytest.approx(np.radians(60), abs=2e-3)
    # beyond the 80 deg jaw limit: clipped to it, as the dVRK's clip_jaw_jp does
    assert psm.jaw.servo_jp(np.radians(100))
    assert psm.jaw.setpoint_js().position[0] == pytest.approx(np.radians(80), abs=1e-12)


def test_hold_and_free_keep_the_arm_up(psm_sim):
    psm = psm_sim.arms["PSM1"]
    q0 = psm.measured_jp()
    assert psm.free()
    psm_sim.run_for(0.5)
    # Gravity compensation alone: the arm does not fall (drift well under a degree).
    assert np.max(np.abs(psm.measured_jp() - q0)) < 0.01
    assert psm.hold()
    psm_sim.run_for(0.3)
    assert psm.setpoint_js().effort is not None


def test_tracking_error_puts_the_arm_in_fault():
    sim = Simulation("psm1")
    home(sim, ["PSM1"])
    psm = sim.arms["PSM1"]
    # A 1.5 rad step in one tick cannot be tracked with the 3.3 N·m yaw motor (dvrk.md 1.2).
    psm.servo_jp([1.5, 0, 0.12, 0, 0, 0])
    sim.run_for(0.3)
    assert psm.operating_state().state == "FAULT"
    assert "tracking error" in psm.channels.last("error").text
    assert psm.state_command("enable")


def test_forward_and_inverse_kinematics_services(psm_sim):
    psm = psm_sim.arms["PSM1"]
    q = np.array([0.2, -0.1, 0.14, 0.3, 0.2, -0.1])
    cp, ok = psm.forward_kinematics(q)
    assert ok
    T_expected = psm.base_frame()[0] @ fk.forward_kinematics(psm.chain, q)
    assert np.allclose(cp.T, T_expected)
    q_ik, ok = psm.inverse_kinematics(q + 0.01, cp.T)
    assert ok and np.allclose(q_ik, q, atol=1e-6)
    shaft, ok = psm.local.forward_kinematics(q[:4])
    assert ok and np.linalg.norm(shaft.position) == pytest.approx(q[2] - 0.0156, abs=1e-9)
    assert not psm.forward_kinematics([np.nan])[1]


def test_deterministic_for_the_same_seed_and_commands():
    def run(seed):
        sim = Simulation("psm1", seed=seed, encoder_noise_std=1e-5)
        home(sim, ["PSM1"])
        psm = sim.arms["PSM1"]
        goal = psm.measured_cp().T.copy()
        for _k in range(300):
            goal[0, 3] += 2e-5
            psm.servo_cp(goal)
            sim.tick()
        return sim.data.qpos.copy(), psm.measured_jp()

    a, b, c = run(3), run(3), run(4)
    assert a[0].tobytes() == b[0].tobytes() and a[1].tobytes() == b[1].tobytes()
    assert a[1].tobytes() != c[1].tobytes()


def test_suj_arms_report_the_rcm_in_the_cart(psm_sim):
    suj = psm_sim.arms["SUJ/PSM1"]
    st = suj.operating_state()
    assert st.state == "ENABLED" and st.is_homed
    # dvrk.md 1.6 [derived]: PSM1 RCM in the cart (0.0288 m precision of the table).
    assert np.allclose(suj.measured_cp().position, [-0.0288, 1.2198, 0.9591], atol=2e-4)


@pytest.mark.parametrize(
    "command, words",
    [
        (lambda a: a.servo_jp(a.setpoint_jp(), velocity=[1e300, 0, 0, 0, 0, 0]),
         "velocity[0] (yaw) = 1e+300 is over"),
        (lambda a: a.servo_jp(a.setpoint_jp(), velocity=[0, 0, 0, 0, 0, -1e3]), "velocity[5]"),
        (lambda a: a.trajectory_j_set_ratio(1e-320), "ratio must be in [0.001, 1]"),
        (lambda a: a.move_cp(_far(a.setpoint_cp().T)), "beyond 10 m"),
        (lambda a: a.servo_cp(_far(a.setpoint_cp().T)), "beyond 10 m"),
        # The sweep of every value of every command (issue 11, 4): efforts, wrenches,
        # twists, switches, names, kinematics queries, the jaw.
        (lambda a: a.servo_jf([1e300, 0, 0, 0, 0, 0]), "effort[0] (yaw) = 1e+300 is over 33.16"),
        (lambda a: a.servo_jf([0, 0, -1e3, 0, 0, 0]), "effort[2] (insertion)"),
        (lambda a: a.servo_jf([0, 0, 0, 0, 0, float("nan")]), "NaN or inf"),
        (lambda a: a.body.servo_cf([1e300, 0, 0, 0, 0, 0]), "wrench[0] (fx) = 1e+300 is over 100"),
        (lambda a: a.spatial.servo_cf([0, 0, 0, 0, 0, -50]), "wrench[5] (tz) = -50 is over 10"),
        (lambda a: a.servo_cp(a.setpoint_cp().T, twist=[1e300, 0, 0, 0, 0, 0]),
         "twist[0] (vx) = 1e+300 is over 10"),
        (lambda a: a.servo_cp(a.setpoint_cp().T, twist=[0, 0, 0, 0, 0, 1e3]), "twist[5] (wz)"),
        (lambda a: a.servo_cp(a.setpoint_cp().T, twist=[9, 0, 0, 0, 0, 0]),
         "twist as joint velocity"),
        (lambda a: a.jaw.servo_jf(1e300), "effort[0] (jaw) = 1e+300 is over 1.6"),
        (lambda a: a.jaw.servo_jp(1e300), "outside its limits"),
        (lambda a: a.use_gravity_compensation("false"), "enabled must be true or false"),
        (lambda a: a.body_set_cf_orientation_absolute(2), "absolute must be true or false"),
        (lambda a: a.set_base_frame(np.eye(4), 5), "reference_frame must be a name"),
        (lambda a: a.set_base_frame(np.eye(4), "x" * 10**6), "(1000002 characters)"),
        (lambda a: a.forward_kinematics([1e300])[1], "within ±1000"),
        (lambda a: a.local.forward_kinematics([0, 1e300])[1], "within ±1000"),
        (lambda a: a.inverse_kinematics([1e300, 0, 0.1, 0, 0, 0], a.setpoint_cp().T)[1],
         "reference joints[0] (yaw) = 1e+300 is over 1000"),
        (lambda a: a.insert_jp("deep"), "depth must be a number"),
        (lambda a: a.insert_jp(float("inf")), "depth is inf"),
        (lambda a: a.servo_jp([0.0] * 5 + ["x"] * 10**5), "characters)"),
        (lambda a: a.servo_jp([10**400] * 6), "must be a sequence of 6 numbers"),
        (lambda a: a.jaw.servo_jp(10**400), "too large for a float"),
        (lambda a: a.trajectory_j_set_ratio(True), "ratio must be a number"),
    ],
)  # fmt: skip
def test_huge_finite_values_are_refused_with_the_field_named(psm_sim, command, words):
    """Finite but huge values (issue 11, 4) used to crash the physics or leak raw errors;
    a refusal names the field, echoes at most a few hundred characters of the value and
    changes nothing (setpoints, servo references, modes, the arm's state)."""
    psm = psm_sim.arms["PSM1"]
    before = psm.setpoint_jp()
    servo = psm_sim.servo.get_state()
    arm_state = psm.get_state()
    result = command(psm)
    assert not result and words in result.message
    assert len(result.message) < 600
    for name, value in psm_sim.servo.get_state().items():
        np.testing.assert_array_equal(value, servo[name], err_msg=name)
    assert psm.get_state().keys() == arm_state.keys()
    assert psm.user_base_frame() is None and psm.wrench_setpoint() is None
    psm_sim.run_for(0.1)
    assert np.array_equal(before, psm.setpoint_jp())
    assert psm.operating_state().state == "ENABLED"
    assert psm_sim.recoveries == 0


def test_values_within_the_bounds_are_accepted_and_clamped(psm_sim):
    """Between the dVRK's limit and the absurd bound, efforts are clamped to ftmax (as the
    dVRK's controller does); bools and names of the right kind are taken."""
    psm = psm_sim.arms["PSM1"]
    assert psm.servo_jf([5 * 3.316101, 0, 0, 0, 0, 0])
    assert psm_sim.servo.tau_ff[psm.actuator_indices[0]] == pytest.approx(3.316101)
    assert psm.use_gravity_compensation(1) and psm.use_gravity_compensation(False)
    assert psm.body_set_cf_orientation_absolute(np.bool_(True))
    assert psm.set_base_frame(np.eye(4), "table")


def _far(T):
    T = T.copy()
    T[0, 3] = 1e300
    return T


@pytest.mark.parametrize("kind", ["body", "spatial"])
def test_a_zero_wrench_renders_zero_efforts_as_the_law_computes_them(psm_sim, kind):
    """(A zero wrench skips the kinematics: the efforts are the law's own, +0.0 each, at
    any joints; a following MTM without a field renders it every tick.)"""
    from davinci_sim.sim import arm_laws as laws

    psm = psm_sim.arms["PSM1"]
    rng = np.random.default_rng(3)
    for w in (np.zeros(6), -np.zeros(6)):
        for _ in range(5):
            q = psm.setpoint_jp() + rng.uniform(-0.2, 0.2, psm.dof) * [1, 1, 0.1, 1, 1, 1]
            psm.servo_jp(q)
            psm_sim.run_for(0.01)
            tau = psm._wrench_to_effort(kind, w)
            _, T_base_tip, J = psm._measured_kinematics()
            R = T_base_tip[:3, :3] if kind == "body" else psm.base_frame()[0][:3, :3].T
            want = laws.wrench_effort(J, R, w, psm.chain.ftmax)
            assert tau.tobytes() == want.tobytes()  # (the same signed zeros)
            assert not np.signbit(tau).any()
