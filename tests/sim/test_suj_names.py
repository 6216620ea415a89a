"""The setup joints carry the dVRK's names, SUJ_<arm>_J0…J5 (dvrk.md 1.6 and section 6)."""

from __future__ import annotations

import mujoco
import numpy as np

from davinci_sim.sim.simulation import Simulation


def test_measured_and_setpoint_js_name_the_setup_joints_as_the_dvrk():
    sim = Simulation("full")
    for arm in ("ECM", "PSM1", "PSM2", "PSM3"):
        expected = [f"SUJ_{arm}_J{i}" for i in range(6)]  # 6 for every arm, the ECM's too
        suj = sim.arms[f"SUJ/{arm}"]
        assert list(suj.measured_js().name) == expected
        assert list(suj.setpoint_js().name) == expected
        for name in expected:  # the model's joints: <prefix>/<dVRK name>, as every arm's
            assert mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_JOINT, f"SUJ/{arm}/{name}") >= 0
    sim.close()


def test_a_refusal_names_the_setup_joint():
    sim = Simulation("psm1")
    suj = sim.arms["SUJ/PSM1"]
    before = suj.setpoint_jp().copy()
    q = before.copy()
    q[0] = 5e3  # J0 (lift) is limited to +-2 m: clipped up to 1000 m, refused beyond
    result = suj.servo_jp(q)
    assert not result and "SUJ_PSM1_J0" in result.message
    assert np.array_equal(suj.setpoint_jp(), before)
    sim.close()
