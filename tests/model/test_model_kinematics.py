"""The generated bodies reproduce the dVRK kinematics exactly (dvrk.md 1.1-1.6)."""

import mujoco
import numpy as np
import pytest
from model_test_utils import body_pose, set_joints, site_pose

from davinci_sim.kinematics.arms import load_arm, load_suj
from davinci_sim.kinematics.fk import forward_kinematics

N_RANDOM = 250


def _rotation_angle(R: np.ndarray) -> float:
    return float(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))


@pytest.mark.parametrize("arm", ["PSM1", "PSM2", "PSM3", "ECM", "MTML", "MTMR"])
def test_tip_site_matches_dvrk_fk(full_model, arm):
    """<ARM>/tip in <ARM>/base equals FK(chain, q) (incl. tooltip offset) for random q."""
    m = full_model
    d = mujoco.MjData(m)
    chain = load_arm(arm).chain
    base, tip = m.body(f"{arm}/base").id, m.site(f"{arm}/tip").id
    rng = np.random.default_rng(hash(arm) % 2**32)
    for q in rng.uniform(chain.qmin, chain.qmax, size=(N_RANDOM, chain.dof)):
        set_joints(m, d, arm, chain.joint_names, q)
        mujoco.mj_kinematics(m, d)
        T_base_tip = np.linalg.inv(body_pose(d, base)) @ site_pose(d, tip)
        T_ref = forward_kinematics(chain, q)
        assert np.linalg.norm(T_base_tip[:3, 3] - T_ref[:3, 3]) <= 1e-6
        assert _rotation_angle(T_base_tip[:3, :3].T @ T_ref[:3, :3]) <= 1e-6


@pytest.mark.parametrize("arm", ["ECM", "PSM1", "PSM2", "PSM3"])
def test_rcm_matches_suj_fk(full_model, arm):
    """The RCM in the cart frame = T_cart_sujbase · FK(SUJ, q) · T_sujtip_rcm (dvrk.md 1.6)."""
    m = full_model
    d = mujoco.MjData(m)
    suj = load_suj()[arm]
    rng = np.random.default_rng(7)
    lo = np.array([-0.3, -np.pi, -np.pi, -np.pi, -np.pi, -np.pi])
    for q in rng.uniform(lo, -lo, size=(50, 6)):
        set_joints(m, d, f"SUJ/{arm}", suj.chain.joint_names, q)
        mujoco.mj_kinematics(m, d)
        T_ref = suj.T_cart_sujbase @ forward_kinematics(suj.chain, q) @ suj.T_sujtip_rcm
        T_base = body_pose(d, m.body(f"{arm}/base").id)
        assert np.allclose(T_base[:3, 3], T_ref[:3, 3], atol=1e-9)
        assert _rotation_angle(T_base[:3, :3].T @ T_ref[:3, :3]) <= 1e-6
        assert np.allclose(d.site_xpos[m.site(f"{arm}/rcm").id], T_ref[:3, 3], atol=1e-9)


def test_home_keyframe_rcms_match_dvrk_derived_values(full_model):
    """Keyframe home = qpos0: SUJ at simulated_position gives dvrk.md 1.6's RCMs."""
    m = full_model
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
    assert np.array_equal(d.qpos, m.qpos0)
    mujoco.mj_kinematics(m, d)
    expected = {
        "ECM": (0.0601, 1.2421, 0.9942),
        "PSM1": (-0.0288, 1.2198, 0.9591),
        "PSM2": (0.1843, 1.1877, 0.9742),
        "PSM3": (0.2128, 1.2254, 0.9115),
    }
    for arm, p in expected.items():
        assert np.allclose(d.site_xpos[m.site(f"{arm}/rcm").id], p, atol=1e-4)
    # ECM tip at its home in the cart (dvrk.md 1.6 [derived]).
    assert np.allclose(d.site_xpos[m.site("ECM/tip").id], (0.0560, 1.1569, 0.9088), atol=1e-4)
    for arm in ("PSM1", "PSM2", "PSM3", "ECM", "MTML", "MTMR"):
        kin = load_arm(arm)
        for name, q in zip(kin.chain.joint_names, kin.home, strict=True):
            assert d.qpos[m.jnt_qposadr[m.joint(f"{arm}/{name}").id]] == pytest.approx(q)


@pytest.mark.parametrize("arm", ["PSM1", "PSM2", "PSM3"])
def test_shaft_axis_passes_through_rcm(full_model, arm):
    """The instrument shaft (z of the roll body) always passes through the RCM."""
    m = full_model
    d = mujoco.MjData(m)
    chain = load_arm(arm).chain
    roll = m.body(f"{arm}/roll").id
    rcm = m.site(f"{arm}/rcm").id
    shaft = m.geom(f"{arm}/shaft").id
    rng = np.random.default_rng(3)
    for q in rng.uniform(chain.qmin, chain.qmax, size=(N_RANDOM, chain.dof)):
        set_joints(m, d, arm, chain.joint_names, q)
        mujoco.mj_kinematics(m, d)
        p, axis = d.xpos[roll], d.xmat[roll].reshape(3, 3)[:, 2]
        r = d.site_xpos[rcm] - p
        assert np.linalg.norm(r - np.dot(r, axis) * axis) <= 1e-6
        # The shaft geom lies on that axis, and the shaft-end site is the link-4 origin.
        g = d.geom_xpos[shaft] - p
        assert np.linalg.norm(g - np.dot(g, axis) * axis) <= 1e-9
        assert np.allclose(d.site_xpos[m.site(f"{arm}/shaft_end").id], p)


def test_endoscope_cameras_follow_the_tip_frame(full_model):
    """ECM/left and ECM/right: tip frame turned 180° about y, ±baseline/2 along tip x."""
    m = full_model
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("surgical").id)
    mujoco.mj_forward(m, d)  # cameras are placed by mj_camlight, after mj_kinematics
    T_tip = site_pose(d, m.site("ECM/tip").id)
    flip = np.diag([-1.0, 1.0, -1.0])
    for name, side in (("left", 1.0), ("right", -1.0)):
        c = m.camera(f"ECM/{name}").id
        assert np.allclose(d.cam_xmat[c].reshape(3, 3), T_tip[:3, :3] @ flip, atol=1e-9)
        expected = T_tip[:3, 3] + side * 0.0025 * T_tip[:3, 0]
        assert np.allclose(d.cam_xpos[c], expected, atol=1e-9)
        assert m.cam_fovy[c] == pytest.approx(45.0)
