"""What the bedside view draws, read from a compiled ``mujoco.MjModel``: pure functions.

* :func:`visible_geoms`: the geoms MuJoCo's default visualisation shows (groups 0-2, not
  fully transparent), each as a :class:`GeomVisual` (shape, size, colour, pose in its body);
* :func:`moving_bodies`: the bodies whose pose depends on ``qpos`` (the others, welded to the
  world, are drawn once);
* :func:`capsule_mesh`: a capsule as a triangle mesh (the browser's scene has boxes,
  spheres and cylinders as primitives, not capsules);
* :func:`guidance_arrows`: the guidance force of each PSM as an arrow at its tool tip;
* :func:`camera_presets`: the named viewpoints of the bedside view, from the model's bodies,
  sites and cameras.

All lengths in m, in the world (cart) frame unless a name says otherwise; quaternions are
``wxyz`` as in MuJoCo.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

_G = mujoco.mjtGeom

#: MuJoCo's default visualisation shows geom groups 0, 1 and 2 (``mjvOption.geomgroup``).
SHOWN_GROUPS = (0, 1, 2)
#: A geom's ``rgba`` overrides its material only when it differs from this internal default
#: (MuJoCo XML reference, ``geom/rgba``).
DEFAULT_GEOM_RGBA = np.array([0.5, 0.5, 0.5, 1.0], dtype=np.float32)
#: A plane of size 0 is infinite in MuJoCo; the view draws this half-extent (m) of it.
INFINITE_PLANE_HALF_EXTENT = 5.0

SHAPES = {
    int(_G.mjGEOM_PLANE): "plane",
    int(_G.mjGEOM_SPHERE): "sphere",
    int(_G.mjGEOM_CAPSULE): "capsule",
    int(_G.mjGEOM_ELLIPSOID): "ellipsoid",
    int(_G.mjGEOM_CYLINDER): "cylinder",
    int(_G.mjGEOM_BOX): "box",
    int(_G.mjGEOM_MESH): "mesh",
}


@dataclass(frozen=True, eq=False)
class GeomVisual:
    """One geom as the view draws it."""

    geom: int
    """Geom id in the model."""
    body: int
    """Body id the geom is attached to."""
    shape: str
    """One of :data:`SHAPES`' values."""
    size: np.ndarray
    """MuJoCo's ``geom_size`` (3,): radius / half-lengths / half-extents, m."""
    rgba: np.ndarray
    """Colour (4,), 0..1, as MuJoCo renders it (geom colour or material colour × texture)."""
    p_body_geom: np.ndarray
    """Geom position in its body frame (3,), m."""
    q_body_geom: np.ndarray
    """Geom orientation in its body frame, ``wxyz`` (4,)."""
    mesh: tuple[np.ndarray, np.ndarray] | None = None
    """(vertices (n, 3) float32 in the geom frame, faces (m, 3) uint32) of a mesh geom."""


def _texture_mean_rgb(model: mujoco.MjModel, texid: int) -> np.ndarray:
    """Mean RGB (3,), 0..1, of texture ``texid`` (the colour a textured surface averages to)."""
    adr = int(model.tex_adr[texid])
    n = int(model.tex_width[texid] * model.tex_height[texid])
    channels = int(model.tex_nchannel[texid])
    data = np.asarray(model.tex_data[adr : adr + n * channels], dtype=float).reshape(n, channels)
    rgb = data[:, :3] if channels >= 3 else np.repeat(data[:, :1], 3, axis=1)
    return rgb.mean(axis=0) / 255.0


def geom_rgba(model: mujoco.MjModel, geom: int) -> np.ndarray:
    """The colour (4,), 0..1, MuJoCo renders ``geom`` with: its own ``rgba`` when set (not
    the default), else its material's colour (tinted by the mean of the material's RGB
    texture, if any), else the default grey."""
    rgba = np.asarray(model.geom_rgba[geom], dtype=float)
    matid = int(model.geom_matid[geom])
    if matid < 0 or not np.allclose(rgba, DEFAULT_GEOM_RGBA):
        return rgba.copy()
    out = np.asarray(model.mat_rgba[matid], dtype=float).copy()
    texid = int(model.mat_texid[matid, int(mujoco.mjtTextureRole.mjTEXROLE_RGB)])
    if texid >= 0:
        out[:3] *= _texture_mean_rgb(model, texid)
    return out


