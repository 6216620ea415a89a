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
