"""``IKResult.reached``: the goal is reached and only joint limits can fail the result (the
dVRK's arm clips such a solution to the limits, dvrk.md 1.8)."""

import numpy as np
import pytest

from davinci_sim.kinematics.arms import load_arm
from davinci_sim.kinematics.fk import forward_kinematics
from davinci_sim.kinematics.ik import inverse_kinematics


@pytest.mark.parametrize("method", ["closed_form", "reference"])
def test_a_psm_goal_past_a_wrist_limit_is_reached_but_not_a_success(method):
    kin = load_arm("PSM1")
    q = np.array([0.1, -0.2, 0.12, 0.3, kin.chain.qmax[4] + 0.05, 0.2])
    result = inverse_kinematics(kin, forward_kinematics(kin.chain, q), q, method=method)
    assert not result.success and result.reached
    assert "joint limits" in result.message
    inside = q.copy()
    inside[4] = 1.0
    ok = inverse_kinematics(kin, forward_kinematics(kin.chain, inside), inside, method=method)
    assert ok.success and ok.reached


@pytest.mark.parametrize("method", ["closed_form", "reference"])
def test_a_goal_the_solver_refuses_is_not_reached(method):
    kin = load_arm("PSM1")
    T = np.eye(4)  # at the RCM: the dVRK refuses goals within 1 mm of it (dvrk.md 1.8)
    result = inverse_kinematics(kin, T, kin.home, method=method)
    assert not result.success and not result.reached
