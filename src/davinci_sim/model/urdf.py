"""The URDF of a scene, generated from its compiled MuJoCo model (``davinci-sim urdf``).

:func:`robot_from_model` reads the bodies, joints, primitive geoms, cameras and parallelogram
tendons of a compiled :class:`mujoco.MjModel` (the one :func:`~davinci_sim.model.build_model`
makes from the dVRK kinematics) and returns a :class:`Robot`: a frozen value that writes the
URDF (:meth:`Robot.to_xml`) and gives every joint's transform at given joint values
(:meth:`Robot.transforms`, what ``robot_state_publisher`` computes; the bridge's
``/tf``, ``/tf_static`` and ``/joint_states`` come from it). :meth:`Robot.arm` is one arm
alone, as the dVRK's launch files describe each arm (its joints named as its
``measured_js``).

Names (frames as the dVRK's URDF spells them, joints as the bridge publishes them):

* links: the MuJoCo body ``PSM1/yaw`` → ``PSM1_yaw_link``, ``SUJ/PSM1/SUJ_PSM1_J0`` →
  ``SUJ_PSM1_J0_link``; the world body → ``world``; the cart → ``Cart`` and the console's
  stereo viewer → ``HRSV``, the dVRK's reference frames that ``measured_cp`` on ``/tf``
  already names, so those frames hang in the same tree;
* joints: ``PSM1/yaw`` → ``PSM1_yaw``, ``SUJ/PSM1/SUJ_PSM1_J0`` → ``SUJ_PSM1_J0`` (the
  dVRK joint names, prefixed by the arm where they are not already); the jaw's two fingers
  ``PSM1_jaw_1``/``_2`` and the MTM gripper's ``MTML_gripper_1``/``_2`` (the dVRK's jaw
  and gripper angles are their sums); values in rad and m, equal to MuJoCo's ``qpos`` and
  to the dVRK's joint values;
* cameras: a fixed link per camera in the ROS optical convention (x right, y down, z along
  the view): ``ECM_left``/``ECM_right``, the ``frame_id`` of the endoscope's images, and
  ``overview``.

A link frame is its MuJoCo body frame, except where the body's joint is not at the body's
origin (the MTM shoulder, elbow and platform joints): URDF puts a link's frame on its joint,
so there the link frame is the body frame moved to the joint's anchor (same orientation).

Closed chains: URDF describes trees. The MuJoCo model is a tree too; each PSM/ECM
parallelogram's back link is a tendon drawn between the yaw and pitch bodies. Here, as in
the dVRK's own URDF, it becomes a link ``<ARM>_pitch_back_link`` on a joint that mimics
``<ARM>_pitch`` (multiplier 1), hinged at the lower pivot: it stays parallel to the
instrument, which is what the parallelogram does. Geometry: boxes, cylinders and spheres
as URDF primitives, a capsule as a cylinder and two spheres; the scene's fixed bodies (the
operating table, the bead's post) are fixed links; the floor plane and free bodies (loose
objects such as the bead) are left out. Limits: MuJoCo's joint ranges; effort the joint
servo's force range; velocity the dVRK's trajectory limit where the dVRK gives one, else 0
(the braked setup joints and the MTM's passive gripper have none: read 0 as "not given").
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from functools import cached_property

import mujoco
import numpy as np

from davinci_sim.geometry.se3 import transform
from davinci_sim.geometry.so3 import rotation_from_vector
from davinci_sim.kinematics.arms import ARM_FILES, load_arm

ROOT = "world"
#: MuJoCo bodies whose link takes a dVRK reference frame's name (dvrk.md 2.1).
FRAME_NAMES = {"world": ROOT, "cart": "Cart", "console/HRSV": "HRSV"}
#: ROS optical frame (x right, y down, z forward) in MuJoCo's camera frame (x right, y up,
#: looking along −z).
R_CAMERA_OPTICAL = np.diag([1.0, -1.0, -1.0])

_J = mujoco.mjtJoint
_G = mujoco.mjtGeom


def _collapse(name: str) -> str:
    """``A/B/C`` → ``A_B_C``, or ``C`` alone when it already starts with ``A_B_``."""
    parts = name.split("/")
    head = "_".join(parts[:-1])
    if head and parts[-1].startswith(head + "_"):
        return parts[-1]
    return "_".join(parts)


def link_name(body: str) -> str:
    """URDF link (and tf frame) of the MuJoCo body ``body`` (see the module docstring)."""
    return FRAME_NAMES.get(body, _collapse(body) + "_link")


def joint_name(joint: str) -> str:
    """URDF joint of the MuJoCo joint ``joint``: ``PSM1/yaw`` → ``PSM1_yaw``."""
    return _collapse(joint)


def camera_frame(camera: str) -> str:
    """Optical frame of the MuJoCo camera ``camera``: ``ECM/left`` → ``ECM_left``."""
    return camera.replace("/", "_")


# =========================================================================== values
@dataclass(frozen=True, eq=False)
class Joint:
    """One URDF joint: ``T_parent_child(q) = T_parent_origin · motion(q)``.

    ``axis`` is a unit vector in the origin (= child) frame; ``q`` in rad (revolute) or m
    (prismatic). ``source``: the MuJoCo joint it stands for (None: fixed or mimic);
    ``mimic``: ``(joint, multiplier, offset)``, its value is ``multiplier·q + offset``.
    """

    name: str
    type: str
    parent: str
    child: str
    T_parent_origin: np.ndarray
    axis: np.ndarray
    lower: float = 0.0
    upper: float = 0.0
    effort: float = 0.0
    velocity: float = 0.0
    source: str | None = None
    mimic: tuple[str, float, float] | None = None

    def T_parent_child(self, q: float = 0.0) -> np.ndarray:
        """Pose of the child link in the parent link at joint value ``q``."""
        if self.type == "fixed":
            return self.T_parent_origin
        if self.type == "prismatic":
            return self.T_parent_origin @ transform(p=self.axis * q)
        return self.T_parent_origin @ transform(rotation_from_vector(self.axis * q))


@dataclass(frozen=True, eq=False)
class Shape:
    """A primitive of a link: ``kind`` ``box`` (``size`` = full extents, m), ``cylinder``
    (radius, length along its z), ``sphere`` (radius), posed by ``T_link_shape``;
    ``collision``: the MuJoCo geom collides (it is also written as a collision element)."""

    link: str
    kind: str
    size: tuple[float, ...]
    T_link_shape: np.ndarray
    material: str
    collision: bool = False


@dataclass(frozen=True, eq=False)
class Inertial:
    link: str
    mass: float
    """kg"""
    T_link_com: np.ndarray
    """Centre of mass and principal axes in the link frame."""
    inertia: tuple[float, float, float]
    """Principal moments, kg·m²."""


@dataclass(frozen=True, eq=False)
class Robot:
    """A URDF robot (see the module docstring): links, joints in tree order (a parent's
    joint before its children's), shapes, inertials and named colours (RGBA in [0, 1])."""

    name: str
    links: tuple[str, ...]
    joints: tuple[Joint, ...]
    shapes: tuple[Shape, ...]
    inertials: tuple[Inertial, ...]
    materials: tuple[tuple[str, tuple[float, float, float, float]], ...]
    qpos_addresses: Mapping[str, int]
    """MuJoCo ``qpos`` address of every actuated (non-mimic, moving) joint, by URDF name."""

    @property
    def root(self) -> str:
        return self.links[0]

    @property
    def actuated(self) -> tuple[str, ...]:
        """Names of the joints a ``JointState`` carries (moving, not mimic)."""
        return tuple(self.qpos_addresses)

    def joint_values(self, qpos) -> dict[str, float]:
        """The actuated joints' values in MuJoCo's ``qpos`` of the model this robot was read
        from (rad, m)."""
        q = np.asarray(qpos, dtype=float)
        return {name: float(q[adr]) for name, adr in self.qpos_addresses.items()}

    @cached_property
    def moving(self) -> tuple[Joint, ...]:
        """The joints that are not fixed (actuated and mimic), in tree order."""
        return tuple(j for j in self.joints if j.type != "fixed")

    @cached_property
    def _batch(self) -> tuple:
        mv = self.moving
        origins = np.stack([j.T_parent_origin for j in mv])
        axes = np.stack([j.axis for j in mv])
        revolute = np.array([j.type == "revolute" for j in mv])
        source = [j.mimic[0] if j.mimic else j.name for j in mv]
        multiplier = np.array([j.mimic[1] if j.mimic else 1.0 for j in mv])
        offset = np.array([j.mimic[2] if j.mimic else 0.0 for j in mv])
        K = np.zeros((len(mv), 3, 3))  # the axes' cross-product matrices (Rodrigues)
        K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -axes[:, 2], axes[:, 1], -axes[:, 0]
        K -= K.transpose(0, 2, 1)
        return origins, axes, revolute, source, multiplier, offset, K, K @ K

    def moving_transforms(self, values: Mapping[str, float]) -> np.ndarray:
        """``T_parent_child`` (n, 4, 4) of the :attr:`moving` joints at the actuated joints'
        ``values`` (mimic joints follow theirs; a missing value counts as 0), all at once:
        what ``/tf`` publishes at its rate."""
        origins, axes, revolute, source, multiplier, offset, K, K2 = self._batch
        q = multiplier * np.array([values.get(name, 0.0) for name in source]) + offset
        s, c = np.sin(q)[:, None, None], np.cos(q)[:, None, None]
        M = np.zeros((len(q), 4, 4))
        M[:, :3, :3] = np.where(revolute[:, None, None], np.eye(3) + s * K + (1 - c) * K2,
                                np.eye(3))  # fmt: skip
        M[:, :3, 3] = np.where(revolute[:, None], 0.0, axes * q[:, None])
        M[:, 3, 3] = 1.0
        return origins @ M

    def transforms(self, values: Mapping[str, float]) -> list[tuple[Joint, np.ndarray]]:
        """``(joint, T_parent_child)`` of every joint at the actuated joints' ``values``
        (see :meth:`moving_transforms`), in tree order."""
        moving = dict(zip(self.moving, self.moving_transforms(values), strict=True))
        return [(j, moving[j] if j in moving else j.T_parent_origin) for j in self.joints]

    def arm(self, arm: str) -> Robot:
        """The part of one arm, as the dVRK describes each arm on its own: the links named
        ``<prefix>…`` (``PSM1`` → ``PSM1_…``, ``SUJ/PSM1`` → ``SUJ_PSM1_…``), rooted at the
        arm's base link, with the same link names (so it draws from the same ``/tf``) and
        the joints named as the arm's ``measured_js`` names them (``yaw``, ``pitch`` …;
        ``jaw_1``/``jaw_2`` the fingers; the setup joints keep ``SUJ_PSM1_J0`` …).

        Raises:
            KeyError: no link of that arm.
        """
        prefix = arm.replace("/", "_") + "_"
        links = tuple(n for n in self.links if n.startswith(prefix))
        if not links:
            raise KeyError(f"no link of arm {arm!r} (its links would start with {prefix!r})")
        kept = set(links)
        joints = [j for j in self.joints if j.parent in kept and j.child in kept]
        roots = kept - {j.child for j in joints}
        if len(roots) != 1:
            raise KeyError(f"arm {arm!r}: its links {sorted(roots)} are not one tree")
        root = roots.pop()
        renamed = {j.name: j.name.removeprefix(prefix) if not arm.startswith("SUJ") else j.name
                   for j in joints}  # fmt: skip

        def rename(j: Joint) -> Joint:
            mimic = None if j.mimic is None else (renamed[j.mimic[0]], *j.mimic[1:])
            return replace(j, name=renamed[j.name], mimic=mimic)

        return Robot(
            arm.replace("/", "_"),
            (root, *(n for n in links if n != root)),
            tuple(rename(j) for j in joints),
            tuple(x for x in self.shapes if x.link in kept),
            tuple(x for x in self.inertials if x.link in kept),
            self.materials,
            {renamed[n]: a for n, a in self.qpos_addresses.items() if n in renamed},
        )

    @property
    def arms(self) -> tuple[str, ...]:
        """The arms :meth:`arm` describes (``PSM1`` …, ``SUJ/PSM1`` …), by their joints."""
        out = []
        for j in self.joints:
            if j.source is not None and "/" in j.source:
                arm = j.source.rsplit("/", 1)[0]
                if arm not in out:
                    out.append(arm)
        return tuple(out)

    def link_poses(self, values: Mapping[str, float]) -> dict[str, np.ndarray]:
        """``T_root_link`` of every link at ``values`` (forward kinematics)."""
        poses = {self.root: np.eye(4)}
        for j, T in self.transforms(values):
            poses[j.child] = poses[j.parent] @ T
        return poses

    def to_xml(self) -> str:
        """The URDF document (:func:`davinci_sim.model.urdf_xml.urdf_xml`)."""
        from davinci_sim.model.urdf_xml import urdf_xml

        return urdf_xml(self)


# =========================================================================== reading
def _T(pos, quat_wxyz) -> np.ndarray:
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat_wxyz, dtype=float))
    return transform(R.reshape(3, 3), pos)


