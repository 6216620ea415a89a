"""FK against the reference poses of dvrk.md 1.2, 1.4 and 1.5 ([derived] values).

Tolerances: 1e-6 where the reference prints enough digits; otherwise half the last printed
digit. The simple poses (q = 0, home) are exact numbers for exact right-angle twists, but the
JSON twists are ±1.5708, 3.7e-6 rad off ±π/2: positions then move by up to lever × 3.7e-6
(1.03e-6 for the MTM's 0.2794 m upper arm), so they get 2e-6; rotation entries printed as
exact 0/±1 differ by up to ~1.1e-5 and get 2e-5. (The SUJ values
of dvrk.md 1.6 are checked in test_suj_frames.py.)
"""

from __future__ import annotations

import numpy as np
import pytest

from davinci_sim.kinematics.arms import load_arm
from davinci_sim.kinematics.fk import forward_kinematics

ROUNDED_UNIT = 2e-5  # exact-looking 0/±1 rotation entries, see the module docstring
TWIST_SHIFT = 2e-6  # exact-looking positions, see the module docstring

PSM_R = [[0, 1, 0], [1, 0, 0], [0, 0, -1]]
ECM_R = [[1, 0, 0], [0, -1, 0], [0, 0, -1]]
MTM_R = [[0, 1, 0], [0, 0, 1], [1, 0, 0]]


@pytest.mark.parametrize(
    ("arm", "q", "p", "R"),
    [
        ("PSM1", [0, 0, 0, 0, 0, 0], [0, 0, 0.0065], PSM_R),  # dvrk.md 1.2, q = 0
        ("PSM2", [0, 0, 0.12, 0, 0, 0], [0, 0, -0.1135], PSM_R),  # 1.2, simulated home
        ("ECM", [0, 0, 0, 0], [0, 0, -0.0007], ECM_R),  # 1.4, q = 0
        ("ECM", [0, 0, 0.12, 0], [0, 0, -0.1207], ECM_R),  # 1.4, simulated home
        ("MTML", [0] * 7, [0, -0.3645, -0.1288], MTM_R),  # 1.5, local FK at q = 0
        ("MTMR", [0] * 7, [0, -0.3645, -0.1288], MTM_R),
    ],
)
def test_fk_reference_poses(arm, q, p, R):
    T = forward_kinematics(load_arm(arm).chain, np.array(q, dtype=float))
    np.testing.assert_allclose(T[:3, 3], p, rtol=0, atol=TWIST_SHIFT)
    np.testing.assert_allclose(T[:3, :3], R, rtol=0, atol=ROUNDED_UNIT)
    np.testing.assert_array_equal(T[3], [0, 0, 0, 1])


def test_fk_psm_general_configuration():
    """dvrk.md 1.2 third check; printed to 5 decimals, so tolerance 5e-6."""
    T = forward_kinematics(load_arm("PSM1").chain, np.array([0.3, -0.2, 0.1, 0.5, 0.2, -0.3]))
    atol = 5e-6 + 1e-12
    np.testing.assert_allclose(T[:3, 3], [0.02629, 0.01699, -0.08793], rtol=0, atol=atol)
    R = [
        [0.45592, 0.88785, -0.06205],
        [0.88241, -0.44183, 0.16164],
        [0.11610, -0.12845, -0.98490],
    ]
    np.testing.assert_allclose(T[:3, :3], R, rtol=0, atol=atol)


@pytest.mark.parametrize(("arm", "x"), [("MTML", 0.180), ("MTMR", -0.180)])
def test_fk_mtm_in_hrsv(arm, x):
    """dvrk.md 1.5: base frame (HRSV) · FK at q = 0; p printed to 4 decimals (5e-5), the
    rotation's 0.866 to 3 decimals (5e-4)."""
    kin = load_arm(arm)
    T = kin.T_reference_base @ forward_kinematics(kin.chain, np.zeros(7))
    np.testing.assert_allclose(T[:3, 3], [x, 0.0199, 0.4043], rtol=0, atol=5e-5)
    R = [[0, -1, 0], [0.5, 0, 0.866], [-0.866, 0, 0.5]]
    np.testing.assert_allclose(T[:3, :3], R, rtol=0, atol=5e-4)


def test_fk_psm_derived_geometry():
    """dvrk.md 1.2 [derived]: wrist-pitch axis at q₃ − 0.0156 from the RCM along the shaft."""
    chain = load_arm("PSM1").chain
    for q3 in (0.05, 0.12, 0.2):
        T4 = forward_kinematics(chain.truncated(4), np.array([0.2, -0.3, q3, 0.7]))
        assert abs(np.linalg.norm(T4[:3, 3]) - (q3 - 0.0156)) < 1e-12
