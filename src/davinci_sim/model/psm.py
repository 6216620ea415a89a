"""A Patient Side Manipulator with a large needle driver (dvrk.md 1.2).

Bodies/joints ``PSM<i>/yaw``, ``pitch``, ``insertion``, ``roll``, ``wrist_pitch``,
``wrist_yaw`` follow the modified-DH chain below ``PSM<i>/base`` (the RCM frame). The
instrument: a carriage and instrument housing on the insertion body, an 8 mm shaft on the
roll body whose axis is the roll body's z axis (it runs from the instrument mount at the
insertion body origin to the wrist at the roll body origin, and passes through the RCM by
construction), a wrist clevis and two jaws ``PSM<i>/jaw_1``/``jaw_2`` hinged on the
wrist-yaw axis (the EndoWrist jaws turn about the same axis as wrist yaw).
"""

from __future__ import annotations

import mujoco
import numpy as np

from davinci_sim.geometry.se3 import transform
from davinci_sim.kinematics.arms import ArmKinematics
from davinci_sim.model.frames import set_pose
from davinci_sim.model.rcm_arm import RCMArmShape, add_rcm_arm, design_frames, mount_uv
from davinci_sim.model.shapes import Painter, set_inertial

SHAFT_RADIUS = 0.004
"""Large needle driver: 8 mm shaft."""
JAW_LENGTH = 0.010
JAW_HALF_THICKNESS = 0.0011
JAW_HALF_WIDTH = 0.0018

#: Masses, kg. The parallelogram (PSM ≈ 5 kg of moving arm) is counterbalanced; the
#: carriage and the instrument (~0.3 kg) translate with insertion and load yaw/pitch with at
#: most ≈ 0.3 kg · 9.81 · 0.45 m ≈ 1.3 N·m < 0.5 · ftmax (3.3 N·m).
PSM_MASS = {
    "base": 3.0,
    "yaw": 2.0,
    "pitch": 3.0,
    "insertion": 0.22,
    "roll": 0.06,
    "wrist_pitch": 0.003,
    "wrist_yaw": 0.002,
    "jaw": 0.001,
}


def psm_shape(T_sujtip_rcm: np.ndarray) -> RCMArmShape:
    """PSM proportions (Classic): the yaw link reaches 0.49 m from the mount to the RCM."""
    uv = mount_uv(T_sujtip_rcm)
    return RCMArmShape(
        mount_uv=uv,
        yaw_motor_u=(uv[0] - 0.05, uv[0] + 0.10),
        pivot_uv=(0.27, 0.07),
        back_link_length=0.40,
        rail_u=0.05,
        rail_v=(0.09, 0.60),
        link_half=0.018,
        link_w=0.055,
        cannula_radius=0.0065,
    )


def add_psm(spec: mujoco.MjSpec, mount, name: str, arm: ArmKinematics, T_sujtip_rcm, q_ref,
            joint_errors=(0.0, 0.0, 0.0)):  # fmt: skip
    """Add ``name`` (PSM1/2/3) below the SUJ tip body ``mount``; returns the base body.
    ``joint_errors``: the kinematic error of the first three joints (outer yaw and pitch,
    rad; insertion, m; :attr:`~davinci_sim.model.config.SceneConfig.joint_errors`)."""
    chain = arm.chain
    q_error = np.zeros(chain.dof)
    q_error[:3] = joint_errors
    shape = psm_shape(np.asarray(T_sujtip_rcm))
    accent = f"carriage_{name}"
    base, bodies = add_rcm_arm(
        spec, mount, name, chain, T_sujtip_rcm, q_ref, shape, accent, PSM_MASS, q_error
    )
    _add_carriage(bodies["insertion"], name, shape, accent, chain)
    _add_instrument(bodies, name, arm)
    return base


def _add_carriage(insertion, name: str, shape: RCMArmShape, accent: str, chain) -> None:
    # Insertion body: origin = the instrument mount on the shaft axis, z = insertion
    # direction; drawn in D orientation (u back, v up the rail, w pitch axis).
    D = design_frames(chain)["insertion"]
    paint = Painter(insertion, D, prefix=f"{name}/")
    paint.box([shape.rail_u, 0.02, 0], [0.022, 0.05, 0.034], "black")
    paint.box([0.008, 0.05, 0], [0.03, 0.05, 0.032], accent)
    paint.box([-0.012, 0.05, 0], [0.012, 0.045, 0.036], "shell")
    set_inertial(insertion, PSM_MASS["insertion"], [0.02, 0.04, 0], 1e-3, T_body_design=D)


