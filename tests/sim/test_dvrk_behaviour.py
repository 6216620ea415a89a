"""Where scripts rely on the dVRK's own behaviour (issue 21, 3): joint goals clipped to the
limits, setpoints following the measured joints in effort mode, the MTM's orientation lock
moving along a trajectory, the jaw inside the cannula, throttled "arm not ready" errors."""

import math
import re

import numpy as np
import pytest
from sim_helpers import home

from davinci_sim.sim.simulation import Simulation
from davinci_sim.sim.types import ACCEPTED


@pytest.fixture(scope="module")
def mtm_sim():
    """PSM1, ECM and MTMR, all homed (shared by the MTM tests: each leaves MTMR holding)."""
    sim = Simulation("psm1_ecm_mtmr")
    home(sim)
    yield sim
    sim.close()


# ------------------------------------------------------------------ a. clip_jp
def test_servo_jp_returns_accepted(psm_sim):
    psm = psm_sim.arms["PSM1"]
    assert psm.servo_jp(psm.setpoint_jp()) == ACCEPTED
    assert psm.servo_jp(psm.setpoint_jp(), np.zeros(6)) == ACCEPTED


def test_joint_goals_outside_the_limits_are_clipped_as_the_dvrk_clips_them(psm_sim):
    psm = psm_sim.arms["PSM1"]
    qmin, qmax = psm.chain.qmin, psm.chain.qmax
    goal = psm.setpoint_jp()
    goal[0] = qmin[0] - 0.2  # yaw past its lower limit
    assert psm.move_jp(goal)
    psm_sim.run_until(lambda: not psm.is_busy(), 10)
    assert psm.setpoint_jp()[0] == qmin[0]
    assert abs(psm.measured_jp()[0] - qmin[0]) < 2e-3
    goal = psm.setpoint_jp()
    goal[0] = qmin[0] - 0.001  # streaming a goal a hair past the limit
    goal[1] += 0.001
    assert psm.servo_jp(goal)
    assert psm.setpoint_jp()[0] == qmin[0]
    assert psm.setpoint_jp()[1] == goal[1]
    # relative goals: the sum is clipped
    assert psm.move_jr([-0.5, 0, 0, 0, 0, 0])
    psm_sim.run_until(lambda: not psm.is_busy(), 10)
    assert psm.setpoint_jp()[0] == qmin[0]
    assert psm.servo_jr([0, 0, 0, 0, 10.0, 0])
    assert psm.setpoint_jp()[4] == qmax[4]


def test_absurd_and_malformed_joint_goals_are_still_refused(psm_sim):
    psm = psm_sim.arms["PSM1"]
    before = psm.setpoint_jp()
    for goal in ([1e300, 0, 0.12, 0, 0, 0], [np.nan, 0, 0.12, 0, 0, 0], [0, 0, 0.12]):
        assert not psm.servo_jp(goal)
        assert not psm.move_jp(goal)
    assert not psm.jaw.move_jp(float("inf"))
    assert np.array_equal(psm.setpoint_jp(), before)


def test_the_jaw_takes_exactly_80_degrees_and_clips_beyond(psm_sim):
    psm = psm_sim.arms["PSM1"]
    assert psm.jaw.spec.qmax == math.radians(80)  # dvrk.md 1.2: the jaw opens to 80°
    assert psm.jaw.move_jp(math.radians(80))
    psm_sim.run_until(lambda: not psm.is_busy(), 5)
    assert psm.jaw.setpoint_js().position[0] == pytest.approx(math.radians(80), abs=1e-12)
    assert psm.jaw.servo_jp(math.radians(95))
    assert psm.jaw.setpoint_js().position[0] == pytest.approx(math.radians(80), abs=1e-12)
    assert psm.jaw.servo_jp(-1.0)
    assert psm.jaw.setpoint_js().position[0] == pytest.approx(psm.jaw.spec.qmin, abs=1e-12)


def test_an_mtm_resting_past_a_limit_still_moves(mtm_sim):
    """dvrk_move_wait_test.py: the goals are the current setpoint with one joint changed;
    an MTM 1 mrad past shoulder_pitch's limit must not make every move_jp fail."""
    mtm = mtm_sim.arms["MTMR"]
    start = mtm.setpoint_jp()
    start[1] = mtm.chain.qmin[1] - 1e-3
    goal = start.copy()
    goal[0] += 0.1
    assert mtm.move_jp(goal)
    assert mtm.is_busy()
    assert mtm_sim.run_until(lambda: not mtm.is_busy(), 10)
    assert mtm.setpoint_jp()[1] == mtm.chain.qmin[1]
    assert abs(mtm.setpoint_jp()[0] - goal[0]) < 1e-12