def is_visible(model: mujoco.MjModel, geom: int) -> bool:
    """Whether MuJoCo's default visualisation shows ``geom``: a group it shows
    (:data:`SHOWN_GROUPS`), not fully transparent, a shape the view draws."""
    return (
        int(model.geom_group[geom]) in SHOWN_GROUPS
        and geom_rgba(model, geom)[3] > 0.0
        and int(model.geom_type[geom]) in SHAPES
    )


def _mesh_of(model: mujoco.MjModel, geom: int) -> tuple[np.ndarray, np.ndarray]:
    mesh = int(model.geom_dataid[geom])
    v0, nv = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
    f0, nf = int(model.mesh_faceadr[mesh]), int(model.mesh_facenum[mesh])
    vertices = np.asarray(model.mesh_vert[v0 : v0 + nv], dtype=np.float32)
    faces = np.asarray(model.mesh_face[f0 : f0 + nf], dtype=np.uint32)
    return vertices, faces


def visible_geoms(model: mujoco.MjModel) -> list[GeomVisual]:
    """Every geom :func:`is_visible` shows, in geom order."""
    out = []
    for g in range(model.ngeom):
        if not is_visible(model, g):
            continue
        shape = SHAPES[int(model.geom_type[g])]
        out.append(
            GeomVisual(
                geom=g,
                body=int(model.geom_bodyid[g]),
                shape=shape,
                size=np.asarray(model.geom_size[g], dtype=float).copy(),
                rgba=geom_rgba(model, g),
                p_body_geom=np.asarray(model.geom_pos[g], dtype=float).copy(),
                q_body_geom=np.asarray(model.geom_quat[g], dtype=float).copy(),
                mesh=_mesh_of(model, g) if shape == "mesh" else None,
            )
        )
    return out


def moving_bodies(model: mujoco.MjModel) -> np.ndarray:
    """Ids of the bodies whose world pose depends on ``qpos``: not welded to the world
    (``body_weldid`` ≠ 0). Mocap bodies (moved by ``mocap_pos``, not ``qpos``) are static."""
    ids = np.arange(model.nbody)
    return ids[(model.body_weldid != 0) & (model.body_mocapid < 0)]


def capsule_mesh(
    radius: float, half_length: float, segments: int = 16, cap_rings: int = 4
) -> tuple[np.ndarray, np.ndarray]:
    """A capsule along z centred at the origin (MuJoCo's capsule frame): vertices (n, 3)
    float32, m, and outward-facing (counter-clockwise) triangles (m, 3) uint32.

    ``segments`` vertices around, ``cap_rings`` rings per hemisphere (the equator rings of
    both hemispheres bound the cylindrical part).
    """
    if radius <= 0 or half_length < 0:
        raise ValueError(
            f"capsule needs radius > 0 and half_length >= 0, got {radius}, {half_length}"
        )
    phi = 2 * np.pi * np.arange(segments) / segments
    # Polar angles of the rings, top hemisphere (shifted +h) then bottom (shifted −h).
    theta = np.concatenate(
        [
            np.pi / 2 * np.arange(1, cap_rings + 1) / cap_rings,
            np.pi / 2 + np.pi / 2 * np.arange(cap_rings) / cap_rings,
        ]
    )
    shift = np.where(np.arange(2 * cap_rings) < cap_rings, half_length, -half_length)
    rho, z = radius * np.sin(theta), radius * np.cos(theta) + shift
    rings = np.stack(
        [
            np.outer(rho, np.cos(phi)),
            np.outer(rho, np.sin(phi)),
            np.repeat(z[:, None], segments, 1),
        ],
        axis=-1,
    ).reshape(-1, 3)
    top, bottom = [0.0, 0.0, half_length + radius], [0.0, 0.0, -half_length - radius]
    vertices = np.vstack([top, rings, bottom]).astype(np.float32)
    n_rings, k = 2 * cap_rings, np.arange(segments)
    k1 = (k + 1) % segments
    faces = [np.stack([np.zeros(segments, int), 1 + k, 1 + k1], axis=1)]
    for j in range(n_rings - 1):
        a, b = 1 + j * segments + k, 1 + j * segments + k1
        c, d = a + segments, b + segments
        faces += [np.stack([a, c, d], axis=1), np.stack([a, d, b], axis=1)]
    last = 1 + (n_rings - 1) * segments
    faces.append(np.stack([np.full(segments, len(vertices) - 1), last + k1, last + k], axis=1))
    return vertices, np.vstack(faces).astype(np.uint32)


