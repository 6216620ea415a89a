"""The suture pad: a skin that deforms (a MuJoCo flex), the entry and exit marks drawn on
it, and the needle's passage through it, read from geometry.

**The skin** is a 2-D MuJoCo flex (``<prefix>pad_skin``): a grid of vertices ``spacing``
apart over the pad's top, its border pinned to the pad's block, each inner vertex a body on
one slide joint along the pad's normal with a spring to its rest position (``k_normal``),
and the flex's edges damped. The jaws and shafts of the
instruments collide with the skin's triangles and dent it locally (a foundation of
springs: a press spreads over the vertices under and next to the jaw, not over the whole
pad); a firm base ``depth`` below the skin (kind ``env``, touching the instruments only)
stops an instrument pushed through it. Why this discretisation, measured with MuJoCo 4 on
the 2-core development machine:

* flex ``<elasticity>`` is no longer integrated under ``implicitfast`` (the scene's
  integrator) and explicit Euler at 1 ms was unstable for a skin stiff enough to carry the
  jaws; edge stiffness exists only for 1-D flexes;
* a 3-D flex with trilinear degrees of freedom is cheap but dents as a whole (0.07 mm under
  0.3 N, no local dent); with full degrees of freedom (7×7×3 vertices, 295 dofs) a step took
  713 µs, 7-14× the scene's tick;
* the skin here: 11×9 vertices, 4 mm apart; with three slide joints per inner vertex
  (190 dofs) a 3 mm capsule pressed with 0.3 N dented it 0.7 mm under the capsule and
  0.2 mm 3.5 mm away and held 1 N (1.8 mm), but the scene's step took 2.5× as long
  (206 µs against 84 µs, ``bench_suture``); one joint per vertex, along the normal (63
  dofs), keeps the local dent (a foundation of springs) at a third of the dofs. The joint
  springs are explicit in MuJoCo's step, so the vertex mass keeps ω·Δt ≤ 0.5 (checked on
  construction); MuJoCo refuses joint damping on a flex's vertices, so the edges carry the
  damping.

**The needle does not collide with the skin** (the flex's collision bits leave objects
out): a needle's passage is geometry, as the AccelNet challenge scores it. Its tip entering
the skin's rest surface within ``mark_radius`` of an entry mark and coming out within
``mark_radius`` of the paired exit mark is a passage (:func:`passage_step`); while the tip
is in the tissue the entry point must stay on the needle's circle (a needle driven along
its own curve), and how far it leaves it is the tissue-trauma measure (m).

The pad's frame: origin at the centre of the skin's rest surface, z up (the skin's normal),
rotated by ``yaw`` about the world z axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import mujoco
import numpy as np

from davinci_sim.geometry.se3 import rot_z, transform
from davinci_sim.model import contact
from davinci_sim.model.patient import TISSUE_SURFACE_Z
from davinci_sim.model.shapes import set_inertial

SKIN_RGBA = (0.93, 0.66, 0.62, 1.0)
PAD_RGBA = (0.86, 0.55, 0.52, 1.0)
ENTRY_RGBA = (0.10, 0.35, 0.95, 1.0)
EXIT_RGBA = (0.05, 0.65, 0.25, 1.0)
#: Timestep the skin's springs are checked against, s (the scene's, 1 kHz).
TIMESTEP = 0.001


@dataclass(frozen=True)
class SuturePad:
    """A suture pad on the tissue, world frame, m, kg, N/m (see the module docstring)."""

    center: tuple[float, float]
    """The skin's centre (x, y)."""
    top: float
    """Height of the skin's rest surface."""
    yaw: float = 0.0
    """The pad's rotation about the world z axis, rad."""
    pairs: tuple[tuple[tuple[float, float], tuple[float, float]], ...] = (
        ((-0.007, 0.0), (0.007, 0.0)),
    )
    """(entry (x, y), exit (x, y)) marks, pad frame: a suture's bites in order."""
    size: tuple[float, float] = (0.040, 0.032)
    """The skin's extent along the pad's x and y."""
    spacing: float = 0.004
    """Distance between the skin's vertices."""
    depth: float = 0.006
    """From the skin down to the firm base."""
    skin_radius: float = 0.0015
    """Half the skin's collision thickness (MuJoCo flex radius)."""
    vertex_mass: float = 0.0007
    k_normal: float = 150.0
    """Each inner vertex's spring to its rest position along the skin's normal, N/m."""
    edge_damping: float = 0.05
    """Damping of the flex's edge lengths (MuJoCo ``edgedamping``)."""
    mark_radius: float = 0.0025
    """How near a mark the needle must enter and exit (the challenge's ±2.5 mm)."""

    def __post_init__(self) -> None:
        for name in ("spacing", "depth", "skin_radius", "vertex_mass", "k_normal",
                     "mark_radius"):  # fmt: skip
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise ValueError(f"suture pad {name} must be a finite number > 0, got {v!r}")
        if not (math.isfinite(self.edge_damping) and self.edge_damping >= 0):
            raise ValueError(f"suture pad edge_damping must be ≥ 0, got {self.edge_damping!r}")
        sx, sy = (float(v) for v in self.size)
        if not (sx > 0 and sy > 0) or min(self.grid) < 3:
            raise ValueError(f"suture pad size {self.size!r} must hold 3 vertices "
                             f"{self.spacing} m apart along each side")  # fmt: skip
        if self.skin_radius * 2 >= self.spacing:
            raise ValueError("suture pad skin_radius must be under half the spacing")
        stiffest = self.k_normal
        if math.sqrt(stiffest / self.vertex_mass) * TIMESTEP > 0.5:
            raise ValueError(
                f"suture pad springs of {stiffest} N/m on {self.vertex_mass} kg vertices are "
                f"too stiff for a {TIMESTEP} s step (ω·Δt > 0.5: MuJoCo integrates them "
                "explicitly); make the vertices heavier or the springs softer"
            )
        if self.top - self.depth <= TISSUE_SURFACE_Z:
            raise ValueError(f"suture pad top {self.top} m leaves no room for its base above "
                             f"the tissue at {TISSUE_SURFACE_Z} m")  # fmt: skip
        if not self.pairs:
            raise ValueError("suture pad needs at least one entry/exit pair")
        for k, pair in enumerate(self.pairs):
            for x, y in pair:
                if abs(x) > sx / 2 - self.spacing or abs(y) > sy / 2 - self.spacing:
                    raise ValueError(f"suture pad pair {k}: mark ({x}, {y}) is not on the "
                                     "skin's inner part")  # fmt: skip

    @property
    def grid(self) -> tuple[int, int]:
        """Vertices along the pad's x and y."""
        return (int(round(self.size[0] / self.spacing)) + 1,
                int(round(self.size[1] / self.spacing)) + 1)  # fmt: skip

    @property
    def T_world_pad(self) -> np.ndarray:
        """The pad's frame (4×4, world)."""
        return transform(rot_z(self.yaw), [self.center[0], self.center[1], self.top])

    @property
    def marks(self) -> np.ndarray:
        """(P, 2, 3) entry and exit marks on the rest surface, pad frame."""
        m = np.array(self.pairs, dtype=float).reshape(-1, 2, 2)
        return np.concatenate([m, np.zeros((*m.shape[:2], 1))], axis=2)

    def marks_world(self) -> np.ndarray:
        """(P, 2, 3) :attr:`marks` in the world frame."""
        T = self.T_world_pad
        return self.marks @ T[:3, :3].T + T[:3, 3]

    def vertices(self) -> np.ndarray:
        """(nx·ny, 3) the skin's rest vertices, pad frame (x fastest)."""
        nx, ny = self.grid
        x = (np.arange(nx) - (nx - 1) / 2) * self.spacing
        y = (np.arange(ny) - (ny - 1) / 2) * self.spacing
        X, Y = np.meshgrid(x, y)
        return np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])

    def border(self) -> np.ndarray:
        """(nx·ny,) bool: the pinned vertices."""
        nx, ny = self.grid
        i, j = np.meshgrid(np.arange(nx), np.arange(ny))
        return ((i == 0) | (i == nx - 1) | (j == 0) | (j == ny - 1)).ravel()

    def triangles(self) -> np.ndarray:
        """(2·(nx−1)·(ny−1), 3) the skin's triangles (vertex indices, counter-clockwise
        seen from above)."""
        nx, ny = self.grid
        out = []
        for j in range(ny - 1):
            for i in range(nx - 1):
                a, b, c, d = j * nx + i, j * nx + i + 1, (j + 1) * nx + i + 1, (j + 1) * nx + i
                out += [(a, b, c), (a, c, d)]
        return np.array(out, dtype=np.int64)


