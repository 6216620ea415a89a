"""Build the MuJoCo model of a scene: :func:`build_spec` and :func:`build_model`.

The world frame is the dVRK cart frame (z up, origin on the floor at the cart). Tree:
``cart`` → ``SUJ/<ARM>/base`` → ``SUJ/<ARM>/SUJ_<ARM>_J0…J5`` → ``<ARM>/base`` (RCM) → arm joints;
``console`` → ``console/HRSV`` → ``MTM<L|R>/base`` → arm joints; ``table``; ``object/bead``.

Keyframes:

* ``home`` (also the model's ``qpos0``): SUJ at the dVRK ``simulated_position``, PSMs and ECM
  at their dVRK homing goal (zeros, insertion 0.12 m, dvrk.md 1.7), MTMs at zero, jaws and
  grippers closed, ``ctrl`` = those joint values.
* ``surgical``: the same, but the ECM's setup joints posed (:data:`ECM_SUJ_SURGICAL`) so
  that the endoscope sees the instruments. With the dVRK's simulated SUJ values the PSM
  tips at home are ≈ 83° off the endoscope axis, next to and behind the camera.
"""

from __future__ import annotations

import mujoco
import numpy as np

from davinci_sim.kinematics.arms import load_arm, load_suj
from davinci_sim.kinematics.fk import forward_kinematics
from davinci_sim.model import appearance
from davinci_sim.model.actuators import JointServoSpec, add_actuators, tune_gains
from davinci_sim.model.cameras import OVERVIEW, add_external_camera
from davinci_sim.model.config import SceneConfig, resolve_scene
from davinci_sim.model.console import add_console
from davinci_sim.model.ecm import add_ecm
from davinci_sim.model.patient import (
    PAD_CENTER_XY,
    TISSUE_SURFACE_Z,
    add_bead,
    add_floor,
    add_table,
    bead_rest_height,
)
from davinci_sim.model.psm import add_psm
from davinci_sim.model.suj import add_cart, add_suj_arm

TIMESTEP = 0.001

#: ECM setup joints J0…J5 of the ``surgical`` keyframe. Solved (least squares, offline) so
#: that the optical axis of the endoscope at its home insertion passes ≈ 0.2 m from the
#: camera through the middle of the three PSM tips at home; the ECM port (RCM) moves from
#: (0.06, 1.24, 0.99) to (0.27, 1.38, 1.05) m and all tips fall within the 45° view.
ECM_SUJ_SURGICAL = np.array([0.7101, -0.0996, 0.0, 2.5138, 0.2744, 0.0])