def _velocity_limits() -> dict[str, float]:
    """The dVRK's trajectory velocity limits by MuJoCo joint name (rad/s, m/s)."""
    out: dict[str, float] = {}
    for arm in ARM_FILES:
        kin = load_arm(arm)
        for name, v in zip(kin.chain.joint_names, kin.v_max, strict=True):
            out[f"{arm}/{name}"] = float(v)
        if kin.jaw is not None and math.isfinite(kin.jaw_v_max):
            for i in (1, 2):  # each finger moves half the jaw angle
                out[f"{arm}/jaw_{i}"] = kin.jaw_v_max / 2
    return out


def _efforts(model: mujoco.MjModel) -> dict[int, float]:
    """Joint id → the largest effort of its actuator (N·m, N)."""
    out: dict[int, float] = {}
    for a in range(model.nu):
        if model.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT:
            continue
        j = int(model.actuator_trnid[a, 0])
        if model.actuator_forcelimited[a]:
            effort = float(np.max(np.abs(model.actuator_forcerange[a])))
        else:
            effort = float(np.max(np.abs(model.actuator_ctrlrange[a])))
        out[j] = max(out.get(j, 0.0), effort)
    return out


class _Colours:
    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.used: dict[str, tuple[float, float, float, float]] = {}

    def of(self, matid: int, rgba) -> str:
        if matid >= 0:
            name = self.model.material(matid).name
            rgba = self.model.mat_rgba[matid]
        else:
            name = "rgba_" + "_".join(f"{x:.3f}" for x in rgba)
        self.used.setdefault(name, tuple(round(float(x), 4) for x in rgba))
        return name


