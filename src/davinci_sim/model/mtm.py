"""A Master Tool Manipulator, MTML or MTMR (dvrk.md 1.5, standard DH, 7 joints + gripper).

Bodies/joints ``<MTM>/outer_yaw`` … ``wrist_roll`` below ``<MTM>/base`` (the MTM base frame,
z up). Each standard-DH body is the frame at the *end* of its link, so the upper arm
(a = 0.2794 m) is drawn on ``shoulder_pitch``, the forearm (a = 0.3645 m) on
``elbow_pitch`` and the wrist-platform drop (d = 0.1506 m) on ``wrist_platform``; the
gimbal (platform, pitch, yaw, roll axes crossing at one point) carries the handle with the
two gripper levers ``<MTM>/gripper_1``/``gripper_2`` (the gripper angle is their sum).
"""

from __future__ import annotations

import mujoco
import numpy as np

from davinci_sim.kinematics.arms import ArmKinematics
from davinci_sim.model.dh import add_dh_chain, link_segments
from davinci_sim.model.frames import set_pose
from davinci_sim.model.shapes import Painter, set_inertial

#: (mass kg, centre of mass in the body frame). The real MTM counterweights its forearm;
#: centres of mass close to the joint axes keep gravity torques below half the small MTM
#: effort limits (0.1 N·m for the wrist joints, dvrk.md 1.5).
MTM_MASS = {
    "outer_yaw": (0.8, None),
    "shoulder_pitch": (0.40, (-0.26, 0.0, 0.0)),
    "elbow_pitch": (0.20, (-0.36, 0.0, 0.0)),
    "wrist_platform": (0.04, None),
    "wrist_pitch": (0.025, (0.0, 0.0, 0.0)),
    "wrist_yaw": (0.018, (0.0, 0.0, 0.0)),
    "wrist_roll": (0.012, (0.0, 0.0, -0.01)),
}
GRIPPER_MASS = 0.003
HANDLE_LENGTH = 0.07
#: Where the operator's hand's mass sits, in the ``wrist_roll`` frame, m: at the MTM tip (the
#: gimbal centre), where the simulated hand's wrench acts (devices.SimulatedMTM). A mass
#: below the tip, pulled at the tip, makes the free gimbal swing like a pendulum under
#: lateral forces, a wobble a real grasp does not have.
HAND_GRIP = (0.0, 0.0, 0.0)


def add_mtm(parent, name: str, arm: ArmKinematics, q_ref=None):
    """Add ``name`` below ``parent`` (the HRSV body) at ``T_reference_base``; returns the base."""
    chain = arm.chain
    base = parent.add_body(name=f"{name}/base")
    set_pose(base, arm.T_reference_base)
    bpaint = Painter(base, prefix=f"{name}/")
    bpaint.cylinder([0, 0, 0.12], [0, 0, 0.02], 0.045, "mtm_dark")
    bodies = add_dh_chain(base, chain, name, q_ref)
    named = dict(zip(chain.joint_names, bodies, strict=True))
    owners = [base, *bodies]
    for i, joint in enumerate(chain.joints):
        body = bodies[i]
        segments = link_segments(chain, i, q_ref)
        for owner, p0, p1 in segments:
            target = owners[i] if owner == "parent" else owners[i + 1]
            radius = 0.018 if i < 3 else 0.012
            Painter(target).capsule(p0, p1, radius, "mtm")
        mass, com = MTM_MASS[joint.name]
        if com is None:  # on the joint axis, midway along the link's pieces
            pts = [p for _, p0, p1 in segments for p in (p0, p1)]
            com = np.mean(pts, axis=0) if pts else np.zeros(3)
            if joint.name == "outer_yaw":
                com = np.zeros(3)
        set_inertial(body, mass, com, max(mass * 0.05**2, 1e-5))
    # Joint housings: a disc on each proximal joint axis (in standard DH the joint i axis is
    # the parent's z: draw it on the parent body).
    for i in range(3):
        Painter(owners[i]).cylinder([0, 0, -0.03], [0, 0, 0.03], 0.03, "mtm_dark")
    _add_gimbal(named, name)
    return base


def _add_gimbal(bodies: dict, name: str) -> None:
    # Nested gimbal brackets: each body shows a bar along its own z (= next joint axis).
    for joint, half, radius in (
        ("wrist_platform", 0.05, 0.009),
        ("wrist_pitch", 0.04, 0.008),
        ("wrist_yaw", 0.03, 0.007),
    ):
        Painter(bodies[joint]).capsule([0, 0, -half], [0, 0, half], radius, "mtm_dark")
    roll = bodies["wrist_roll"]
    paint = Painter(roll, prefix=f"{name}/")
    paint.cylinder([0, 0, -HANDLE_LENGTH], [0, 0, 0.01], 0.011, "mtm")
    paint.sphere([0, 0, 0], 0.014, "mtm_dark")
    site = roll.add_site(name=f"{name}/tip", size=[0.004, 0, 0])
    site.group = 5  # T_last_tip is the identity for the MTMs (dvrk.md 1.5)
    for i, side in ((1, 1.0), (2, -1.0)):
        lever = roll.add_body(name=f"{name}/gripper_{i}", pos=[0, 0, -HANDLE_LENGTH + 0.01])
        lever.add_joint(
            name=f"{name}/gripper_{i}",
            type=mujoco.mjtJoint.mjJNT_HINGE,
            axis=[0, side, 0],
            # Half of the −15°…60° gripper range each: 0 is "just closed" (dvrk.md 4.1
            # gripper_scaling.zero); the fingers squeeze on past it to −15°, which the
            # teleoperation's jaw = s·gripper + o (s = 80°/60°, dvrk.md 4.2) makes −20°, the
            # dVRK's close (dvrk.md 3.2 p.jaw.close), for a full grip on what the jaws hold.
            range=[-0.1309, 0.5236],
            limited=mujoco.mjtLimited.mjLIMITED_TRUE,
        )
        p = Painter(lever, prefix=f"{name}/")
        p.bar([side * 0.013, 0, 0], [side * 0.013, 0, 0.05], 0.003, 0.008, "mtm_dark")
        p.cylinder([side * 0.02, -0.012, 0.045], [side * 0.02, 0.012, 0.045], 0.012, "black")
        set_inertial(lever, GRIPPER_MASS, [side * 0.013, 0, 0.03], 2e-6)
    # The operator's hand: a massless body at the grip until a simulated hand holds the
    # handle and gives it the limb's mass (devices.SimulatedMTM). Its weight is compensated
    # (gravcomp 1: the person carries their own arm), so the hand adds inertia, not load.
    hand = roll.add_body(name=f"{name}/hand", pos=list(HAND_GRIP))
    hand.explicitinertial = True
    hand.mass = 0.0
    hand.inertia = [0.0, 0.0, 0.0]
    hand.gravcomp = 1.0