def test_an_ik_solution_past_a_limit_is_clipped(psm_sim):
    """The dVRK clips move_cp's IK solution to the joint limits (clip_jp after IK)."""
    psm = psm_sim.arms["PSM1"]
    q = psm.setpoint_jp()
    q[4] = psm.chain.qmax[4] + 0.05  # wrist_pitch 3° past its limit
    pose, ok = psm.forward_kinematics(q)
    assert ok
    assert psm.move_cp(pose.T)
    assert psm_sim.run_until(lambda: not psm.is_busy(), 10)
    assert psm.setpoint_jp()[4] == psm.chain.qmax[4]


def test_a_servo_stream_rolling_the_tool_past_its_limit_stops_it_there(psm_sim):
    """dvrk.md 1.8: the IK puts the roll nearest the current one mod 2π and the arm clips
    it: a stream of goals turning the tool past its ±260° roll holds it at the limit. (The
    IK took the turn 360° back, within the limit, before: the setpoint jumped a whole turn
    in one tick and the arm faulted on its roll's tracking error, as a trainee rolling the
    tool with the wrist keys or a hand turning a carried needle did.)"""
    psm = psm_sim.arms["PSM1"]
    q = psm.setpoint_jp()
    q[3] = 4.3
    assert psm.move_jp(q)
    assert psm_sim.run_until(lambda: not psm.is_busy(), 10)
    rolls = []
    for roll in np.linspace(4.3, 4.9, 300):  # 0.6 rad over 0.6 s, past 4.538
        q[3] = roll
        pose, _ = psm.forward_kinematics(q)
        psm.servo_cp(pose.T)
        psm_sim.run_for(0.002)
        rolls.append(psm.setpoint_jp()[3])
    assert psm.operating_state().state == "ENABLED"
    assert np.abs(np.diff(rolls)).max() < 0.01
    assert rolls[-1] == psm.chain.qmax[3]
    assert abs(psm.measured_js().position[3] - psm.chain.qmax[3]) < 0.02


def test_a_servo_goal_past_the_wrists_reach_is_refused_and_the_tool_held(psm_sim):
    """A goal the wrist can reach only on its other branch (the closed form has no answer on
    its own: here one a trainee's wrist key asked for with the yaw at its limit) is refused
    and the tool held, not taken: the roll and yaw would jump ~3 rad in one tick and the arm
    fault on its tracking error, where the dVRK's IK, iterating from the measured joints,
    stays on its branch."""
    psm = psm_sim.arms["PSM1"]
    here = np.array([0.1254, -0.1418, 0.1947, 0.1432, -1.1436, 1.39])
    there = np.array([0.1377, -0.2294, 0.203, 3.2672, -1.39, 0.0047])  # (its other branch)
    assert psm.move_jp(here)
    assert psm_sim.run_until(lambda: not psm.is_busy(), 10)
    goal, _ = psm.forward_kinematics(there)
    for _ in range(100):
        result = psm.servo_cp(goal.T)
        psm_sim.run_for(0.002)
    assert not result and "wrist's reach" in result.message
    assert psm.operating_state().state == "ENABLED"
    np.testing.assert_allclose(psm.setpoint_jp()[3:], here[3:], atol=0.02)
    # (a goal on the wrist's own branch is taken as before)
    near = here.copy()
    near[3] += 0.01
    assert psm.servo_cp(psm.forward_kinematics(near)[0].T)


# ------------------------------------------------------- b. effort-mode setpoints
def test_in_effort_mode_the_setpoint_follows_the_measured_joints(psm_sim):
    """dVRK PID: a joint in effort mode has setpoint = measured, so setpoint_js/setpoint_cp
    (and what a later position command starts from) are where the arm is."""
    psm = psm_sim.arms["PSM1"]
    q_before = psm.setpoint_jp()
    assert psm.servo_jf([0.3, 0, 0, 0, 0, 0])  # push yaw
    psm_sim.run_for(0.3)
    q = psm.measured_jp()
    assert abs(q[0] - q_before[0]) > 0.01  # it moved
    assert np.array_equal(psm.setpoint_jp(), q)
    assert np.array_equal(psm.setpoint_js().position, q)
    assert np.allclose(psm.setpoint_cp().T, psm.measured_cp().T, atol=1e-12)
    # A relative move starts from where the arm is, not from the stale position setpoint.
    assert psm.move_jr([0.05, 0, 0, 0, 0, 0])
    assert np.allclose(psm.setpoint_jp(), q, atol=1e-6)
    assert psm_sim.run_until(lambda: not psm.is_busy(), 10)
    assert psm.setpoint_jp()[0] == pytest.approx(q[0] + 0.05, abs=1e-9)
    assert psm.operating_state().state == "ENABLED"


