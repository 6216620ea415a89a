"""MTM iterative IK (dvrk.md 1.8): round trips, wrist-roll rule, failures.

Round trips sample every joint 5 % of its range inside the limits (the DLS may then move the
redundant platform a little without leaving them) and seed 0.05 rad (σ) away from the truth,
as a servo loop would. 7 joints for 6 DOF: the answer need not equal the truth, only reach it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from davinci_sim.kinematics.arms import load_arm
from davinci_sim.kinematics.fk import forward_kinematics
from davinci_sim.kinematics.mtm_ik import WRIST_ROLL, mtm_ik_iterative

TOL = 1e-6


@pytest.mark.parametrize("arm", ["MTML", "MTMR"])
def test_round_trips_1000(arm, rng):
    chain = load_arm(arm).chain
    margin = 0.05 * (chain.qmax - chain.qmin)
    Q = rng.uniform(chain.qmin + margin, chain.qmax - margin, size=(1000, 7))
    for q, T in zip(Q, forward_kinematics(chain, Q), strict=True):
        r = mtm_ik_iterative(chain, T, q + rng.normal(0.0, 0.05, 7))
        assert r.success, r.message
        assert r.position_error <= TOL and r.rotation_error <= TOL


def test_wrist_roll_nearest_current():
    kin = load_arm("MTMR")
    q = np.array([0.1, 0.3, 0.1, 0.5, 0.4, 0.2, 0.3])
    T = forward_kinematics(kin.chain, q)
    for turns in (1, -1):
        seed = q.copy()
        seed[WRIST_ROLL] += turns * 2 * math.pi + 0.01
        r = mtm_ik_iterative(kin.chain, T, seed)
        assert r.success, r.message
        # Redundant arm: the roll need not equal the truth, but it is the turn nearest the seed.
        assert abs(r.q[WRIST_ROLL] - seed[WRIST_ROLL]) < math.pi


def test_unreachable_goal_fails():
    kin = load_arm("MTML")
    T = forward_kinematics(kin.chain, kin.home)
    T[:3, 3] = [2.0, 0.0, 0.0]
    r = mtm_ik_iterative(kin.chain, T, kin.home)
    assert not r.success
    assert r.position_error > 1.0
    with pytest.raises(ValueError, match="7 joints"):
        mtm_ik_iterative(load_arm("PSM1").chain, T, np.zeros(6))
