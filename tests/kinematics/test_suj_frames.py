"""SUJ frame chain against dvrk.md 1.6 [derived] values (printed to 4 decimals: 5e-5)."""

from __future__ import annotations

import numpy as np
import pytest

from davinci_sim.geometry.se3 import invert_transform
from davinci_sim.kinematics.arms import load_arm, load_suj
from davinci_sim.kinematics.fk import forward_kinematics
from davinci_sim.kinematics.suj import T_cart_rcm, cart_frames

ATOL = 5e-5  # half the last printed digit

RCM_IN_CART = {
    "ECM": [0.0601, 1.2421, 0.9942],
    "PSM1": [-0.0288, 1.2198, 0.9591],
    "PSM2": [0.1843, 1.1877, 0.9742],
    "PSM3": [0.2128, 1.2254, 0.9115],
}
RCM_IN_CAMERA = {
    "PSM1": [-0.0877, -0.0060, -0.0771],
    "PSM2": [0.1266, 0.0201, -0.0724],
    "PSM3": [0.1534, -0.0518, -0.0555],
}


def test_derived_values_at_simulated_positions():
    frames = cart_frames()
    assert frames.reference_arm == "ECM"
    for name, p in RCM_IN_CART.items():
        np.testing.assert_allclose(frames.T_cart_rcm[name][:3, 3], p, rtol=0, atol=ATOL)
    np.testing.assert_allclose(
        frames.T_cart_camera[:3, 3], [0.0560, 1.1569, 0.9088], rtol=0, atol=ATOL
    )
    for name, p in RCM_IN_CAMERA.items():
        np.testing.assert_allclose(frames.base_frames[name][:3, 3], p, rtol=0, atol=ATOL)
    # The reference arm's base frame is its RCM in the cart (ECM/measured_cp = camera in cart).
    np.testing.assert_array_equal(frames.base_frames["ECM"], frames.T_cart_rcm["ECM"])


def test_psm_pose_in_camera_frame(psm):
    """measured_cp = base_frame · FK is the PSM tip seen from the ECM tip (camera)."""
    q_ecm = np.array([0.2, -0.1, 0.1, 0.3])
    frames = cart_frames(q_reference=q_ecm)
    ecm = load_arm("ECM")
    T_cart_cam = frames.T_cart_rcm["ECM"] @ forward_kinematics(ecm.chain, q_ecm)
    np.testing.assert_allclose(frames.T_cart_camera, T_cart_cam, atol=1e-12)
    T_rcm_tip = forward_kinematics(psm.chain, psm.home)
    measured = frames.base_frames["PSM2"] @ T_rcm_tip
    expected = invert_transform(T_cart_cam) @ frames.T_cart_rcm["PSM2"] @ T_rcm_tip
    np.testing.assert_allclose(measured, expected, atol=1e-12)
    for T in frames.base_frames.values():
        with pytest.raises(ValueError):
            T[0, 0] = 1.0  # read-only


def test_joint_overrides_and_reference_arm(psm):
    suj = load_suj()
    q = suj["PSM1"].simulated_position + 0.1
    frames = cart_frames({"PSM1": q}, reference_arm="PSM1", q_reference=psm.home)
    np.testing.assert_allclose(frames.T_cart_rcm["PSM1"], T_cart_rcm(suj["PSM1"], q))
    np.testing.assert_allclose(frames.T_cart_rcm["PSM2"][:3, 3], RCM_IN_CART["PSM2"], atol=ATOL)
    np.testing.assert_array_equal(frames.base_frames["PSM1"], frames.T_cart_rcm["PSM1"])
    cam = frames.T_cart_rcm["PSM1"] @ forward_kinematics(psm.chain, psm.home)
    np.testing.assert_allclose(
        frames.base_frames["ECM"], invert_transform(cam) @ frames.T_cart_rcm["ECM"], atol=1e-12
    )
    with pytest.raises(KeyError, match="known"):
        cart_frames({"PSM4": q})


def test_batched_rcm_and_inverse(rng):
    arm = load_suj()["PSM3"]
    Q = arm.simulated_position + rng.normal(0.0, 0.1, (5, 6))
    T = T_cart_rcm(arm, Q)
    assert T.shape == (5, 4, 4)
    for Ti, qi in zip(T, Q, strict=True):
        np.testing.assert_allclose(Ti, T_cart_rcm(arm, qi), atol=1e-12)
        np.testing.assert_allclose(invert_transform(Ti) @ Ti, np.eye(4), atol=1e-12)