def drive_pose(pad: SuturePad, pair: int, needle, alpha: float, tilt: float = 0.0) -> np.ndarray:
    """The needle's frame (4×4, world) driven through ``pair``'s marks: its circle crossing
    the skin's rest surface at the entry and exit marks, its plane containing the line
    between them, tilted by ``tilt`` (rad) from the vertical about that line, towards the
    pad's −y; turned by ``alpha`` (rad) about its own centre (its z axis) from the pose
    with the swage end towards the exit mark level with the centre (at ``alpha`` = 0 the
    point is towards the entry). The point enters the skin as ``alpha`` passes
    π − ψ_e and exits as it passes π − ψ_x, the angles of the marks seen from the centre;
    a ValueError if the marks are farther apart than the needle's diameter."""
    entry, exit_ = pad.marks[pair]
    half = float(np.linalg.norm(exit_ - entry)) / 2
    if half >= needle.radius:
        raise ValueError(f"pair {pair}'s marks are {2 * half * 1e3:.1f} mm apart: the "
                         f"needle's circle ({2 * needle.radius * 1e3:.1f} mm across) cannot "
                         "join them")  # fmt: skip
    x = (exit_ - entry) / (2 * half)
    up = np.array([0.0, 0.0, 1.0])
    y = math.cos(tilt) * up - math.sin(tilt) * np.cross(up, x)  # (in the plane ⟂ x)
    R0 = np.column_stack([x, y, np.cross(x, y)])
    c, s = math.cos(alpha), math.sin(alpha)
    T = np.eye(4)
    T[:3, :3] = R0 @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    T[:3, 3] = (entry + exit_) / 2 + math.sqrt(needle.radius**2 - half**2) * y
    return pad.T_world_pad @ T


