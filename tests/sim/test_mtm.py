"""MTM: wrench commands act on the model, gripper, base frame in HRSV."""

import numpy as np
from sim_helpers import home

from davinci_sim.sim.simulation import Simulation


def test_mtm_body_wrench_pushes_the_handle_and_is_clamped():
    sim = Simulation("psm1_ecm_mtmr")
    home(sim, ["MTMR"])
    mtm = sim.arms["MTMR"]
    assert mtm.measured_cp().reference_frame == "HRSV"
    p0 = mtm.measured_cp().position.copy()
    assert mtm.spatial.servo_cf([0.0, 0.0, 2.0, 0.0, 0.0, 0.0])  # 2 N along HRSV z
    sim.run_for(0.2)
    moved = mtm.measured_cp().position - p0
    assert moved[2] > 0.005  # pushed away from the operator
    effort = mtm.setpoint_js().effort
    assert np.all(np.abs(effort) <= mtm.chain.ftmax + 1e-12)
    bad = mtm.body.servo_cf([np.nan] * 6)
    assert not bad and "NaN" in bad.message


def test_mtm_gripper_is_an_input_and_measured():
    sim = Simulation("psm1_ecm_mtmr")
    mtm = sim.arms["MTMR"]
    assert mtm.gripper.servo_jp(np.radians(30))  # the operator's fingers, any arm state
    sim.run_for(0.5)
    assert abs(mtm.gripper.measured_js().position[0] - np.radians(30)) < 2e-3


def test_the_compiled_orientation_lock_is_the_python_lock_bit_for_bit(monkeypatch):
    """MTM._lock_step's one compiled call (the wrist's goal and its trajectory step) leaves
    the same wrist setpoints, tick by tick, as the Python lock (the goal's solve, then
    trajectory.step_towards)."""
    from davinci_sim.sim import arm_laws

    sim = Simulation("psm1_ecm_mtmr")
    home(sim)
    mtm = sim.arms["MTMR"]
    assert mtm.body.servo_cf(np.zeros(6))  # effort mode, the handle free
    sim.run_for(0.05)
    q = mtm.measured_jp()
    q[4] += 0.8
    q[5] -= 0.4
    R_goal = mtm.forward_kinematics(q)[0].T[:3, :3]
    start = sim.get_state()
    compiled_calls: list[bool] = []
    law = arm_laws.wrist_lock_step

    def counted(*args):
        answer = law(*args)
        compiled_calls.append(answer)
        return answer

    runs = []
    for step in (counted, lambda *args: False):  # (False: the Python path's lock)
        sim.set_state(start)
        monkeypatch.setattr(arm_laws, "wrist_lock_step", step)
        assert mtm.lock_orientation(R_goal)
        setpoints = []
        for _ in range(400):
            sim.tick()
            setpoints.append(mtm.setpoint_jp())
        runs.append((np.array(setpoints), sim.data.qpos.copy()))
    assert len(compiled_calls) == 400 and all(compiled_calls)
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    assert np.abs(runs[0][0][-1, 3:] - runs[0][0][0, 3:]).max() > 0.1  # (the wrist moved)
