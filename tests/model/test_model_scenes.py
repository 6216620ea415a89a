"""Scenes build fast, follow the naming contract, and respect the dVRK effort limits."""

import mujoco
import numpy as np
import pytest

from davinci_sim.kinematics.arms import load_arm, load_suj
from davinci_sim.model import (
    SCENES,
    CameraConfig,
    ExternalCamera,
    SceneConfig,
    build_model,
    build_spec,
    scene_arms,
    servo_gains,
)
from davinci_sim.model.contact import TOOL_BIT


def _joint_names(arm: str) -> list[str]:
    kin = load_arm(arm)
    names = [f"{arm}/{j}" for j in kin.chain.joint_names]
    if kin.jaw is not None:
        names += [f"{arm}/jaw_1", f"{arm}/jaw_2"]
    if kin.gripper is not None:
        names += [f"{arm}/gripper_1", f"{arm}/gripper_2"]
    if arm in load_suj():
        names += [f"SUJ/{arm}/SUJ_{arm}_J{i}" for i in range(6)]
    return names


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_scene_builds_fast_with_contract_names(scene):
    """Every scene builds; bodies/joints/actuators/sites/cameras are named as agreed."""
    m = build_model(scene)
    assert m.opt.timestep == 0.001
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert np.allclose(m.opt.gravity, [0, 0, -9.81])
    arms = scene_arms(scene)
    for arm in arms:
        for name in _joint_names(arm):
            assert m.body(name).name == name
            assert m.joint(name).name == name
            assert m.actuator(name).trnid[0] == m.joint(name).id
        assert m.body(f"{arm}/base")
        assert m.site(f"{arm}/tip")
        if arm in load_suj():
            assert m.body(f"SUJ/{arm}/base")
            assert m.site(f"{arm}/rcm")
        if arm.startswith("PSM"):
            assert m.site(f"{arm}/shaft_end")
    assert ("ECM/left" in _names(m, "camera")) == ("ECM" in arms)
    assert "overview" in _names(m, "camera")
    if any(a.startswith("MTM") for a in arms):
        assert m.site("console/HRSV") and m.body("console/HRSV")
    if arms and arms[0].startswith("PSM"):
        assert m.body("cart")
    if SCENES[scene].include_patient:  # (the bead lies on the phantom)
        assert m.body("object/bead") and m.joint("object/bead")
    else:
        assert "object/bead" not in _names(m, "body")
    assert {m.key(i).name for i in range(m.nkey)} == {"home", "surgical"}
    # Only the contracted joints (plus the bead's free joint) exist.
    expected = {n for a in arms for n in _joint_names(a)}
    if SCENES[scene].include_patient:
        expected |= {"object/bead"}
    assert set(_names(m, "joint")) == expected
    assert set(_names(m, "actuator")) == expected - {"object/bead"}


def _names(m: mujoco.MjModel, kind: str) -> list[str]:
    n = {"camera": m.ncam, "joint": m.njnt, "actuator": m.nu, "body": m.nbody}[kind]
    return [getattr(m, kind)(i).name for i in range(n)]


def test_scene_config_validation_and_overrides():
    assert scene_arms("psm1") == ("PSM1", "ECM")
    assert scene_arms(SceneConfig(arms=("ECM", "PSM2"))) == ("PSM2", "ECM")
    with pytest.raises(ValueError, match="need the ECM"):
        SceneConfig(arms=("PSM1",))
    with pytest.raises(ValueError, match="unknown arms"):
        SceneConfig(arms=("PSM4", "ECM"))
    with pytest.raises(KeyError, match="known scenes"):
        build_spec("nope")
    with pytest.raises(TypeError, match="unknown SceneConfig fields"):
        build_spec("psm1", colour="red")
    cam = ExternalCamera("top", (0.1, 1.2, 2.5), (0.1, 1.2, 0.8), 30.0)
    m = build_model(
        "psm1", include_patient=False, cameras=(cam,), endoscope=CameraConfig(fovy_deg=60.0)
    )
    assert m.cam_fovy[m.camera("ECM/left").id] == pytest.approx(60.0)
    assert m.cam_fovy[m.camera("top").id] == pytest.approx(30.0)
    assert "object/bead" not in [m.body(i).name for i in range(m.nbody)]


def test_actuators_are_pd_servos_limited_to_ftmax(full_model):
    """force = kp (ctrl − q) − kv q̇ with kp, kv > 0, clamped to ±ftmax, no ctrl range."""
    m = full_model
    gains = servo_gains(m)
    assert np.all(gains.kp > 0) and np.all(gains.kv > 0)
    assert np.allclose(m.actuator_biasprm[:, 1], -gains.kp)
    assert np.all(m.actuator_ctrllimited == 0)
    for arm in ("PSM1", "ECM", "MTMR"):
        kin = load_arm(arm)
        for j in kin.chain.joints:
            i = m.actuator(f"{arm}/{j.name}").id
            assert np.allclose(m.actuator_forcerange[i], [-j.ftmax, j.ftmax])
    i = m.actuator("PSM1/jaw_1").id
    assert np.allclose(m.actuator_forcerange[i], [-0.16, 0.16])
    j = m.joint("PSM1/jaw_1").id
    assert np.allclose(m.jnt_range[j], np.radians([-20.0, 40.0]), atol=1e-5)
    j = m.joint("MTML/gripper_2").id
    # Each lever half of the gripper's −15° (squeezed past "just closed") … 60° (dvrk.md 1.5).
    assert np.allclose(m.jnt_range[j], np.radians([-7.5, 30.0]), atol=1e-4)