# ----------------------------------------------------------------- guidance force
#: Forces below this are not drawn, N.
MIN_DRAWN_FORCE_N = 1e-3


def guidance_arrows(
    extras: Mapping[str, Any],
    p_world_tips: Mapping[str, np.ndarray],
    R_world_camera: np.ndarray,
    scale_m_per_N: float,
) -> dict[str, np.ndarray]:
    """PSM -> its guidance force arrow ``[start, end]`` (2, 3), world frame, m.

    ``extras`` are a snapshot's: the haptic loop's state (``extras["haptics"]``) has, per
    MTM, the fields' summed wrench (``requested``, N, camera axes); each PSM teleoperation's
    state (``mtm``, ``psm``, ``following``) says which PSM that MTM drives. An arrow is
    drawn for a following teleoperation with a finite force of at least
    :data:`MIN_DRAWN_FORCE_N`, from the PSM's tip (``p_world_tips``, m) along
    ``R_world_camera @ f``, ``scale_m_per_N`` long per newton.
    """
    requested = getattr(extras.get("haptics"), "requested", None)
    if not requested:
        return {}
    out = {}
    for value in extras.values():
        psm, mtm = getattr(value, "psm", None), getattr(value, "mtm", None)
        if not getattr(value, "following", False) or psm not in p_world_tips:
            continue
        wrench = requested.get(mtm)
        if wrench is None:
            continue
        f_camera = np.asarray(wrench, dtype=float)[:3]
        if not np.all(np.isfinite(f_camera)) or np.linalg.norm(f_camera) < MIN_DRAWN_FORCE_N:
            continue
        start = np.array(p_world_tips[psm], dtype=float)
        out[psm] = np.stack([start, start + scale_m_per_N * (R_world_camera @ f_camera)])
    return out


# ----------------------------------------------------------------- camera presets
@dataclass(frozen=True)
class CameraPreset:
    """A viewpoint: eye ``position`` and ``look_at`` point (world, m), ``up`` direction,
    vertical field of view (degrees)."""

    name: str
    position: tuple[float, float, float]
    look_at: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    fovy_deg: float = 50.0
    description: str = ""


def _id(model, kind: mujoco.mjtObj, name: str) -> int:
    return mujoco.mj_name2id(model, kind, name)


def _tuple(v) -> tuple[float, float, float]:
    return tuple(float(x) for x in v)  # type: ignore[return-value]


def _looking(name, p, forward, up, target, fovy_deg, description) -> CameraPreset:
    """A preset at ``p`` looking along ``forward`` (unit) with ``up``, its orbit centre where
    that line passes closest to ``target``."""
    distance = max(0.05, float(np.dot(np.asarray(target) - p, forward)))
    return CameraPreset(
        name, _tuple(p), _tuple(p + distance * forward), _tuple(up), fovy_deg, description
    )


