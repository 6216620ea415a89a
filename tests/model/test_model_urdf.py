"""The URDF generated from the model (model/urdf.py): parsed by a well-known URDF library
(yourdfpy), its forward kinematics equals MuJoCo's body poses for random configurations,
its names are the dVRK's, and what it leaves out (the floor, loose objects) is said."""

import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest
import yourdfpy

from davinci_sim.geometry.so3 import matrix_from_rpy, rpy_from_matrix
from davinci_sim.model.urdf import camera_frame, joint_name, link_name, robot_from_model


@pytest.fixture(scope="module")
def robot(full_model):
    return robot_from_model(full_model)


@pytest.fixture(scope="module")
def parsed(robot, tmp_path_factory):
    path = tmp_path_factory.mktemp("urdf") / "davinci.urdf"
    path.write_text(robot.to_xml())
    return yourdfpy.URDF.load(
        str(path), load_meshes=False, build_collision_scene_graph=False,
        load_collision_meshes=False,
    )  # fmt: skip


def _random_values(robot, rng):
    return {j.name: rng.uniform(j.lower, j.upper) for j in robot.joints if j.name in robot.actuated}


def _mujoco_link_pose(model, data, b):
    """World pose of body ``b``'s URDF link: the body frame, moved to its joint's anchor."""
    T = np.eye(4)
    T[:3, :3] = data.xmat[b].reshape(3, 3)
    T[:3, 3] = data.xpos[b]
    if model.body_jntnum[b] == 1:
        T[:3, 3] += T[:3, :3] @ model.jnt_pos[model.body_jntadr[b]]
    return T


def test_rpy_round_trip_and_convention():
    rng = np.random.default_rng(3)
    for _ in range(50):
        rpy = rng.uniform([-math.pi, -math.pi / 2, -math.pi], [math.pi, math.pi / 2, math.pi])
        np.testing.assert_allclose(rpy_from_matrix(matrix_from_rpy(*rpy)), rpy, atol=1e-9)
    # URDF's rpy: fixed axes x then y then z, i.e. R = Rz·Ry·Rx.
    R = matrix_from_rpy(0.0, 0.0, math.pi / 2)
    np.testing.assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    R = matrix_from_rpy(0.3, 0.2, 0.1)
    Rx = matrix_from_rpy(0.3, 0, 0)
    Ry = matrix_from_rpy(0, 0.2, 0)
    Rz = matrix_from_rpy(0, 0, 0.1)
    np.testing.assert_allclose(R, Rz @ Ry @ Rx, atol=1e-12)
    # near the lock (pitch within 1e-3 of ±90°, as the dVRK's link frames have), to rounding
    for _ in range(50):
        rpy = [rng.uniform(-3, 3), rng.choice([-1, 1]) * (math.pi / 2 - rng.uniform(0, 1e-3)),
               rng.uniform(-3, 3)]  # fmt: skip
        R = matrix_from_rpy(*rpy)
        np.testing.assert_allclose(matrix_from_rpy(*rpy_from_matrix(R)), R, atol=1e-14)
    # gimbal lock: the rotation is still reproduced
    R = matrix_from_rpy(0.4, math.pi / 2, -0.3)
    np.testing.assert_allclose(matrix_from_rpy(*rpy_from_matrix(R)), R, atol=1e-9)