def _add_instrument(bodies: dict, name: str, arm: ArmKinematics) -> None:
    chain = arm.chain
    roll_d = chain.joints[3].d  # shaft length from the instrument mount to the wrist
    roll = bodies["roll"]
    paint = Painter(roll, prefix=f"{name}/")
    paint.capsule([0, 0, -roll_d], [0, 0, -0.004], SHAFT_RADIUS, "metal", kind="tool", name="shaft")
    paint.cylinder([0, 0, -0.03], [0, 0, -0.004], SHAFT_RADIUS + 0.0003, "black")
    site = roll.add_site(name=f"{name}/shaft_end", size=[0.003, 0, 0])
    site.group = 5
    m = PSM_MASS["roll"]
    # Shaft: a thin rod; its axial inertia is tiny, the roll drive's armature dominates.
    set_inertial(roll, m, [0, 0, -roll_d / 2], [m * roll_d**2 / 12, m * roll_d**2 / 12, 1e-6])

    # Wrist clevis: from the wrist-pitch axis (frame 5 origin) to the wrist-yaw axis, along x5.
    a6 = chain.joints[5].a
    wp = bodies["wrist_pitch"]
    wpaint = Painter(wp, prefix=f"{name}/")
    wpaint.capsule([0, 0, 0], [a6, 0, 0], 0.0036, "steel_dark", kind="tool", name="wrist")
    wpaint.cylinder([0, 0, -0.0035], [0, 0, 0.0035], 0.0032, "metal")
    set_inertial(wp, PSM_MASS["wrist_pitch"], [a6 / 2, 0, 0], 2e-8)

    wy = bodies["wrist_yaw"]
    Painter(wy, prefix=f"{name}/").cylinder([0, 0, -0.0028], [0, 0, 0.0028], 0.0026, "metal")
    set_inertial(wy, PSM_MASS["wrist_yaw"], [0, 0, 0], 1e-8)
    site = wy.add_site(name=f"{name}/tip", size=[0.002, 0, 0])
    set_pose(site, chain.T_last_tip)
    site.group = 5
    _add_jaws(wy, name, arm)


def _add_jaws(wrist_yaw, name: str, arm: ArmKinematics) -> None:
    """Two jaws hinged on the wrist-yaw axis (z of frame 6), pointing along the tip z (= y6).

    jaw_1 opens towards −x6 for positive angles, jaw_2 towards +x6; the dVRK jaw angle is
    their sum, so each gets half of the jaw range (dvrk.md 1.2: −40°…80° → −20°…40°).
    """
    jaw = arm.jaw
    tip_dir = arm.chain.T_last_tip[:3, 2]  # tip z in frame 6 = the jaw direction
    for i, side in ((1, -1.0), (2, 1.0)):
        body = wrist_yaw.add_body(name=f"{name}/jaw_{i}")
        body.add_joint(
            name=f"{name}/jaw_{i}",
            type=mujoco.mjtJoint.mjJNT_HINGE,
            axis=[0, 0, -side],
            range=[jaw.qmin / 2, jaw.qmax / 2],
            limited=mujoco.mjtLimited.mjLIMITED_TRUE,
        )
        # Jaw frame: x = closing side normal, y = along the jaw, z = hinge axis.
        R = np.column_stack([[side, 0, 0], tip_dir, np.cross([side, 0, 0], tip_dir)])
        paint = Painter(body, transform(R), prefix=f"{name}/")
        paint.box(
            [JAW_HALF_THICKNESS, JAW_LENGTH / 2 + 0.0005, 0],
            [JAW_HALF_THICKNESS, JAW_LENGTH / 2, JAW_HALF_WIDTH],
            "steel_dark",
            kind="tool",
            name=f"jaw_{i}",
        )
        com = R @ np.array([JAW_HALF_THICKNESS, JAW_LENGTH / 2, 0])
        set_inertial(body, PSM_MASS["jaw"], com, 2e-8)