def add_suture_pad(spec: mujoco.MjSpec, pad: SuturePad, prefix: str = "task/") -> mujoco.MjsBody:
    """Add ``pad`` to ``spec``: the body ``<prefix>pad`` (its block, drawn; the firm base,
    kind ``env``; the marks, drawn), the skin's vertex bodies ``<prefix>pad_v<i>`` and the
    flex ``<prefix>pad_skin``. Every keyframe gets the vertices' rest positions (zeros)
    appended: add the pad after the bodies whose joints the keyframes already hold."""
    box, cyl = mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_CYLINDER
    body = spec.worldbody.add_body(name=f"{prefix}pad")
    T = pad.T_world_pad
    body.pos = T[:3, 3]
    body.quat = [math.cos(pad.yaw / 2), 0.0, 0.0, math.sin(pad.yaw / 2)]
    half = [pad.size[0] / 2, pad.size[1] / 2]
    below = pad.top - TISSUE_SURFACE_Z
    # The block (drawn, just under the skin) and its firm base (collides).
    block = body.add_geom(name=f"{prefix}pad_block", type=box,
                          pos=[0, 0, -pad.depth / 2 - pad.skin_radius],
                          size=[*half, pad.depth / 2 - pad.skin_radius])  # fmt: skip
    contact.apply(block, "visual")
    block.rgba = list(PAD_RGBA)
    base = body.add_geom(name=f"{prefix}pad_base", type=box,
                         pos=[0, 0, -(pad.depth + below) / 2],
                         size=[*half, (below - pad.depth) / 2])  # fmt: skip
    contact.apply(base, "env")
    base.contype, base.conaffinity = 0, contact.TOOL_BIT  # (instruments only, as the skin)
    base.rgba = list(PAD_RGBA)
    for k, pair in enumerate(pad.marks):
        for which, p, rgba in (("entry", pair[0], ENTRY_RGBA), ("exit", pair[1], EXIT_RGBA)):
            g = body.add_geom(name=f"{prefix}pad_{which}_{k}", type=cyl,
                              pos=p + [0, 0, pad.skin_radius + 0.0002],
                              size=[0.0012, 0.0001, 0])  # fmt: skip
            contact.apply(g, "visual")
            g.rgba = list(rgba)
    # The skin: inner vertices on springs, the border pinned to the block.
    verts, pinned = pad.vertices(), pad.border()
    names, local = [], []
    slide = mujoco.mjtJoint.mjJNT_SLIDE
    for i, (p, pin) in enumerate(zip(verts, pinned, strict=True)):
        if pin:
            names.append(body.name)
            local.append(p)
            continue
        v = body.add_body(name=f"{prefix}pad_v{i}", pos=p)
        i_sphere = 0.4 * pad.vertex_mass * pad.skin_radius**2
        set_inertial(v, pad.vertex_mass, np.zeros(3), np.full(3, i_sphere))
        v.add_joint(type=slide, axis=[0, 0, 1], stiffness=[pad.k_normal, 0, 0])
        names.append(v.name)
        local.append(np.zeros(3))
    flex = spec.add_flex(name=f"{prefix}pad_skin")
    flex.dim = 2
    flex.vertbody = names
    flex.vert = np.asarray(local).ravel()
    flex.elem = pad.triangles().ravel()
    flex.radius = pad.skin_radius
    flex.edgedamping = pad.edge_damping
    # Instruments only: not the needle (its passage is geometry), not the scene.
    flex.contype, flex.conaffinity = 0, contact.TOOL_BIT
    flex.condim = 3
    flex.friction = contact.ENV_FRICTION
    flex.selfcollide = mujoco.mjtFlexSelf.mjFLEXSELF_NONE
    flex.rgba = list(SKIN_RGBA)
    flex.group = 0
    free = int((~pinned).sum())
    for key in spec.keys:
        q = np.asarray(key.qpos, dtype=float)
        if q.size:
            key.qpos = np.concatenate([q, np.zeros(free)])
    return body