def _shapes(model, g: int, link: str, T_link_body: np.ndarray, colours: _Colours) -> list[Shape]:
    """The URDF primitives of geom ``g`` (a capsule: a cylinder and two spheres)."""
    kind, size = int(model.geom_type[g]), model.geom_size[g]
    T = T_link_body @ _T(model.geom_pos[g], model.geom_quat[g])
    material = colours.of(int(model.geom_matid[g]), model.geom_rgba[g])
    collides = bool(model.geom_contype[g] or model.geom_conaffinity[g])

    def shape(k, s, TT=T):
        return Shape(link, k, tuple(float(x) for x in s), TT, material, collides)

    if kind == _G.mjGEOM_BOX:
        return [shape("box", 2 * size)]
    if kind == _G.mjGEOM_CYLINDER:
        return [shape("cylinder", (size[0], 2 * size[1]))]
    if kind == _G.mjGEOM_SPHERE:
        return [shape("sphere", (size[0],))]
    if kind == _G.mjGEOM_CAPSULE:
        r, h = size[0], size[1]
        return [
            shape("cylinder", (r, 2 * h)),
            shape("sphere", (r,), T @ transform(p=[0, 0, h])),
            shape("sphere", (r,), T @ transform(p=[0, 0, -h])),
        ]
    raise ValueError(
        f"geom {model.geom(g).name or g} of body {model.body(model.geom_bodyid[g]).name}: "
        f"type {mujoco.mjtGeom(kind).name} has no URDF primitive"
    )