#: Natural frequency (Hz) and armature of each joint servo, by joint name. Armature stands
#: for the reflected motor/gearbox inertia of the real drives.
_PSM_SERVO = {
    "yaw": (15.0, 0.05),
    "pitch": (15.0, 0.05),
    "insertion": (15.0, 0.5),
    "roll": (20.0, 2e-4),
    "wrist_pitch": (20.0, 1e-4),
    "wrist_yaw": (20.0, 1e-4),
    "jaw": (20.0, 5e-5),
}
_ECM_SERVO = {
    "yaw": (12.0, 0.2),
    "pitch": (12.0, 0.2),
    "insertion": (12.0, 1.0),
    "roll": (15.0, 1e-3),
}
_MTM_SERVO = {
    "outer_yaw": (12.0, 2e-3),
    "shoulder_pitch": (12.0, 2e-3),
    "elbow_pitch": (12.0, 2e-3),
    "wrist_platform": (15.0, 5e-4),
    "wrist_pitch": (15.0, 2e-4),
    "wrist_yaw": (15.0, 2e-4),
    "wrist_roll": (15.0, 2e-4),
    "gripper": (10.0, 2e-5),
}
#: Viscous (N·m·s/rad) and dry (N·m) friction of the MTM's drives, by joint (our choices:
#: dvrk.md gives no friction). A real MTM's motors, capstans and cables are never
#: frictionless: left alone in effort mode it stays where it is, a position hold ends a
#: little off its setpoint (static friction against the PID), and it damps a haptic wall
#: closed over ROS. The values are the smallest of the order of a drive's friction with
#: which an unheld MTM pushed with 3 N into crtk_python_client's haptic box (500 N/m,
#: closed at 200 Hz on ``measured_cp`` published every 10 ms, dvrk.md 2.2) settles at the
#: wall instead of oscillating, up to 40 ms of loop latency; without them a position hold
#: is exact to 1e-16 rad (a frictionless joint and an exact gravity compensation), which no
#: real MTM reading is. The gripper is the operator's fingers: no friction.
_MTM_FRICTION = {
    "outer_yaw": (1.0, 0.05),
    "shoulder_pitch": (1.0, 0.05),
    "elbow_pitch": (1.0, 0.05),
    "wrist_platform": (0.01, 0.002),
    "wrist_pitch": (0.01, 0.002),
    "wrist_yaw": (0.01, 0.002),
    "wrist_roll": (0.01, 0.002),
}
#: The SUJ joints are braked on the real cart. Their servos stand for the brakes: stiff
#: (10 Hz with a large armature) and with effort limits far above the ≈ 350 N on a lift and
#: the ≈ 100 N·m on a tilt joint that the carried arm causes, so they never slip.
_SUJ_SERVO = {"prismatic": (10.0, 20.0, 2000.0), "revolute": (10.0, 2.0, 1000.0)}
#: The MTM gripper is passive on the real console (no motor, dvrk.md 1.5 gives no ftmax);
#: its simulated actuator stands for the operator's fingers.
_MTM_GRIPPER_FTMAX = 0.5


def _servo_specs(config: SceneConfig) -> list[JointServoSpec]:
    servos: list[JointServoSpec] = []
    suj = load_suj()
    for arm_name in config.arms:
        arm = load_arm(arm_name)
        if arm_name in config.patient_side_arms:
            for j in suj[arm_name].chain.joints:
                f, armature, ftmax = _SUJ_SERVO[j.joint_type]
                servos.append(JointServoSpec(f"SUJ/{arm_name}/{j.name}", ftmax, f, armature))
        table = {"PSM": _PSM_SERVO, "ECM": _ECM_SERVO, "MTM": _MTM_SERVO}[arm.arm_type]
        friction = _MTM_FRICTION if arm.arm_type == "MTM" else {}
        for j in arm.chain.joints:
            f, armature = table[j.name]
            viscous, coulomb = friction.get(j.name, (0.0, 0.0))
            servos.append(
                JointServoSpec(
                    f"{arm_name}/{j.name}",
                    j.ftmax,
                    f,
                    armature,
                    viscous_friction=viscous,
                    coulomb_friction=coulomb,
                )  # fmt: skip
            )
        if arm.jaw is not None:
            # jaw = q1 + q2, so by virtual work a jaw effort τ acts as τ on each finger:
            # each finger actuator gets the full jaw ftmax (0.16 N·m, dvrk.md 1.2).
            f, armature = table["jaw"]
            for i in (1, 2):
                servos.append(JointServoSpec(f"{arm_name}/jaw_{i}", arm.jaw.ftmax, f, armature))
        if arm.gripper is not None:
            f, armature = table["gripper"]
            for i in (1, 2):
                servos.append(
                    JointServoSpec(f"{arm_name}/gripper_{i}", _MTM_GRIPPER_FTMAX, f, armature)
                )
    return servos


def _bead_pose(config: SceneConfig) -> tuple[np.ndarray, float]:
    """Bead on its post, on PSM1's instrument axis at home, square to its jaws."""
    z = TISSUE_SURFACE_Z + bead_rest_height()
    if "PSM1" not in config.arms:
        return np.array([PAD_CENTER_XY[0], PAD_CENTER_XY[1], z]), 0.0
    suj = load_suj()["PSM1"]
    arm = load_arm("PSM1")
    T_cart_rcm = (
        suj.T_cart_sujbase
        @ forward_kinematics(suj.chain, suj.simulated_position)
        @ suj.T_sujtip_rcm
    )
    T_cart_tip = T_cart_rcm @ forward_kinematics(arm.chain, arm.home)
    tip, axis = T_cart_tip[:3, 3], T_cart_tip[:3, 2]
    p = tip + axis * (z - tip[2]) / axis[2]
    closing = T_cart_tip[:3, 1]  # the jaws close along the tip y axis (= frame 6 x)
    return p, float(np.arctan2(closing[1], closing[0]))


