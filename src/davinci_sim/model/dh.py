"""DH chains as MuJoCo bodies whose joint positions equal the dVRK joint values.

For every joint of a :class:`~davinci_sim.kinematics.chain.DHChain` one body, one joint and
(added later, see :mod:`davinci_sim.model.actuators`) one actuator are named
``<prefix>/<joint name>``. Offsets, θ and d live in the body frames, so MuJoCo's qpos is the
dVRK q (dvrk.md 1.1).

* Modified DH: body i relative to body i−1 is RotX(α)·TransX(a)·RotZ(θ+offset)·TransZ(d)
  (prismatic: …RotZ(θ)·TransZ(d+offset)) and the joint acts along/about the body's own z.
* Standard DH: the joint acts about the *parent's* z through the parent origin, before the
  link transform RotZ(θ+offset)·TransZ(d)·TransX(a)·RotX(α); the hinge is therefore given in
  the child frame as the parent's z axis and origin.

The body frames are computed at ``q_ref`` and the joints get ``ref = q_ref``: MuJoCo then
starts (``qpos0``) at that configuration while q keeps its dVRK meaning. A kinematic error
(``q_error``, the robot-inaccuracy option) shifts the refs instead: q still reads as the
arm's joint value while the links stand at ``q + q_error``.
"""

from __future__ import annotations

import mujoco
import numpy as np

from davinci_sim.kinematics.chain import DHChain
from davinci_sim.kinematics.fk import link_transforms
from davinci_sim.model.frames import set_pose


def add_dh_chain(parent, chain: DHChain, prefix: str, q_ref=None, q_error=None) -> list:
    """Add the bodies and joints of ``chain`` below ``parent``; returns the bodies in order.

    Args:
        parent: the MjSpec body whose frame is the chain base.
        chain: the DH chain.
        prefix: name prefix, e.g. ``"PSM1"`` or ``"SUJ/PSM1"``.
        q_ref: joint values of the initial configuration (default zeros).
        q_error: the robot's kinematic error (default zeros), rad or m per joint: the links
            stand at the chain's configuration ``q + q_error`` when MuJoCo's joint value (what
            the arm reads and servoes) is ``q`` (each joint's ``ref`` is ``q_ref − q_error``:
            the bodies, placed at ``q_ref``, turn by ``q − ref``).
    """
    q_ref = np.zeros(chain.dof) if q_ref is None else np.asarray(q_ref, dtype=float)
    q_error = np.zeros(chain.dof) if q_error is None else np.asarray(q_error, dtype=float)
    links = link_transforms(chain, q_ref)
    bodies = []
    body = parent
    for i, joint in enumerate(chain.joints):
        T_parent_child = links[i]
        child = body.add_body(name=f"{prefix}/{joint.name}")
        set_pose(child, T_parent_child)
        if chain.convention == "modified":
            axis, pos = np.array([0.0, 0.0, 1.0]), np.zeros(3)
        else:
            R, p = T_parent_child[:3, :3], T_parent_child[:3, 3]
            axis, pos = R.T @ np.array([0.0, 0.0, 1.0]), -R.T @ p
        child.add_joint(
            name=f"{prefix}/{joint.name}",
            type=mujoco.mjtJoint.mjJNT_HINGE if joint.is_revolute else mujoco.mjtJoint.mjJNT_SLIDE,
            axis=axis,
            pos=pos,
            ref=float(q_ref[i] - q_error[i]),
            range=[joint.qmin, joint.qmax],
            limited=mujoco.mjtLimited.mjLIMITED_TRUE,
        )
        bodies.append(child)
        body = child
    return bodies


def link_segments(
    chain: DHChain, index: int, q_ref=None
) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The straight pieces of link ``index`` as (body, start, end) in that body's frame.

    ``body`` is ``"parent"`` or ``"child"``: the piece of a modified-DH link along the
    parent's x (length a) is fixed in the parent; the piece along the joint axis (length d)
    and both pieces of a standard-DH link turn with the child. Prismatic pieces are omitted
    (their length changes). Zero-length pieces are omitted.
    """
    q_ref = np.zeros(chain.dof) if q_ref is None else np.asarray(q_ref, dtype=float)
    joint = chain.joints[index]
    T = link_transforms(chain, q_ref)[index]
    R, p = T[:3, :3], T[:3, 3]
    out: list[tuple[str, np.ndarray, np.ndarray]] = []
    if chain.convention == "modified":
        # Parent frame: RotX(α) keeps x, so the a-piece runs along the parent's x.
        foot = np.array([joint.a, 0.0, 0.0])
        if abs(joint.a) > 1e-9:
            out.append(("parent", np.zeros(3), foot))
        d = p - foot  # along the child's z, expressed in the parent frame
        if joint.is_revolute and np.linalg.norm(d) > 1e-9:
            out.append(("child", R.T @ (foot - p), np.zeros(3)))
    else:
        # Child frame: the parent origin is −Rᵀp; the d-piece runs along the parent's z up
        # to the point −a·x_child, then the a-piece along the child's x to the origin.
        parent_origin = -R.T @ p
        knee = np.array([-joint.a, 0.0, 0.0])
        if np.linalg.norm(knee - parent_origin) > 1e-9:
            out.append(("child", parent_origin, knee))
        if abs(joint.a) > 1e-9:
            out.append(("child", knee, np.zeros(3)))
    return out
