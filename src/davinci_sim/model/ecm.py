"""The Endoscopic Camera Manipulator with a straight Classic SD endoscope (dvrk.md 1.4).

Bodies/joints ``ECM/yaw``, ``pitch``, ``insertion``, ``roll`` below ``ECM/base`` (the RCM
frame). The endoscope (10 mm scope and camera head, 1.5 kg as the dVRK's gravity model
assumes for a Classic SD scope) rolls with the ``roll`` body, whose origin is the scope tip.
The stereo cameras ``ECM/left``/``ECM/right`` and the scope light sit at the tip frame.
"""

from __future__ import annotations

import mujoco
import numpy as np

from davinci_sim.kinematics.arms import ArmKinematics
from davinci_sim.model.cameras import CameraConfig, add_endoscope_cameras
from davinci_sim.model.frames import set_pose
from davinci_sim.model.rcm_arm import RCMArmShape, add_rcm_arm, design_frames, mount_uv
from davinci_sim.model.shapes import Painter, set_inertial

SCOPE_RADIUS = 0.005
"""The Classic endoscope is a 10-12 mm tube: 10 mm here."""

#: Masses, kg. Counterbalanced arm (COM on the yaw axis / at the RCM); the endoscope mass
#: is the dVRK's Classic SD value (dvrk.md 1.4) with its camera head at the back.
ECM_MASS = {"base": 4.0, "yaw": 3.0, "pitch": 5.0, "insertion": 0.4, "endoscope": 1.5}


def ecm_shape(T_sujtip_rcm: np.ndarray) -> RCMArmShape:
    """ECM proportions: longer than a PSM (0.61 m from the mount to the RCM)."""
    uv = mount_uv(T_sujtip_rcm)
    return RCMArmShape(
        mount_uv=uv,
        yaw_motor_u=(uv[0] - 0.06, uv[0] + 0.12),
        pivot_uv=(0.36, 0.08),
        back_link_length=0.46,
        rail_u=0.07,
        rail_v=(0.10, 0.66),
        link_half=0.024,
        link_w=0.07,
        cannula_radius=0.0075,
    )


def add_ecm(
    spec: mujoco.MjSpec, mount, arm: ArmKinematics, T_sujtip_rcm, q_ref, camera: CameraConfig
):
    """Add the ECM below the SUJ tip body ``mount``; returns the base body."""
    name = "ECM"
    chain = arm.chain
    shape = ecm_shape(np.asarray(T_sujtip_rcm))
    base, bodies = add_rcm_arm(
        spec, mount, name, chain, T_sujtip_rcm, q_ref, shape, "shell_dark", ECM_MASS
    )
    # Scope holder on the insertion stage.
    D = design_frames(chain)["insertion"]
    holder = Painter(bodies["insertion"], D, prefix=f"{name}/")
    holder.box([shape.rail_u, 0.0, 0], [0.026, 0.06, 0.04], "black")
    holder.box([0.03, 0.0, 0], [0.03, 0.03, 0.03], "carriage_ECM")
    set_inertial(bodies["insertion"], ECM_MASS["insertion"], [0.04, 0.0, 0], 2e-3, T_body_design=D)

    # Endoscope on the roll body: scope tube from the holder (insertion body origin) to
    # the tip (roll body origin), camera head and cable behind the holder.
    roll = bodies["roll"]
    length = chain.joints[3].d
    paint = Painter(roll, prefix=f"{name}/")
    paint.capsule([0, 0, -length], [0, 0, -0.003], SCOPE_RADIUS, "metal", kind="tool", name="scope")
    paint.cylinder([0, 0, -0.003], [0, 0, 0.0], SCOPE_RADIUS, "viewer_glass")
    paint.cylinder([0, 0, -length - 0.01], [0, 0, -length - 0.13], 0.028, "shell")
    paint.cylinder([0, 0, -length - 0.13], [0, 0, -length - 0.16], 0.018, "black")
    # Camera head (~1.2 kg) far back, scope (~0.3 kg) along the tube; both on the roll axis
    # so that gravity exerts no torque on roll.
    com_z = (1.2 * (-length - 0.07) + 0.3 * (-length / 2)) / 1.5
    m = ECM_MASS["endoscope"]
    set_inertial(roll, m, [0, 0, com_z], [0.03, 0.03, 5e-4])
    tip = roll.add_site(name=f"{name}/tip", size=[0.003, 0, 0])
    set_pose(tip, chain.T_last_tip)
    tip.group = 5
    add_endoscope_cameras(roll, chain.T_last_tip, camera)
    # The endoscope brings its own light (the abdomen is dark), pointing along the view.
    light = roll.add_light(name=f"{name}/light", castshadow=False)
    light.pos = [0.0, 0.0, 0.0]
    light.dir = chain.T_last_tip[:3, 2]
    light.diffuse = [0.9, 0.88, 0.85]
    light.specular = [0.3, 0.3, 0.3]
    light.cutoff = 70.0
    light.exponent = 2.0
    light.attenuation = [1.0, 0.0, 0.0]
    return base