def build_spec(scene: str | SceneConfig = "full", **overrides) -> mujoco.MjSpec:
    """The MjSpec of ``scene`` (a name from :data:`SCENES` or a :class:`SceneConfig`).

    Args:
        scene: scene name or configuration.
        **overrides: :class:`SceneConfig` fields to replace, e.g. ``include_patient=False``.

    Returns:
        A spec with all bodies, actuators (gains tuned) and the ``home``/``surgical``
        keyframes; ``spec.compile()`` gives the model.
    """
    config = resolve_scene(scene, **overrides)
    spec = mujoco.MjSpec()
    spec.modelname = "davinci"
    spec.option.timestep = TIMESTEP
    spec.option.gravity = [0.0, 0.0, -9.81]
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    # Elliptic friction cones with a high impratio make friction nearly hard, so that a bead
    # squeezed between two angled jaws does not creep out (MuJoCo's advice for grasping).
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 10.0
    # Explicit inertials everywhere: visual geoms carry no mass.
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.compiler.autolimits = True
    spec.compiler.degree = False  # joint ranges and refs are in rad (dVRK units)
    appearance.add_materials(spec)
    cam = config.endoscope
    appearance.configure_visual(spec, offwidth=max(1280, cam.width), offheight=max(960, cam.height))
    world = spec.worldbody
    appearance.add_room_lights(world)
    add_floor(world)

    suj = load_suj()
    if config.patient_side_arms:
        cart = add_cart(world)
        for name in config.patient_side_arms:
            s = suj[name]
            suj_bodies = add_suj_arm(cart, s, s.simulated_position)
            arm = load_arm(name)
            if name == "ECM":
                add_ecm(spec, suj_bodies[-1], arm, s.T_sujtip_rcm, arm.home, cam)
            else:
                add_psm(spec, suj_bodies[-1], name, arm, s.T_sujtip_rcm, arm.home,
                        config.errors_of(name))  # fmt: skip
    if config.include_patient:
        add_table(world)
        position, yaw = _bead_pose(config)
        add_bead(world, position, yaw)
    if config.include_console or config.mtms:
        add_console(world, config.mtms)
    add_external_camera(world, OVERVIEW)
    for c in config.cameras:
        add_external_camera(world, c)

    servos = _servo_specs(config)
    add_actuators(spec, servos)
    model = spec.compile()
    qpos_home = model.qpos0.copy()
    tune_gains(spec, model, qpos_home, servos)
    _add_keyframes(spec, model, qpos_home, servos, config)
    return spec


def _add_keyframes(spec, model, qpos_home, servos, config: SceneConfig) -> None:
    adr = {s.joint: model.jnt_qposadr[model.joint(s.joint).id] for s in servos}
    qpos_surgical = qpos_home.copy()
    if "ECM" in config.arms:
        for i, j in enumerate(load_suj()["ECM"].chain.joints):
            qpos_surgical[adr[f"SUJ/ECM/{j.name}"]] = ECM_SUJ_SURGICAL[i]
    for name, qpos in (("home", qpos_home), ("surgical", qpos_surgical)):
        ctrl = np.array([qpos[adr[s.joint]] for s in servos])
        spec.add_key(name=name, qpos=qpos, ctrl=ctrl)


def build_model(scene: str | SceneConfig = "full", **overrides) -> mujoco.MjModel:
    """The compiled model of ``scene`` (see :func:`build_spec`)."""
    return build_spec(scene, **overrides).compile()