def test_parses_with_every_body_joint_and_limit(full_model, robot, parsed):
    m = full_model
    assert parsed.robot.name == "davinci"
    assert parsed.base_link == "world"
    # every body but the world and the loose bead is a link; plus the parallelogram back
    # links (one per PSM/ECM) and the three cameras
    bodies = {link_name(m.body(b).name) for b in range(m.nbody)} - {"object_bead_link"}
    assert bodies <= set(parsed.link_map)
    extra = set(parsed.link_map) - bodies
    assert extra == {f"{a}_pitch_back_link" for a in ("PSM1", "PSM2", "PSM3", "ECM")} | {
        "ECM_left", "ECM_right", "overview"
    }  # fmt: skip
    # every hinge/slide joint, with its name, type, range
    for j in range(m.njnt):
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            continue
        name = m.joint(j).name
        joint = parsed.joint_map[joint_name(name)]
        expected_type = "revolute" if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE else "prismatic"
        assert joint.type == expected_type
        assert joint.limit.lower == pytest.approx(m.jnt_range[j][0])
        assert joint.limit.upper == pytest.approx(m.jnt_range[j][1])
        assert joint.limit.effort > 0
    # dVRK names: the arm's joints as measured_js names them, prefixed by the arm
    assert {"PSM1_yaw", "PSM1_pitch", "PSM1_insertion", "PSM1_roll", "PSM1_wrist_pitch",
            "PSM1_wrist_yaw", "PSM1_jaw_1", "PSM1_jaw_2", "SUJ_PSM1_J0", "ECM_roll",
            "MTML_wrist_roll", "MTMR_gripper_2"} <= set(parsed.actuated_joint_names)  # fmt: skip
    # velocity limits from the dVRK's trajectory limits where it has them (PSM yaw)
    assert parsed.joint_map["PSM1_yaw"].limit.velocity > 0
    assert set(parsed.actuated_joint_names) == set(robot.actuated)


def test_primitives_and_materials(full_model, robot):
    root = ET.fromstring(robot.to_xml())
    kinds = {g.tag for g in root.iter() if g.tag in ("box", "cylinder", "sphere", "mesh")}
    assert kinds == {"box", "cylinder", "sphere"}  # capsules: a cylinder and two spheres
    # every visual names a defined material with a colour
    materials = {m.get("name") for m in root.findall("material")}
    used = {m.get("name") for v in root.iter("visual") for m in v.iter("material")}
    assert used and used <= materials
    # every geom of the kept bodies is drawn: boxes, cylinders, spheres and 3 per capsule
    m = full_model
    G = mujoco.mjtGeom
    kept = [g for g in range(m.ngeom) if m.geom_bodyid[g] != 0
            and m.body(m.geom_bodyid[g]).name != "object/bead"]  # fmt: skip
    n = sum(3 if m.geom_type[g] == G.mjGEOM_CAPSULE else 1 for g in kept)
    assert len(root.findall("link/visual")) == n + 4  # + the four parallelogram back links
    # the floor plane (a world geom) is the room: left out
    assert all(s.link != "world" for s in robot.shapes)


def test_fk_equals_mujoco_for_random_configurations(full_model, robot, parsed):
    """Every link's pose from yourdfpy's FK of the written URDF equals MuJoCo's body pose
    (at the joint anchor) for random joint values within the limits."""
    m = full_model
    d = mujoco.MjData(m)
    rng = np.random.default_rng(7)
    for _ in range(4):
        values = _random_values(robot, rng)
        d.qpos[:] = m.qpos0
        for name, v in values.items():
            d.qpos[robot.qpos_addresses[name]] = v
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_camlight(m, d)  # camera poses
        assert robot.joint_values(d.qpos) == pytest.approx(values)
        parsed.update_cfg(values)
        own = robot.link_poses(values)
        compared = 0
        for b in range(1, m.nbody):
            link = link_name(m.body(b).name)
            if link not in parsed.link_map:
                continue
            T = _mujoco_link_pose(m, d, b)
            np.testing.assert_allclose(parsed.get_transform(link, "world"), T, atol=1e-9,
                                       err_msg=link)  # fmt: skip
            np.testing.assert_allclose(own[link], T, atol=1e-12, err_msg=link)
            compared += 1
        assert compared == m.nbody - 2  # all but the world and the bead
        # cameras: MuJoCo's camera frame turned to the ROS optical convention
        for c in range(m.ncam):
            frame = camera_frame(m.camera(c).name)
            T = parsed.get_transform(frame, "world")
            R_cam = d.cam_xmat[c].reshape(3, 3)
            np.testing.assert_allclose(T[:3, 3], d.cam_xpos[c], atol=1e-9)
            np.testing.assert_allclose(T[:3, 2], -R_cam[:, 2], atol=1e-9)  # z: the view
            np.testing.assert_allclose(T[:3, 1], -R_cam[:, 1], atol=1e-9)  # y: image down
        # the parallelogram's back link stays parallel to the instrument (pitch link) and
        # turns about the lower pivot
        for arm in ("PSM1", "PSM2", "PSM3", "ECM"):
            back = parsed.get_transform(f"{arm}_pitch_back_link", "world")
            pitch = parsed.get_transform(f"{arm}_pitch_link", "world")
            np.testing.assert_allclose(back[:3, :3], pitch[:3, :3], atol=1e-9)
            np.testing.assert_allclose(back[:3, 3], d.site(f"{arm}/parallelogram_lower").xpos,
                                       atol=1e-9)  # fmt: skip