def robot_from_model(model: mujoco.MjModel, name: str = "davinci") -> Robot:
    """The :class:`Robot` of a compiled model (see the module docstring).

    Raises:
        ValueError: a body with more than one joint or a ball joint (no URDF joint), or a
            geom that is not a box, cylinder, sphere, capsule or plane.
    """
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    velocities = _velocity_limits()
    efforts = _efforts(model)
    colours = _Colours(model)
    links: list[str] = [ROOT]
    joints: list[Joint] = []
    shapes: list[Shape] = []
    inertials: list[Inertial] = []
    addresses: dict[str, int] = {}
    # T_link_body of every kept body: identity, or the joint anchor's offset undone.
    T_link_body: dict[int, np.ndarray] = {0: np.eye(4)}
    for b in range(1, model.nbody):
        parent = int(model.body_parentid[b])
        if parent not in T_link_body:  # below a free body: not part of the robot
            continue
        jnum, jadr = int(model.body_jntnum[b]), int(model.body_jntadr[b])
        body = model.body(b).name
        if jnum == 1 and model.jnt_type[jadr] == _J.mjJNT_FREE:
            continue
        if jnum > 1 or (jnum == 1 and model.jnt_type[jadr] == _J.mjJNT_BALL):
            raise ValueError(f"body {body}: only one hinge or slide joint has a URDF joint")
        link = link_name(body)
        T_pb = T_link_body[parent] @ _T(model.body_pos[b], model.body_quat[b])
        if jnum == 0:
            T_link_body[b] = np.eye(4)
            joints.append(Joint(f"{link}_fixed", "fixed", link_name(model.body(parent).name),
                                link, T_pb, np.zeros(3)))  # fmt: skip
        else:
            j = jadr
            anchor = np.array(model.jnt_pos[j], dtype=float)
            axis = np.array(model.jnt_axis[j], dtype=float)
            axis /= np.linalg.norm(axis)
            ref = float(model.qpos0[model.jnt_qposadr[j]])
            hinge = model.jnt_type[j] == _J.mjJNT_HINGE
            # MuJoCo: the body is at body_pos/quat when qpos = qpos0 (the joint's ref); URDF:
            # the child is at the origin when q = 0. So the origin is the rest pose turned
            # (or slid) back by ref about the joint's axis through its anchor.
            back = (
                transform(rotation_from_vector(-axis * ref)) if hinge else transform(p=-axis * ref)
            )
            T_origin = T_pb @ transform(p=anchor) @ back
            T_link_body[b] = transform(p=-anchor)
            lo, hi = model.jnt_range[j] if model.jnt_limited[j] else (-math.pi, math.pi)
            mj_name = model.joint(j).name
            jn = joint_name(mj_name)
            joints.append(Joint(
                jn, "revolute" if hinge else "prismatic", link_name(model.body(parent).name),
                link, T_origin, axis, float(lo), float(hi), efforts.get(j, 0.0),
                velocities.get(mj_name, 0.0), mj_name,
            ))  # fmt: skip
            addresses[jn] = int(model.jnt_qposadr[j])
        links.append(link)
        g0 = int(model.body_geomadr[b])
        for g in range(g0, g0 + int(model.body_geomnum[b])):
            shapes.extend(_shapes(model, g, link, T_link_body[b], colours))
        if model.body_mass[b] > 0:
            T_com = T_link_body[b] @ _T(model.body_ipos[b], model.body_iquat[b])
            inertials.append(Inertial(link, float(model.body_mass[b]), T_com,
                                      tuple(float(x) for x in model.body_inertia[b])))  # fmt: skip
    # The world body's own geoms (the floor plane) are the room, not the robot.
    kept = set(T_link_body)
    _add_parallelograms(model, data, kept, T_link_body, joints, links, shapes, colours)
    _add_cameras(model, kept, T_link_body, joints, links)
    return Robot(name, tuple(links), tuple(joints), tuple(shapes), tuple(inertials),
                 tuple(colours.used.items()), addresses)  # fmt: skip


