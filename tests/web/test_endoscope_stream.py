"""The page's endoscope scene and pose messages against MuJoCo's own kinematics and the
camera model the server's images and heads-up display use."""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from davinci_sim.model import build_model
from davinci_sim.model.cameras import CameraConfig, project_left
from davinci_sim.web.endoscope_stream import (
    POSE_HEADER,
    PoseStream,
    decode_poses,
    pose_layout,
    scene_message,
)
from davinci_sim.web.scene3d_model import moving_bodies, visible_geoms


@pytest.fixture(scope="module")
def model():
    return build_model("psm1_ecm_mtmr")


def random_qpos(model, seed: int) -> np.ndarray:
    """Joint positions inside every limited joint's range (the others near qpos0)."""
    rng = np.random.default_rng(seed)
    q = model.qpos0.copy()
    for j in range(model.njnt):
        if model.jnt_type[j] not in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            continue
        lo, hi = model.jnt_range[j] if model.jnt_limited[j] else (-0.3, 0.3)
        q[model.jnt_qposadr[j]] = rng.uniform(lo, hi)
    return q


def test_a_pose_message_carries_mujocos_body_camera_and_light_poses(model):
    stream = PoseStream(model)
    reference = mujoco.MjData(model)
    for seed in range(5):
        q = random_qpos(model, seed)
        message = stream.message(q, tick=2**32 + 7, t=1.25)
        got = decode_poses(message, stream.layout)
        reference.qpos[:] = q
        mujoco.mj_kinematics(model, reference)
        mujoco.mj_camlight(model, reference)
        b = list(stream.layout.bodies)
        assert got["tick"] == 7 and got["time"] == 1.25  # (the tick's low 32 bits)
        np.testing.assert_allclose(got["bodies"][:, :3], reference.xpos[b], atol=2e-6)
        np.testing.assert_allclose(got["bodies"][:, 3:], reference.xquat[b], atol=2e-6)
        for k, c in enumerate(stream.layout.cameras):
            np.testing.assert_allclose(got["cameras"][k, :3], reference.cam_xpos[c], atol=2e-6)
            R = np.empty(9)
            mujoco.mju_quat2Mat(R, got["cameras"][k, 3:].astype(float))
            np.testing.assert_allclose(R, reference.cam_xmat[c], atol=2e-6)
        np.testing.assert_allclose(got["lights"][:, :3], reference.light_xpos, atol=2e-6)
        np.testing.assert_allclose(got["lights"][:, 3:], reference.light_xdir, atol=2e-6)


def test_the_layout_is_the_moving_bodies_that_are_drawn_and_both_eyes(model):
    layout = pose_layout(model)
    drawn = {g.body for g in visible_geoms(model)}
    assert set(layout.bodies) == {int(b) for b in moving_bodies(model)} & drawn
    assert [model.camera(c).name for c in layout.cameras] == ["ECM/left", "ECM/right"]
    message = PoseStream(model).message(model.qpos0, 0, 0.0)
    assert len(message) == POSE_HEADER.size + 4 * layout.size


def test_bad_joint_positions_are_refused_and_change_nothing(model):
    stream = PoseStream(model)
    before = stream.message(model.qpos0, 1, 0.0)
    for bad in (np.zeros(model.nq + 1), np.full(model.nq, np.nan)):
        with pytest.raises(ValueError, match="qpos"):
            stream.message(bad, 2, 0.0)
    np.testing.assert_array_equal(stream.data.qpos, model.qpos0)
    assert stream.message(model.qpos0, 1, 0.0) == before


def test_the_scene_has_every_drawn_geom_and_the_endoscopes_camera(model):
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    config = CameraConfig()
    scene = json.loads(json.dumps(scene_message(model, data, config.baseline_m)))  # JSON-ready
    assert [g["id"] for g in scene["geoms"]] == [g.geom for g in visible_geoms(model)]
    for eye in scene["cameras"]:
        assert eye["fovy_deg"] == config.fovy_deg
        assert (eye["width"], eye["height"]) == (config.width, config.height)
    extent = model.stat.extent
    assert scene["znear"] == pytest.approx(model.vis.map.znear * extent)
    assert scene["zfar"] == pytest.approx(model.vis.map.zfar * extent)
    for body, pose in scene["bodies"].items():
        b = int(body)
        np.testing.assert_allclose(pose, np.concatenate([data.xpos[b], data.xquat[b]]))


def test_the_pages_projection_puts_a_point_on_the_servers_pixel(model):
    """The page's camera (the streamed pose as its world matrix, the projection from fovy,
    aspect and the clip planes, as three.js builds it) maps the tool tip to the pixel
    ``project_left`` gives for it in the ECM's camera frame: the heads-up display's marks
    sit on the drawn tool."""
    config = CameraConfig()
    stream = PoseStream(model)
    scene = stream.scene(config.baseline_m)
    eye = scene["cameras"][0]
    tip = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "PSM1/tip")
    ecm = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "ECM/tip")
    data = mujoco.MjData(model)
    key = model.key("surgical").id
    for dq in np.linspace(-0.05, 0.05, 3):
        q = model.key_qpos[key].copy() + dq
        got = decode_poses(stream.message(q, 0, 0.0), stream.layout)
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        p_world = data.site_xpos[tip]
        # the page: world -> left camera (its pose inverted) -> clip -> pixel
        R = np.empty(9)
        mujoco.mju_quat2Mat(R, got["cameras"][0, 3:].astype(float))
        R = R.reshape(3, 3)
        p_eye = R.T @ (p_world - got["cameras"][0, :3])
        f = 1.0 / np.tan(np.radians(eye["fovy_deg"]) / 2)
        aspect = eye["width"] / eye["height"]
        x_ndc, y_ndc = f / aspect * p_eye[0] / -p_eye[2], f * p_eye[1] / -p_eye[2]
        pixel_page = ((x_ndc + 1) / 2 * eye["width"], (1 - y_ndc) / 2 * eye["height"])
        # the server: the tip in the ECM's camera frame, through project_left
        R_ecm = data.site_xmat[ecm].reshape(3, 3)
        p_camera = R_ecm.T @ (p_world - data.site_xpos[ecm])
        pixel_server = project_left(p_camera, config)
        assert pixel_server is not None
        np.testing.assert_allclose(pixel_page, pixel_server, atol=0.05)