def reset_pad(model: mujoco.MjModel, data: mujoco.MjData, prefix: str = "task/") -> None:
    """The skin back at rest in ``data`` (``mj_forward`` after); ValueError without one."""
    dofs = skin_dofs(model, prefix)
    for j in dofs:
        data.qpos[model.jnt_qposadr[j]] = 0.0
        data.qvel[model.jnt_dofadr[j]] = 0.0
        data.qacc_warmstart[model.jnt_dofadr[j]] = 0.0
    mujoco.mj_forward(model, data)


def skin_dofs(model: mujoco.MjModel, prefix: str = "task/") -> np.ndarray:
    """The skin vertices' joints (ids); ValueError if the scene has no suture pad."""
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_FLEX, f"{prefix}pad_skin") < 0:
        raise ValueError("the scene has no suture pad (draw the task)")
    stem = f"{prefix}pad_v"
    bodies = {b for b in range(model.nbody) if model.body(b).name.startswith(stem)}
    return np.array([j for j in range(model.njnt) if model.jnt_bodyid[j] in bodies],
                    dtype=np.int64)  # fmt: skip


# ---------------------------------------------------------------- the needle's passage
class Passage(NamedTuple):
    """A needle's passage through the skin, for n trials ((n,) arrays, ``p_entry`` and
    ``p_tip`` (n, 3), pad frame, m)."""

    inside: np.ndarray
    """The tip is under the skin since it entered."""
    pair: np.ndarray
    """The pair whose entry mark is nearest where it entered (−1: not inside)."""
    p_entry: np.ndarray
    """Where the tip entered (nan: not inside)."""
    entry_error: np.ndarray
    """Entry point to the pair's entry mark, m (nan: not inside)."""
    trauma: np.ndarray
    """Peak distance of the entry point from the needle's circle since the tip entered, m."""
    p_tip: np.ndarray
    """The tip at the previous sample (nan before the first)."""


class PassageEvents(NamedTuple):
    """What :func:`passage_step` saw at one sample ((n,) arrays)."""

    entered: np.ndarray
    """The tip went into the skin."""
    exited: np.ndarray
    """The tip came out away from where it entered."""
    withdrawn: np.ndarray
    """The tip came back out where it entered."""
    passed: np.ndarray
    """It exited within the mark radius of its pair's exit, having entered within it of
    the entry."""
    pair: np.ndarray
    """The pair of an exit (−1: none)."""
    entry_error: np.ndarray
    exit_error: np.ndarray
    """Exit point to the pair's exit mark, m (nan: no exit)."""
    trauma: np.ndarray
    """The passage's peak trauma at an exit (nan: no exit), m."""


def no_passage(n: int) -> Passage:
    """The state before any sample."""
    nan = np.full(n, np.nan)
    return Passage(np.zeros(n, dtype=bool), np.full(n, -1, dtype=np.int64),
                   np.full((n, 3), np.nan), nan, nan.copy(), np.full((n, 3), np.nan))  # fmt: skip


def _no_events(n: int) -> PassageEvents:
    """The events of a sample where nothing happened, read-only (one per n: the usual
    sample's, every tick of a live session)."""
    events = _NO_EVENTS.get(n)
    if events is None:
        off, nan = np.zeros(n, dtype=bool), np.full(n, np.nan)
        minus = np.full(n, -1, dtype=np.int64)
        for a in (off, nan, minus):
            a.setflags(write=False)
        events = _NO_EVENTS[n] = PassageEvents(off, off, off, off, minus, nan, nan, nan)
    return events


_NO_EVENTS: dict[int, PassageEvents] = {}
_TIPS: dict = {}


def _tip_point(needle) -> np.ndarray:
    """The needle's point in its own frame (``needle.points(1.0)``, read-only), once per
    needle."""
    tip = _TIPS.get(needle)
    if tip is None:
        tip = _TIPS[needle] = needle.points(1.0)
        tip.setflags(write=False)
    return tip