def test_after_free_hold_keeps_the_arm_where_it_is(psm_sim):
    psm = psm_sim.arms["PSM1"]
    assert psm.servo_jf([0, -0.3, 0, 0, 0, 0])
    psm_sim.run_for(0.3)
    assert psm.free()
    q = psm.measured_jp()
    assert np.array_equal(psm.setpoint_jp(), q)
    assert psm.hold()
    psm_sim.run_for(0.2)
    assert np.allclose(psm.measured_jp(), q, atol=2e-3)


def test_mtm_setpoint_cp_follows_the_handle_in_effort_mode(mtm_sim):
    mtm = mtm_sim.arms["MTMR"]
    assert mtm.spatial.servo_cf([0.0, 0.0, 2.0, 0.0, 0.0, 0.0])
    mtm_sim.run_for(0.2)
    assert np.allclose(mtm.setpoint_cp().T, mtm.measured_cp().T, atol=1e-12)
    assert mtm.hold()
    mtm_sim.run_for(0.1)


# ------------------------------------------------- c. lock_orientation trajectory
def _rotation_angle(R):
    return math.acos(max(-1.0, min(1.0, (np.trace(R) - 1.0) / 2.0)))


def test_lock_orientation_moves_the_wrist_along_a_trajectory(mtm_sim):
    """dVRK MTM: the locked orientation is reached by a trajectory within the MTM's joint
    velocity and acceleration limits (dvrk.md 1.9), from where the wrist is."""
    mtm = mtm_sim.arms["MTMR"]
    dt = mtm_sim.dt
    assert mtm.body.servo_cf(np.zeros(6))  # effort mode, the handle free
    mtm_sim.run_for(0.1)
    q = mtm.measured_jp()
    q_target = q.copy()
    q_target[4] += 0.8  # wrist_pitch
    q_target[5] -= 0.4  # wrist_yaw
    pose, ok = mtm.forward_kinematics(q_target)
    assert ok
    R_goal = pose.T[:3, :3]
    assert mtm.lock_orientation(R_goal)
    v_max, a_max = mtm.kin.v_max[3:], mtm.kin.a_max[3:]
    wrist_prev = mtm.measured_jp()[3:]
    qd_prev = mtm.measured_js().velocity[3:]  # the trajectory starts from the wrist's motion
    worst_v, worst_a = 0.0, 0.0
    for _ in range(4000):
        mtm_sim.tick()
        wrist = mtm.setpoint_jp()[3:]
        qd = (wrist - wrist_prev) / dt
        worst_v = max(worst_v, float(np.max(np.abs(qd) / v_max)))
        worst_a = max(worst_a, float(np.max(np.abs(qd - qd_prev) / dt / a_max)))
        wrist_prev, qd_prev = wrist, qd
    assert mtm.operating_state().state == "ENABLED"  # no tracking fault
    assert worst_v <= 1.0 + 1e-6
    assert worst_a <= 1.0 + 1e-3
    R = mtm.measured_cp().T[:3, :3]
    assert _rotation_angle(R.T @ R_goal) < 0.01
    # Unlocked: the wrist is in effort mode again (its setpoint is where it is).
    assert mtm.unlock_orientation()
    mtm_sim.run_for(0.01)
    assert np.array_equal(mtm.setpoint_jp(), mtm.measured_jp())
    assert mtm.hold()


# ------------------------------------------------------ d. the jaw in the cannula
def test_the_jaw_moves_while_the_tool_is_inside_the_cannula(psm_sim):
    """The dVRK moves the jaw in joint space when Cartesian control is not allowed yet."""
    psm = psm_sim.arms["PSM1"]
    goal = psm.setpoint_jp()
    goal[2] = 0.02  # shaft end well inside the 43 mm of the cannula (dvrk.md 1.7)
    assert psm.move_jp(goal)
    assert psm_sim.run_until(lambda: not psm.is_busy(), 10)
    assert not psm.servo_cp(psm.setpoint_cp().T)  # Cartesian control: not here
    assert psm.jaw.move_jp(0.6)
    assert psm.is_busy()
    assert psm_sim.run_until(lambda: not psm.is_busy(), 5)
    psm_sim.run_for(0.2)
    assert psm.jaw.measured_js().position[0] == pytest.approx(0.6, abs=5e-3)
    assert psm.jaw.servo_jp(0.3)
    assert psm.jaw.setpoint_js().position[0] == pytest.approx(0.3, abs=1e-12)


# --------------------------------------------------- e. throttled "arm not ready"
def _errors(arm):
    seen = []
    arm.channels.subscribe(lambda event, msg: seen.append(msg.text) if event == "error" else None)
    return seen