def test_servo_holds_keyframes_and_tracks_steps_without_overshoot(full_model):
    """With the sim's ctrl = q_ref + qfrc_bias/kp, joints hold still and steps settle."""
    m = full_model
    d = mujoco.MjData(m)
    gains = servo_gains(m)
    jid = m.actuator_trnid[:, 0]
    qadr, dof = m.jnt_qposadr[jid], m.jnt_dofadr[jid]
    mujoco.mj_resetDataKeyframe(m, d, m.key("surgical").id)
    q_ref = d.qpos[qadr].copy()
    # Small steps (unsaturated) on a few joints after 0.2 s.
    steps = {"PSM1/yaw": 2e-4, "PSM2/insertion": 2e-4, "ECM/pitch": 2e-4, "MTMR/elbow_pitch": 2e-3}
    idx = [gains.names.index(n) for n in steps]
    amp = np.array(list(steps.values()))
    trace = []
    for k in range(500):
        target = q_ref.copy()
        if k >= 200:
            target[idx] += amp
        d.ctrl[:] = target + d.qfrc_bias[dof] / gains.kp
        mujoco.mj_step(m, d)
        trace.append(d.qpos[qadr].copy())
        if k == 199:
            held = d.qpos[qadr].copy()
    trace = np.array(trace)
    # Joint limits (closed jaws/grippers at 0) make the servo press a little: 1 mrad.
    assert np.abs(held - q_ref).max() < 1e-3
    response = (trace[200:, idx] - held[idx]) / amp
    # A joint with dry friction (the MTM's drives) stops where the servo's pull kp·error
    # falls below it: within frictionloss / kp of the step.
    friction_band = m.dof_frictionloss[dof[idx]] / (gains.kp[idx] * amp)
    assert np.all(np.abs(response[-1] - 1.0) <= 0.02 + friction_band), response[-1]
    assert response.max() < 1.05


def test_gravity_torques_stay_within_half_ftmax(full_model):
    """qfrc_bias at rest ≤ 0.5·ftmax on every actuated joint, at home and random poses."""
    m = full_model
    d = mujoco.MjData(m)
    jid = m.actuator_trnid[:, 0]
    qadr, dof = m.jnt_qposadr[jid], m.jnt_dofadr[jid]
    limit = m.actuator_forcerange[:, 1]
    is_suj = np.array([m.actuator(i).name.startswith("SUJ/") for i in range(m.nu)])
    rng = np.random.default_rng(11)
    worst = np.zeros(m.nu)
    for k in range(200):
        mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
        if k:
            q = rng.uniform(m.jnt_range[jid, 0], m.jnt_range[jid, 1])
            # SUJ joints at their home pose (random SUJ poses put arms through the floor).
            q[is_suj] = d.qpos[qadr[is_suj]]
            d.qpos[qadr] = q
        mujoco.mj_forward(m, d)
        assert np.all(d.qfrc_gravcomp == 0.0)  # no hidden gravity compensation
        worst = np.maximum(worst, np.abs(d.qfrc_bias[dof]) / limit)
    assert worst.max() <= 0.5, m.actuator(int(np.argmax(worst))).name


def test_only_tools_environment_and_objects_collide(full_model):
    """Arm/console structure is visual; a tool never collides with its own arm's tools
    (the other arms' it does: tests/tasks/test_instruments_and_reset.py)."""
    m = full_model
    for g in range(m.ngeom):
        name = m.geom(g).name
        body = m.body(m.geom_bodyid[g]).name
        colliding = m.geom_contype[g] or m.geom_conaffinity[g]
        if m.geom_contype[g] & TOOL_BIT:
            assert m.geom_contype[g] & m.geom_conaffinity[g] == 0  # not with its own arm
            assert body.split("/")[-1] in {"roll", "wrist_pitch", "jaw_1", "jaw_2"}, name
        elif colliding:
            assert body in {"world", "table", "object/bead", "object/post"}, (name, body)
    tools = {m.geom(g).name for g in range(m.ngeom) if m.geom_contype[g] & TOOL_BIT}
    for arm in ("PSM1", "PSM2", "PSM3"):
        assert {f"{arm}/shaft", f"{arm}/wrist", f"{arm}/jaw_1", f"{arm}/jaw_2"} <= tools
    assert "ECM/scope" in tools