def _add_parallelograms(model, data, kept, T_link_body, joints, links, shapes, colours) -> None:
    """Each two-site tendon from a body A to its child B (a PSM/ECM parallelogram's back
    link, :mod:`davinci_sim.model.rcm_arm`): a link on A at the first site that mimics B's
    joint, drawn as a bar to the second site."""
    by_child = {j.child: j for j in joints}
    for t in range(model.ntendon):
        adr, num = int(model.tendon_adr[t]), int(model.tendon_num[t])
        if num != 2 or any(model.wrap_type[adr + i] != mujoco.mjtWrap.mjWRAP_SITE for i in (0, 1)):
            continue
        s0, s1 = int(model.wrap_objid[adr]), int(model.wrap_objid[adr + 1])
        a, b = int(model.site_bodyid[s0]), int(model.site_bodyid[s1])
        if a not in kept or b not in kept or model.body_parentid[b] != a:
            continue
        master = by_child.get(link_name(model.body(b).name))
        if master is None or master.type != "revolute":
            continue
        name = f"{master.name}_back"
        link = f"{name}_link"
        # Origin: the first site, turned like B's joint origin, so that at every value the
        # link is parallel to B (the parallelogram's defining property).
        T_origin = transform(master.T_parent_origin[:3, :3],
                             (T_link_body[a] @ transform(p=model.site_pos[s0]))[:3, 3])  # fmt: skip
        joints.append(Joint(name, "revolute", master.parent, link, T_origin, master.axis,
                            master.lower, master.upper, mimic=(master.name, 1.0, 0.0)))  # fmt: skip
        links.append(link)
        # The bar, from the pivot to the second site as they are at qpos0.
        R_world_link = data.xmat[b].reshape(3, 3)  # = B's rotation at qpos0
        end = R_world_link.T @ (data.site_xpos[s1] - data.site_xpos[s0])
        length = float(np.linalg.norm(end))
        width = 2.0 * float(model.tendon_width[t])
        z = end / length
        x = np.cross([0.0, 0.0, 1.0], z) if abs(z[2]) < 0.9 else np.cross([1.0, 0.0, 0.0], z)
        x /= np.linalg.norm(x)
        R = np.column_stack([x, np.cross(z, x), z])
        material = colours.of(int(model.tendon_matid[t]), model.tendon_rgba[t])
        shapes.append(Shape(link, "box", (width, width, length), transform(R, end / 2), material))


def _add_cameras(model, kept, T_link_body, joints, links) -> None:
    for c in range(model.ncam):
        b = int(model.cam_bodyid[c])
        if b not in kept:
            continue
        frame = camera_frame(model.camera(c).name)
        T = T_link_body[b] @ _T(model.cam_pos[c], model.cam_quat[c])
        T[:3, :3] = T[:3, :3] @ R_CAMERA_OPTICAL
        joints.append(Joint(f"{frame}_fixed", "fixed", link_name(model.body(b).name), frame, T,
                            np.zeros(3)))  # fmt: skip
        links.append(frame)


def scene_robot(scene: str = "full", **overrides) -> Robot:
    """The :class:`Robot` of a scene (a name of :data:`~davinci_sim.model.SCENES`)."""
    from davinci_sim.model.builder import build_model

    return robot_from_model(build_model(scene, **overrides))