def test_bad_model_is_refused():
    spec = mujoco.MjSpec()
    b = spec.worldbody.add_body(name="thing")
    b.add_geom(type=mujoco.mjtGeom.mjGEOM_ELLIPSOID, size=[0.1, 0.2, 0.3])
    b.add_joint(type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
    with pytest.raises(ValueError, match="ELLIPSOID"):
        robot_from_model(spec.compile())
    spec = mujoco.MjSpec()
    b = spec.worldbody.add_body(name="two")
    b.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.1, 0, 0])
    b.add_joint(type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
    b.add_joint(type=mujoco.mjtJoint.mjJNT_HINGE, axis=[1, 0, 0])
    with pytest.raises(ValueError, match="only one hinge"):
        robot_from_model(spec.compile())


def test_batched_transforms_equal_each_joint_alone(robot):
    """/tf's all-at-once transforms equal each joint's own (Joint.T_parent_child), mimic
    joints following their joint."""
    rng = np.random.default_rng(11)
    values = _random_values(robot, rng)
    batch = robot.moving_transforms(values)
    assert len(batch) == len(robot.moving) == len(robot.actuated) + 4
    for j, T in zip(robot.moving, batch, strict=True):
        q = values[j.mimic[0]] * j.mimic[1] + j.mimic[2] if j.mimic else values[j.name]
        np.testing.assert_allclose(T, j.T_parent_child(q), atol=1e-14, err_msg=j.name)


def test_each_arm_alone_as_the_dvrk_describes_it(full_model, robot, tmp_path):
    """Per-arm URDFs: the arm's links with the same names, joints named as its measured_js,
    and the same kinematics from its base."""
    from davinci_sim.kinematics.arms import load_arm, load_suj

    assert set(robot.arms) == {"PSM1", "PSM2", "PSM3", "ECM", "MTML", "MTMR", "SUJ/PSM1",
                               "SUJ/PSM2", "SUJ/PSM3", "SUJ/ECM"}  # fmt: skip
    values = _random_values(robot, np.random.default_rng(5))
    whole = robot.link_poses(values)
    for arm in robot.arms:
        part = robot.arm(arm)
        path = tmp_path / f"{arm.replace('/', '_')}.urdf"
        path.write_text(part.to_xml())
        parsed = yourdfpy.URDF.load(str(path), load_meshes=False)
        if arm.startswith("SUJ/"):
            names = load_suj()[arm[4:]].chain.joint_names
        else:
            names = load_arm(arm).chain.joint_names
        assert set(names) <= set(parsed.actuated_joint_names), arm
        assert set(part.links) <= set(robot.links)
        assert parsed.base_link == part.root == f"{arm.replace('/', '_')}_base_link"
        prefix = arm.replace("/", "_") + "_"
        own = {(n if arm.startswith("SUJ") else n.removeprefix(prefix)): v
               for n, v in values.items() if n.startswith(prefix)}  # fmt: skip
        poses = part.link_poses(own)
        T_world_root = whole[part.root]
        for link, T in poses.items():
            np.testing.assert_allclose(T_world_root @ T, whole[link], atol=1e-12, err_msg=link)
    with pytest.raises(KeyError, match="PSM7"):
        robot.arm("PSM7")