def camera_presets(model: mujoco.MjModel, data: mujoco.MjData) -> dict[str, CameraPreset]:
    """The bedside view's presets for ``model`` posed as in ``data`` (after
    ``mj_kinematics``; camera poses need ``mj_camlight`` too, done here):

    * ``overview``: the model's ``overview`` camera (patient cart, table and console);
    * ``bedside``: an assistant standing at the table opposite the cart, eyes at 1.7 m,
      looking at the instruments;
    * ``console``: over the operator's shoulder at the surgeon console, its masters in view
      (scenes with a console);
    * ``monitor_task``: the seed's external monitoring view of the task (seed Fig. 5a): from
      above the far side of the table, down onto the tool tips with the arms behind them;
    * ``monitor_system``: the seed's view of the system (seed Fig. 1): the arms above the
      operating bed, from the foot of the bed;
    * ``endoscope``: the ECM's left camera where it is in ``data`` (scenes with an ECM);
    * every other named world camera of the model (``SceneConfig.cameras``), as it is.
    """
    mujoco.mj_camlight(model, data)
    presets: dict[str, CameraPreset] = {}
    tips = [
        data.site_xpos[i]
        for i in range(model.nsite)
        if (model.site(i).name.startswith("PSM") and model.site(i).name.endswith("/tip"))
    ]
    table = _id(model, mujoco.mjtObj.mjOBJ_BODY, "table")
    if tips:
        work = np.mean(tips, axis=0)
    elif table >= 0:
        work = data.xpos[table] + [0.0, 0.0, 0.75]
    else:
        work = np.array([0.0, 1.0, 0.9])
    for c in range(model.ncam):
        name = model.camera(c).name
        if not name or model.cam_bodyid[c] != 0:
            continue  # cameras on moving bodies (the endoscope) are handled below
        R = data.cam_xmat[c].reshape(3, 3)  # a MuJoCo camera looks along −z, y up
        presets[name] = _looking(
            name,
            data.cam_xpos[c],
            -R[:, 2],
            R[:, 1],
            work,
            float(model.cam_fovy[c]),
            f"the model's {name!r} camera",
        )
    # The assistant's side of the table is away from the cart (the cart is the world origin).
    side = np.array([work[0], work[1], 0.0])
    side = side / (np.linalg.norm(side) or 1.0)
    eye = work + 1.0 * side
    eye[2] = 1.7
    presets["bedside"] = CameraPreset(
        "bedside",
        _tuple(eye),
        _tuple(work),
        fovy_deg=55.0,
        description="an assistant at the table, opposite the cart",
    )
    console = _id(model, mujoco.mjtObj.mjOBJ_BODY, "console")
    if console >= 0:
        mtms = [
            data.site_xpos[i] for i in range(model.nsite) if model.site(i).name.startswith("MTM")
        ]
        hands = np.mean(mtms, axis=0) if mtms else data.xpos[console] + [0.0, 0.0, 1.0]
        # The console frame: origin on the floor below the operator's eyes, x to the
        # operator's right, y forward (model/console.py); the eye behind the right shoulder.
        R = data.xmat[console].reshape(3, 3)
        eye = data.xpos[console] + R @ [0.45, -0.85, 1.75]
        presets["console"] = CameraPreset(
            "console",
            _tuple(eye),
            _tuple(hands),
            fovy_deg=50.0,
            description="over the operator's shoulder at the surgeon console",
        )
    presets["monitor_task"] = CameraPreset(
        "monitor_task",
        _tuple(work + 0.55 * side + [0.0, 0.0, 0.45]),
        _tuple(work - [0, 0, 0.05]),
        fovy_deg=45.0,
        description="the seed's monitoring view of the task (Fig. 5a)",
    )
    presets["monitor_system"] = CameraPreset(
        "monitor_system",
        _tuple(work + [2.0, 0.9, 0.6]),
        _tuple(work * [1, 0.75, 1] + [0, 0, 0.15]),
        fovy_deg=45.0,
        description="the seed's view of the arms over the bed (Fig. 1)",
    )
    ecm_tip = _id(model, mujoco.mjtObj.mjOBJ_SITE, "ECM/tip")
    if ecm_tip >= 0:
        # The ECM tip frame is the camera frame (z into the scene, y up in the image).
        R = data.site_xmat[ecm_tip].reshape(3, 3)
        presets["endoscope"] = _looking(
            "endoscope",
            data.site_xpos[ecm_tip],
            R[:, 2],
            R[:, 1],
            work,
            45.0,
            "the endoscope (ECM tip) where it is now",
        )
    return presets
