"""The curved suture needle in the MuJoCo scene, its park, and what a task reads of it.

**The needle** (:class:`NeedleSpec`) is a circular arc of wire, a free body
``<prefix>needle`` made of a chain of capsules (kind ``object``, like the peg-transfer
rings): nothing welds or attaches it to a jaw; the jaws hold it by contact and friction.
Its frame: origin at the circle's centre, the arc in the x-y plane, symmetric about +y (the
middle of the arc on +y), the swage end (where the suture is crimped) on the +x side and the
point on the −x side, z the normal of the needle's plane.

Its default size is an SH-like needle: a half circle 26 mm long along the curve (radius
26/π ≈ 8.3 mm). Two numbers differ from the steel needle on purpose, for MuJoCo's soft
contacts: the jaws close with the dVRK jaw's 0.16 N·m (dvrk.md §1.2), ≈ 20 N on what they
hold, and a contact's penetration grows with the held body's mobility. On a 0.6 mm wire of
0.07 g (a real SH) the two jaws met inside the wire (measured 0.7-0.9 mm penetration per
jaw) and the needle turned under 1 mN·m. The simulated needle's wire is 1.0 mm thick and
it weighs 0.3 g, and its contacts are stiffer than the scene's (:data:`NEEDLE_SOLIMP`, a
0.3 mm transition width, which dominates the mix with the jaws' by :data:`NEEDLE_SOLMIX`):
measured ≈ 0.25 mm penetration per jaw; the grasp holds a 0.5 N push and 5 mN·m about any
axis, 100 mN·m about the wire's own axis (its contacts resist rolling,
:data:`NEEDLE_CONDIM`), and the needle slips about the wire's axis under 200 mN·m
(``tests/tasks/test_needle.py``).

**The park** is where a needle exercise starts: a foam block on the tissue pad with a slit
across its top; the needle stands upright in the slit on its two ends (its plane vertical,
the middle of the arc up), so that the jaws, pointing down, close across the wire at the
top of the arc without digging into the block. The block is foam, not steel: its contacts
(with the needle and with the jaws) are its own, softer and more slippery than the scene's
(:data:`FOAM_SOLIMP`).

:class:`NeedleProbe` is a task's view of the simulation at a tick: the needle's frame and
which jaws touch it, from MuJoCo's contacts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from davinci_sim.geometry.se3 import rot_z, transform
from davinci_sim.model import contact
from davinci_sim.model.patient import TISSUE_SURFACE_Z
from davinci_sim.model.shapes import set_inertial
from davinci_sim.tasks.objects_probe import ObjectsProbe, frame_of

#: Contact impedance of the needle's geoms (MuJoCo ``solimp``): the scene's nearly hard
#: contacts (:data:`davinci_sim.model.contact.CONTACT_SOLIMP`) with dmax 0.9999 and a
#: 0.3 mm transition width, so that the jaws' grip stays within the 0.5 mm wire radius.
NEEDLE_SOLIMP = np.array([0.99, 0.9999, 0.0003, 0.5, 2.0])
#: Mixing weight of the needle's contact parameters against the other geom's (MuJoCo's
#: ``solmix``: the pair's parameters are the weighted mean): the needle's dominate.
NEEDLE_SOLMIX = 1000.0
#: The needle's contacts resist rolling too (MuJoCo's ``condim`` 6: the ``object`` kind's
#: rolling friction, 0.1 mm). With condim 4 nothing resists the wire rolling between two
#: flat jaws (a pencil between the palms): held by its point after a drive, with the jaws
#: pressing on the skin, the needle rolled ~70° about the wire in 2 s in PSM2's grip. A
#: needle driver's flat, serrated jaws hold a wire on a patch, not a line.
NEEDLE_CONDIM = 6
NEEDLE_RGBA = (0.80, 0.82, 0.86, 1.0)
FOAM_RGBA = (0.30, 0.55, 0.75, 1.0)
#: The park's foam: contact impedance 0.95 → 0.99 over 1 mm of penetration (MuJoCo
#: ``solimp``) with a 4 ms time constant (``solref``; the scene's contacts: 0.99 → 0.999
#: over 0.5 mm, 3 ms), and friction 0.4 (steel on foam; the scene's environment 0.8). Its
#: geoms' ``priority`` makes these the parameters of their every contact (MuJoCo takes the
#: higher-priority geom's instead of mixing), the needle's stiff ones included. With the
#: needle's parameters the slit held like steel: a person's jaws closing across the wire
#: wedged its two ends between the walls (~500 N), and lifting it held the tool back until
#: PSM1 faulted on its insertion's tracking error (``tests/tasks/test_needle.py``).
FOAM_SOLIMP = np.array([0.95, 0.99, 0.001, 0.5, 2.0])
FOAM_SOLREF = np.array([0.004, 1.0])
FOAM_FRICTION = np.array([0.4, 0.005, 0.0001])
FOAM_PRIORITY = 1
#: Noslip solver iterations of a scene with a needle (as the peg board's rings: the
#: solver that stops a held object creeping out of a grasp).
NOSLIP_ITERATIONS = 10


@dataclass(frozen=True)
class NeedleSpec:
    """A curved suture needle; lengths in m, mass in kg (see the module docstring)."""

    radius: float = 0.026 / math.pi
    """Radius of the needle's circle, m (default: 26 mm along a half circle)."""
    arc: float = math.pi
    """Angle the needle spans, rad (π: a half circle, 1/2c in the catalogues)."""
    wire_radius: float = 0.0005
    """Half the wire's thickness, m."""
    mass: float = 0.0003
    segments: int = 12
    """Capsules along the arc (collision and drawing)."""

    def __post_init__(self) -> None:
        for name in ("radius", "arc", "wire_radius", "mass"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise ValueError(f"needle {name} must be a finite number > 0, got {v!r}")
        if self.arc >= 2 * math.pi:
            raise ValueError(f"needle arc must be < 2π (an open curve), got {self.arc!r}")
        if self.wire_radius >= self.radius / 4:
            raise ValueError("needle wire_radius must be under a quarter of its radius")
        if not (isinstance(self.segments, int) and 2 <= self.segments <= 64):
            raise ValueError(f"needle segments must be an integer 2..64, got {self.segments!r}")

    @property
    def length(self) -> float:
        """Length along the curve, m."""
        return self.radius * self.arc

    def points(self, s) -> np.ndarray:
        """Points at fractions ``s`` (0 swage, 1 point) along the needle, needle frame, m:
        (..., 3)."""
        phi = self.arc * (0.5 - np.asarray(s, dtype=float))  # (from +y, towards +x)
        return np.stack([self.radius * np.sin(phi), self.radius * np.cos(phi),
                         np.zeros_like(phi)], axis=-1)  # fmt: skip

    def fraction(self, p_needle) -> np.ndarray:
        """The fraction along the needle (0 swage, 1 point) of the arc's point nearest to
        points ``p_needle`` (..., 3) in the needle frame, clipped to [0, 1]."""
        p = np.asarray(p_needle, dtype=float)
        phi = np.arctan2(p[..., 0], p[..., 1])
        return np.clip(0.5 - phi / self.arc, 0.0, 1.0)

    def centroid(self) -> np.ndarray:
        """The centre of mass (a thin uniform arc), needle frame, m."""
        half = self.arc / 2
        return np.array([0.0, self.radius * math.sin(half) / half, 0.0])

    def inertia(self) -> np.ndarray:
        """Principal moments about the centre of mass along the needle frame's axes
        (a thin uniform arc: the arc's symmetry about y makes them principal), kg·m²."""
        m, R, a = self.mass, self.radius, self.arc
        x2 = m * R * R * (0.5 - math.sin(a) / (2 * a))  # ∫ x² dm
        y2 = m * R * R * (0.5 + math.sin(a) / (2 * a))  # ∫ y² dm
        yc = self.centroid()[1]
        return np.array([y2 - m * yc * yc, x2, x2 + y2 - m * yc * yc])


@dataclass(frozen=True)
class NeedlePark:
    """The foam block the needle starts in, world frame, m (see the module docstring)."""

    center: tuple[float, float]
    """The slit's centre (x, y) on the block's top."""
    top: float
    """Height of the block's top face."""
    yaw: float = 0.0
    """Direction of the slit (and of the needle's plane) about the world z axis, rad:
    0 along the world x axis."""
    slit_depth: float = 0.004
    slit_width: float = 0.0013
    margin: float = 0.004
    """Foam beyond the needle's ends and on either side of the slit."""

    def T_world_needle(self, needle: NeedleSpec) -> np.ndarray:
        """The needle's frame standing in the slit on its ends (plane vertical, middle up):
        4×4, world frame."""
        # The needle's lowest points (its ends, for an arc up to a half circle) rest on the
        # slit's bottom.
        drop = -needle.points(np.linspace(0.0, 1.0, 65))[:, 1].min() + needle.wire_radius
        R = rot_z(self.yaw) @ np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
        z = self.top - self.slit_depth + drop
        return transform(R, [self.center[0], self.center[1], z])


def grasp_pose(T_world_needle: np.ndarray, needle: NeedleSpec, R_world_tip: np.ndarray,
               s: float, depth: float = 0.006) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Where a tip goes to grasp the needle at fraction ``s`` of its length (0 swage, 1
    point) with the jaws closing across the needle's plane: ``(R_world_tip, p_world_pivot)``.

    The tip frame of the dVRK PSM has the jaws along z and their closing direction along y
    (x the hinge axis). The grasp keeps the tip's current orientation ``R_world_tip`` as far
    as it can: its y turned onto the needle plane's normal (the sign nearer the current
    y), its z the current one turned into the needle's plane; the pivot (the tip point, on
    the wrist-yaw axis) lies ``depth`` m behind the wire along the jaws.
    """
    normal = T_world_needle[:3, 2]
    R = np.asarray(R_world_tip, dtype=float)
    y = normal if np.dot(normal, R[:, 1]) >= 0 else -normal
    z = R[:, 2] - y * np.dot(y, R[:, 2])
    norm = np.linalg.norm(z)
    if norm < 1e-6:
        raise ValueError("the jaws point along the needle plane's normal: no grasp across it")
    z /= norm
    p = T_world_needle[:3, :3] @ needle.points(s) + T_world_needle[:3, 3]
    return np.column_stack([np.cross(y, z), y, z]), p - depth * z


def driver_grasp(T_world_needle: np.ndarray, needle: NeedleSpec, z_hint, s: float,
                 depth: float = 0.006) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """A needle driver's grip at fraction ``s``: ``(R_world_tip, p_world_pivot)`` with the
    jaws (tip z) along the needle plane's normal, the sign nearer ``z_hint`` (3,), closing
    (tip y) along the radius, so that the needle lies across the jaws and turning the tip
    about its own z turns the needle in its plane; the wire ``depth`` (m) along the jaws
    from the pivot."""
    R, c = T_world_needle[:3, :3], T_world_needle[:3, 3]
    p = R @ needle.points(s) + c
    radial = (p - c) / np.linalg.norm(p - c)
    z = R[:, 2] if R[:, 2] @ np.asarray(z_hint, dtype=float) >= 0 else -R[:, 2]
    return np.column_stack([np.cross(radial, z), radial, z]), p - depth * z


def add_needle(spec: mujoco.MjSpec, needle: NeedleSpec, park: NeedlePark | None,
               prefix: str = "task/") -> mujoco.MjsBody:  # fmt: skip
    """Add ``needle`` (a free body, ``<prefix>needle``, standing in ``park`` if given,
    else at the world origin) and the park's foam block to ``spec``; every keyframe gets the
    needle's start pose appended (its joint is the last added). Returns the needle's body."""
    world = spec.worldbody
    T = np.eye(4) if park is None else park.T_world_needle(needle)
    if park is not None:
        _add_park(world, needle, park, prefix)
    body = world.add_body(name=f"{prefix}needle", pos=T[:3, 3])
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, T[:3, :3].ravel())
    body.quat = quat
    body.add_freejoint(name=f"{prefix}needle")
    pts = needle.points(np.linspace(0.0, 1.0, needle.segments + 1))
    for j in range(needle.segments):
        g = body.add_geom(name=f"{prefix}needle_{j}", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                          fromto=np.concatenate([pts[j], pts[j + 1]]),
                          size=[needle.wire_radius, 0, 0])  # fmt: skip
        contact.apply(g, "object")
        g.condim = NEEDLE_CONDIM
        g.solimp = NEEDLE_SOLIMP
        g.solmix = NEEDLE_SOLMIX
        g.rgba = list(NEEDLE_RGBA)
        g.mass = 0.0
    set_inertial(body, needle.mass, needle.centroid(), needle.inertia())
    start = np.concatenate([T[:3, 3], quat])
    for key in spec.keys:
        q = np.asarray(key.qpos, dtype=float)
        if q.size:
            key.qpos = np.concatenate([q, start])
    spec.option.noslip_iterations = max(spec.option.noslip_iterations, NOSLIP_ITERATIONS)
    return body


def _add_park(world, needle: NeedleSpec, park: NeedlePark, prefix: str) -> None:
    """The foam block: a base from the tissue up to the slit's bottom, and a wall on either
    side of the slit up to the top (kind ``env``, with the foam's contacts)."""
    box = mujoco.mjtGeom.mjGEOM_BOX
    block = world.add_body(name=f"{prefix}park")
    block.pos = [park.center[0], park.center[1], 0.0]
    block.quat = [math.cos(park.yaw / 2), 0.0, 0.0, math.sin(park.yaw / 2)]
    half_length = needle.radius * math.sin(min(needle.arc, math.pi) / 2) + park.margin
    wall = park.margin
    half_width = park.slit_width / 2 + wall
    bottom = park.top - park.slit_depth
    parts = (
        ("base", [0, 0, (TISSUE_SURFACE_Z + bottom) / 2],
         [half_length, half_width, (bottom - TISSUE_SURFACE_Z) / 2]),
        ("wall_1", [0, park.slit_width / 2 + wall / 2, park.top - park.slit_depth / 2],
         [half_length, wall / 2, park.slit_depth / 2]),
        ("wall_2", [0, -park.slit_width / 2 - wall / 2, park.top - park.slit_depth / 2],
         [half_length, wall / 2, park.slit_depth / 2]),
    )  # fmt: skip
    for name, pos, size in parts:
        g = block.add_geom(name=f"{prefix}park_{name}", type=box, pos=pos, size=size)
        contact.apply(g, "env")
        g.priority = FOAM_PRIORITY
        g.solimp, g.solref, g.friction = FOAM_SOLIMP, FOAM_SOLREF, FOAM_FRICTION
        g.rgba = list(FOAM_RGBA)


def reset_needle(model: mujoco.MjModel, data: mujoco.MjData, needle: NeedleSpec,
                 park: NeedlePark, prefix: str = "task/") -> None:  # fmt: skip
    """Put the needle back in its park at rest in ``data`` (``mj_forward`` after);
    ValueError if the scene has no needle."""
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{prefix}needle")
    if j < 0:
        raise ValueError("the scene has no needle (draw the task)")
    T = park.T_world_needle(needle)
    q, v = model.jnt_qposadr[j], model.jnt_dofadr[j]
    data.qpos[q : q + 3] = T[:3, 3]
    mujoco.mju_mat2Quat(data.qpos[q + 3 : q + 7], T[:3, :3].ravel())
    data.qvel[v : v + 6] = 0.0
    data.qacc_warmstart[v : v + 6] = 0.0
    mujoco.mj_forward(model, data)


class NeedleProbe(ObjectsProbe):
    """Reads, at a tick, the needle's frame (world, 4×4) and the bit mask of the jaws
    touching it (:class:`~davinci_sim.tasks.objects_probe.ObjectsProbe` of the one body):
    bit ``2·a + j`` for jaw ``j`` (0, 1) of instrument ``a`` (index in ``instruments``), as
    :class:`~davinci_sim.tasks.peg_scene.PegProbe` does for rings. ``flex``: as the base's
    (the suture pad's skin, whose contacts' force the reading sums)."""

    def __init__(self, model: mujoco.MjModel, instruments, prefix: str = "task/", *,
                 flex: str | None = None) -> None:  # fmt: skip
        self.body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"{prefix}needle")
        if self.body < 0:
            raise ValueError("the scene has no needle (draw the task first)")
        super().__init__(model, [self.body], instruments, flex=flex)

    def frame(self, data: mujoco.MjData) -> np.ndarray:
        """The needle's frame now (4×4, world, m)."""
        return frame_of(data.xpos[self.body], data.xmat[self.body])

    def grasp(self, data: mujoco.MjData) -> int:
        """The jaws touching the needle now (bit mask)."""
        return int(self.grasps(data)[0])