def test_arm_not_ready_errors_are_throttled_every_2_s_as_the_dvrk_does():
    """dVRK ArmIsReady (dvrk.md 2.4): one "arm not ready" message per arm every 2 s whatever
    the command, with the count of the refusals since; the count restarts once ready."""
    sim = Simulation("psm1")
    psm = sim.arms["PSM1"]
    errors = _errors(psm)
    for i in range(5000):  # 5 s of a script polling every command at 1 kHz
        assert not [psm.move_jp, psm.servo_jp, psm.move_jr][i % 3]([0, 0, 0.12, 0, 0, 0])
        assert not psm.jaw.move_jp(0.3)
        sim.tick()
    assert len(errors) == 3  # at 0, 2 and 4 s
    assert all("arm not ready" in e for e in errors)
    # 2 s x 1 kHz x 2 commands, less the first (± a tick of the clock's rounding)
    count = int(re.search(r"\((\d+) more refusals", errors[1]).group(1))
    assert abs(count - 3999) <= 2
    home(sim, ["PSM1"])
    assert psm.move_jp(psm.setpoint_jp())  # ready: the count restarts
    assert psm.state_command("disable")
    n = len(errors)
    assert not psm.move_jp([0, 0, 0.12, 0, 0, 0])
    assert len(errors) == n + 1 and "more refusals" not in errors[-1]
    sim.close()


def test_cartesian_refusals_inside_the_cannula_are_said_once_per_1000(psm_sim):
    """dVRK SetControlSpaceAndMode: the warning once, then every 1000th consecutive attempt."""
    psm = psm_sim.arms["PSM1"]
    goal = psm.setpoint_jp()
    goal[2] = 0.02
    assert psm.move_jp(goal)
    assert psm_sim.run_until(lambda: not psm.is_busy(), 10)
    errors = _errors(psm)
    T = psm.setpoint_cp().T
    for _ in range(1001):
        assert not psm.move_cp(T)
    assert len(errors) == 2 and "past the cannula" in errors[0]
    assert "999 more refusals" in errors[1]


# ------------------------------------------------------------- g. servo_ci (MTM)
def _z_spring(z_goal_ref, p_pos=-200.0, p_neg=-200.0, T=None):
    from davinci_sim.sim.impedance import CartesianImpedance, HalfPlaneGains

    position = T[:3, 3].copy()
    position[2] = z_goal_ref
    return CartesianImpedance(
        force_position=position,
        position_positive=HalfPlaneGains(p=np.array([0.0, 0.0, p_pos]),
                                         d=np.array([0.0, 0.0, -5.0])),
        position_negative=HalfPlaneGains(p=np.array([0.0, 0.0, p_neg]),
                                         d=np.array([0.0, 0.0, -5.0])),
    )  # fmt: skip


def test_servo_ci_pulls_the_handle_to_the_spring_and_one_side_only(mtm_sim):
    """dvrk_mtm_cartesian_impedance.py: a z spring (dVRK signs: p < 0 pulls back) at a
    position of the reference frame (HRSV); a half-plane has gains on one side only."""
    mtm = mtm_sim.arms["MTMR"]
    assert mtm.hold()
    mtm_sim.run_for(0.1)
    T = mtm.measured_cp().T
    goal_z = T[2, 3] + 0.02  # 2 cm along HRSV z
    assert mtm.servo_ci(_z_spring(goal_z, T=T))
    assert mtm.impedance() is not None
    mtm_sim.run_for(1.5)
    assert abs(mtm.measured_cp().T[2, 3] - goal_z) < 0.005
    # half plane: the handle is below the plane (e < 0) where the gains are zero: no pull
    T = mtm.measured_cp().T
    assert mtm.servo_ci(_z_spring(T[2, 3] - 0.02, p_pos=0.0, p_neg=-500.0, T=T))
    z0 = T[2, 3]
    mtm_sim.run_for(0.5)
    assert abs(mtm.measured_cp().T[2, 3] - z0) < 0.005
    # another command ends the impedance
    assert mtm.spatial.servo_cf(np.zeros(6))
    mtm_sim.run_for(0.01)
    assert mtm.impedance() is None
    assert mtm.hold()


def test_servo_ci_refuses_bad_gains(mtm_sim):
    from davinci_sim.sim.impedance import CartesianImpedance, HalfPlaneGains

    mtm = mtm_sim.arms["MTMR"]
    bad = CartesianImpedance(position_positive=HalfPlaneGains(p=np.array([np.nan, 0, 0])))
    result = mtm.servo_ci(bad)
    assert not result and "position_positive.p" in result.message
    assert not mtm.servo_ci({"p": 1})
    assert mtm.impedance() is None
