"""The remote-centre-of-motion arm shared by the PSMs and the ECM (dvrk.md 1.2, 1.4).

The first three DH joints (yaw, pitch, insertion) of both arm types have the same α and
offsets, so their bodies have the same axes. The shapes are drawn in the *pitch plane*
design frame D = (u, v, w) with its origin at the RCM:

* u: along the yaw axis, from the RCM back towards the SUJ mount;
* v: "up" along the instrument at pitch 0 (the insertion direction is −v);
* w = u × v: the pitch axis.

D is fixed in the yaw body, equals the pitch body frame, and (rotation only) is fixed in the
insertion body. The real arms are parallelograms that keep the instrument pivoting about
the RCM. A rigid body can only hold part of a parallelogram, so the yaw body carries the
yaw link and the lower pivot, the pitch body carries the top link, the insertion rail and
the cannula, and the back link is a tendon drawn between the lower pivot (yaw body) and the
top link (pitch body): it always connects the two, though its length changes a little with
pitch. All of this is visual; masses are set so that gravity torques stay small (see
:func:`set_counterbalanced_inertials`).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from davinci_sim.kinematics.chain import DHChain
from davinci_sim.kinematics.fk import joint_frames
from davinci_sim.model.dh import add_dh_chain
from davinci_sim.model.frames import set_pose
from davinci_sim.model.shapes import Painter, set_inertial


@dataclass(frozen=True)
class RCMArmShape:
    """Dimensions of the visual RCM arm in the pitch-plane frame D (m)."""

    mount_uv: tuple[float, float]
    """The SUJ mount point (from ``T_sujtip_rcm``)."""
    yaw_motor_u: tuple[float, float]
    """Extent of the yaw motor housing along u (on the fixed base)."""
    pivot_uv: tuple[float, float]
    """Lower parallelogram pivot on the yaw link."""
    back_link_length: float
    rail_u: float
    """Offset of the insertion rail from the instrument axis."""
    rail_v: tuple[float, float]
    link_half: float
    """Half thickness of the parallelogram links."""
    link_w: float
    """Offset of the parallelogram plane from the instrument plane (along w)."""
    cannula_radius: float


def design_frames(chain: DHChain) -> dict[str, np.ndarray]:
    """``T_<body>_D`` for the bodies ``base``, ``yaw``, ``pitch`` and ``insertion``.

    Computed at q = 0, where the pitch body frame *is* D; each relation is constant since D
    is attached to the corresponding body (for the insertion body only the rotation is kept:
    its design origin is the instrument mount point, the body origin).
    """
    F = joint_frames(chain, np.zeros(chain.dof))
    T_base_D = F[2]
    out = {
        "base": T_base_D,
        "yaw": np.linalg.inv(F[1]) @ T_base_D,
        "pitch": np.eye(4),
    }
    T_ins = np.eye(4)
    T_ins[:3, :3] = F[3][:3, :3].T @ T_base_D[:3, :3]
    out["insertion"] = T_ins
    return out


def add_rcm_arm_shapes(
    spec: mujoco.MjSpec,
    name: str,
    base,
    yaw,
    pitch,
    chain: DHChain,
    shape: RCMArmShape,
    accent: str,
) -> None:
    """Draw the fixed base, yaw link and parallelogram of one PSM/ECM."""
    D = design_frames(chain)
    mu, mv = shape.mount_uv
    lw = shape.link_w
    h = shape.link_half
    # Fixed part: the bracket from the SUJ mount up to the yaw axis, the yaw motor.
    base_paint = Painter(base, D["base"], prefix=f"{name}/")
    base_paint.bar([mu, mv, 0], [mu, 0.0, 0], 0.045, 0.05, "shell", up=[1, 0, 0])
    base_paint.cylinder([shape.yaw_motor_u[1], 0, 0], [shape.yaw_motor_u[0], 0, 0], 0.06, "shell")
    base_paint.cylinder(
        [shape.yaw_motor_u[0] - 0.005, 0, 0], [shape.yaw_motor_u[0] - 0.02, 0, 0], 0.062, accent
    )
    # Yaw body: the yaw link along the axis, rising to the lower pivot of the parallelogram.
    pu, pv = shape.pivot_uv
    yaw_paint = Painter(yaw, D["yaw"], prefix=f"{name}/")
    yaw_paint.bar(
        [shape.yaw_motor_u[0], 0, 0], [pu + 0.02, 0, 0], 0.05, 0.045, "shell", up=[0, 1, 0]
    )
    yaw_paint.bar([pu + 0.02, 0, 0], [pu, pv, 0], 0.05, 0.045, "shell", up=[0, 0, 1])
    yaw_paint.cylinder([pu, pv, -0.06], [pu, pv, lw + 0.03], 0.045, "shell")
    yaw_site = yaw.add_site(name=f"{name}/parallelogram_lower", size=[0.005, 0, 0])
    yaw_site.pos = D["yaw"][:3, :3] @ np.array([pu, pv, lw]) + D["yaw"][:3, 3]
    yaw_site.group = 5
    # Pitch body: top link, insertion rail, cannula. The top link's far end P1 sits above
    # the pivot (P0 + L·v at pitch 0); the near end meets the rail.
    L = shape.back_link_length
    p1 = np.array([pu, pv + L, lw])
    rail_top = np.array([shape.rail_u, shape.rail_v[1], 0.0])
    pitch_paint = Painter(pitch, D["pitch"], prefix=f"{name}/")
    pitch_paint.bar(p1, [shape.rail_u, pv + L - 0.02, lw], h, h, "link_red", up=[0, 0, 1])
    pitch_paint.cylinder(p1 - [0, 0, h + 0.01], p1 + [0, 0, h + 0.01], h + 0.005, "shell_dark")
    pitch_paint.bar(
        [shape.rail_u, pv + L - 0.02, lw], [shape.rail_u, pv + L - 0.02, 0.0], h, h, "link_red"
    )
    pitch_paint.bar(
        [shape.rail_u, shape.rail_v[0], 0], rail_top, 0.018, 0.026, "black", up=[0, 0, 1]
    )
    pitch_paint.bar([shape.rail_u, rail_top[1], 0], [0.0, rail_top[1], 0], 0.02, 0.02, "black")
    cannula_top = shape.rail_v[0] + 0.02
    pitch_paint.bar([shape.rail_u, cannula_top, 0], [0, cannula_top, 0], 0.02, 0.02, "shell_dark")
    pitch_paint.cylinder([0, cannula_top + 0.02, 0], [0, -0.025, 0], shape.cannula_radius, "metal")
    pitch_site = pitch.add_site(name=f"{name}/parallelogram_upper", size=[0.005, 0, 0])
    pitch_site.pos = p1
    pitch_site.group = 5
    # Back link, parallel to the instrument: a tendon always joins the pivot and the top link.
    tendon = spec.add_tendon(
        name=f"{name}/parallelogram", width=h * 1.1, rgba=[0.93, 0.85, 0.25, 1]
    )
    tendon.wrap_site(f"{name}/parallelogram_lower")
    tendon.wrap_site(f"{name}/parallelogram_upper")


def set_counterbalanced_inertials(
    chain: DHChain,
    base,
    yaw,
    pitch,
    *,
    base_mass: float,
    yaw_mass: float,
    pitch_mass: float,
    mount_uv: tuple[float, float],
) -> None:
    """Masses of the fixed base, yaw link and parallelogram.

    The real PSM/ECM are mechanically counterbalanced (the PSM's yaw/pitch motors have only
    3.3 N·m, dvrk.md 1.2). The yaw link's centre of mass is put on the yaw axis and that of
    the parallelogram at the RCM, where the yaw and pitch axes cross: this is what the
    counterweights achieve, and gravity then exerts no torque on yaw and pitch whatever the
    pose. Only the parts that translate with the insertion stage load these joints.
    """
    D = design_frames(chain)
    set_inertial(
        base,
        base_mass,
        [mount_uv[0] + 0.02, 0.3 * mount_uv[1], 0],
        base_mass * 0.1**2,
        T_body_design=D["base"],
    )
    set_inertial(
        yaw, yaw_mass, [mount_uv[0] * 0.65, 0, 0], yaw_mass * 0.15**2, T_body_design=D["yaw"]
    )
    set_inertial(pitch, pitch_mass, [0, 0, 0], pitch_mass * 0.32**2, T_body_design=D["pitch"])


def mount_uv(T_sujtip_rcm) -> tuple[float, float]:
    """The SUJ tip (the arm's mount) in the design plane (u, v) of the RCM base frame, m:
    u = −y_base and v = +z_base at yaw 0 (see :func:`design_frames`)."""
    T = np.asarray(T_sujtip_rcm, dtype=float)
    mount = -T[:3, :3].T @ T[:3, 3]  # SUJ tip in the RCM frame
    return (float(-mount[1]), float(mount[2]))


def add_rcm_arm(
    spec: mujoco.MjSpec,
    mount,
    name: str,
    chain: DHChain,
    T_sujtip_rcm,
    q_ref,
    shape: RCMArmShape,
    accent: str,
    masses: dict[str, float],
    q_error=None,
):
    """What a PSM and the ECM have in common: the base body at the RCM below the SUJ tip
    ``mount`` (with an ``<name>/rcm`` site), the DH chain's bodies, the yaw link and
    parallelogram shapes, and counterbalanced inertials (``masses``: base, yaw, pitch, kg);
    ``q_error``: the chain's kinematic error (:func:`~davinci_sim.model.dh.add_dh_chain`).
    Returns ``(base body, {joint name: body})``."""
    base = mount.add_body(name=f"{name}/base")
    set_pose(base, T_sujtip_rcm)
    rcm = base.add_site(name=f"{name}/rcm", size=[0.006, 0, 0], rgba=[1, 0.2, 0.2, 0.5])
    rcm.group = 5
    chain_bodies = add_dh_chain(base, chain, name, q_ref, q_error)
    bodies = dict(zip(chain.joint_names, chain_bodies, strict=True))
    add_rcm_arm_shapes(spec, name, base, bodies["yaw"], bodies["pitch"], chain, shape, accent)
    set_counterbalanced_inertials(
        chain,
        base,
        bodies["yaw"],
        bodies["pitch"],
        base_mass=masses["base"],
        yaw_mass=masses["yaw"],
        pitch_mass=masses["pitch"],
        mount_uv=shape.mount_uv,
    )
    return base, bodies
