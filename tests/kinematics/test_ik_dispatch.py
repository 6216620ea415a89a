"""inverse_kinematics picks the solver by arm type; shared IK helpers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from davinci_sim.kinematics.arms import ArmKinematics, load_arm, load_suj
from davinci_sim.kinematics.fk import forward_kinematics
from davinci_sim.kinematics.ik import inverse_kinematics
from davinci_sim.kinematics.ik_base import nearest_turn, pose_errors, wrap_angle


@pytest.mark.parametrize("arm", ["PSM1", "PSM2", "PSM3", "ECM", "MTML", "MTMR"])
@pytest.mark.parametrize("method", ["default", "reference"])
def test_every_arm_round_trips(arm, method):
    kin = load_arm(arm)
    q = kin.home + 0.1
    r = inverse_kinematics(kin, forward_kinematics(kin.chain, q), kin.home, method=method)
    assert r.success, r.message
    assert r.position_error <= 1e-9 and r.rotation_error <= 1e-9


def test_method_selects_solver():
    kin = load_arm("PSM1")
    T = forward_kinematics(kin.chain, kin.home + 0.1)
    closed = inverse_kinematics(kin, T, kin.home, method="closed_form")
    reference = inverse_kinematics(kin, T, kin.home, method="reference")
    np.testing.assert_allclose(closed.q, reference.q, atol=1e-9)
    assert reference.iterations > closed.iterations  # DLS steps vs. wrist fixed-point steps
    with pytest.raises(ValueError, match="available"):
        inverse_kinematics(load_arm("MTML"), T, np.zeros(7), method="closed_form")


def test_other_arm_types_use_generic_dls():
    suj = load_suj()["PSM1"]
    kin = ArmKinematics(
        arm_type="SUJ",  # type: ignore[arg-type]
        chain=suj.chain,
        home=suj.simulated_position,
        v_max=np.ones(6),
        a_max=np.ones(6),
        goal_tolerance=np.ones(6),
    )
    q = suj.simulated_position + 0.05
    r = inverse_kinematics(kin, forward_kinematics(suj.chain, q), suj.simulated_position)
    assert r.success, r.message
    np.testing.assert_allclose(r.q, q, atol=1e-8)


def test_bad_input_raises_value_error():
    kin = load_arm("ECM")
    with pytest.raises(ValueError, match="finite"):
        inverse_kinematics(kin, np.full((4, 4), np.nan), kin.home)
    with pytest.raises(ValueError, match="shape"):
        inverse_kinematics(kin, np.eye(3), kin.home)


def test_helpers():
    assert wrap_angle(math.pi) == pytest.approx(math.pi)
    assert wrap_angle(-math.pi) == pytest.approx(math.pi)
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert nearest_turn(0.1, 6.0) == pytest.approx(0.1 + 2 * math.pi)
    eye = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    c, s = math.cos(1e-10), math.sin(1e-10)
    tiny = (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 3e-12)
    dp, dr = pose_errors(eye, tiny)
    assert dp == pytest.approx(3e-12) and dr == pytest.approx(1e-10, rel=1e-6)