def circle_deviation(p_needle: np.ndarray, radius: float) -> np.ndarray:
    """Distance of points ``p_needle`` (..., 3, needle frame) from the needle's circle
    (radius ``radius`` about the origin in the x-y plane), m."""
    p = np.asarray(p_needle, dtype=float)
    return np.hypot(np.hypot(p[..., 0], p[..., 1]) - radius, p[..., 2])


def passage_step(state: Passage, T_pad_needle: np.ndarray, needle, pad: SuturePad,
                 ) -> tuple[Passage, PassageEvents]:  # fmt: skip
    """One sample of n trials (pure): the needle's frames ``T_pad_needle`` (n, 4, 4) in the
    pad's frame; ``needle`` a :class:`~davinci_sim.tasks.needle_scene.NeedleSpec`.

    The tip (the needle's point, fraction 1) crossing the skin's rest surface downwards
    inside the pad's extent is an entry (the crossing point interpolated between the two
    samples); crossing it upwards is an exit, or a withdrawal when it comes out within the
    mark radius of where it went in. While inside, the trauma is the entry point's distance
    from the needle's circle (0 for a needle turned about its own centre)."""
    T = np.asarray(T_pad_needle, dtype=float).reshape(-1, 4, 4)
    # (R @ point + o summed in index order, as the compiled step sums it: numpy's matmul
    # may not: tasks/needle_row.py)
    R, p, point = T[:, :3, :3], T[:, :3, 3], _tip_point(needle)
    tip = ((R[:, :, 0] * point[0] + R[:, :, 1] * point[1]) + R[:, :, 2] * point[2]) + p
    if not state.inside.any() and (tip[:, 2] >= 0.0).all():  # (the usual sample: above)
        return state._replace(p_tip=tip), _no_events(len(T))
    prev = state.p_tip
    marks = pad.marks
    half = np.array(pad.size, dtype=float) / 2
    on_pad = np.all(np.abs(tip[:, :2]) <= half, axis=1)
    known = ~np.isnan(prev[:, 2])
    with np.errstate(invalid="ignore", divide="ignore"):
        down = known & (prev[:, 2] >= 0) & (tip[:, 2] < 0) & on_pad & ~state.inside
        up = known & (prev[:, 2] < 0) & (tip[:, 2] >= 0) & state.inside
        w = prev[:, 2] / (prev[:, 2] - tip[:, 2])
    cross = prev + np.where(np.isfinite(w), w, 0.0)[:, None] * (tip - prev)
    cross[:, 2] = 0.0

    # Entries: the nearest entry mark is the pair.
    d_entry = np.linalg.norm(cross[:, None, :2] - marks[None, :, 0, :2], axis=2)  # (n, P)
    nearest = np.argmin(d_entry, axis=1)
    inside = state.inside.copy()
    pair = state.pair.copy()
    p_entry = state.p_entry.copy()
    entry_error = state.entry_error.copy()
    trauma = state.trauma.copy()
    inside[down] = True
    pair[down] = nearest[down]
    p_entry[down] = cross[down]
    entry_error[down] = d_entry[down, nearest[down]]
    trauma[down] = 0.0

    # The trauma while inside: the entry point against the needle's circle.
    d = p_entry - p
    e_needle = (R[:, 0, :] * d[:, 0:1] + R[:, 1, :] * d[:, 1:2]) + R[:, 2, :] * d[:, 2:3]  # Rᵀd
    dev = circle_deviation(e_needle, needle.radius)
    trauma = np.where(inside, np.fmax(trauma, dev), trauma)

    # Exits.
    back = up & (np.linalg.norm(cross - p_entry, axis=1) <= pad.mark_radius)
    out = up & ~back
    safe_pair = np.clip(pair, 0, len(marks) - 1)
    exit_error = np.where(out, np.linalg.norm(cross[:, :2] - marks[safe_pair, 1, :2], axis=1),
                          np.nan)  # fmt: skip
    with np.errstate(invalid="ignore"):
        passed = out & (entry_error <= pad.mark_radius) & (exit_error <= pad.mark_radius)
    events = PassageEvents(down, out, back, passed, np.where(out, pair, -1),
                           np.where(down | out, entry_error, np.nan), exit_error,
                           np.where(out, trauma, np.nan))  # fmt: skip
    ended = up
    inside[ended] = False
    pair[ended] = -1
    p_entry[ended] = np.nan
    entry_error[ended] = np.nan
    trauma[ended] = np.nan
    return Passage(inside, pair, p_entry, entry_error, trauma, tip.copy()), events
