"""What the page needs to draw the endoscope itself: the scene once, then poses per frame.

The page draws the stereo endoscope with three.js (``static/endoscope.js``) from the same
compiled model the server renders (the system's ``model_source``, the task's drawing
included), so the two views show one scene:

* :func:`scene_message` (JSON, once per page): every geom MuJoCo's default visualisation
  shows (:func:`~davinci_sim.web.scene3d_model.visible_geoms`: shape, size, colour, the
  material's specular and shininess, pose in its body), the pose of every body that carries
  one (world frame), which of them move, the model's lights, MuJoCo's headlight, the clip
  planes (``vis.map.znear``/``zfar`` × ``stat.extent``, as MuJoCo's renderer uses them) and
  the endoscope's two cameras: vertical field of view, image size, stereo baseline.
* :class:`PoseStream` (binary, per frame, a few KB): the joint positions of a snapshot
  through ``mj_kinematics`` (and ``mj_camlight``), then the world pose of each moving body,
  of both cameras and of each light, as float32. The layout is :data:`POSE_HEADER` and
  :func:`pose_layout`.

A MuJoCo camera looks along its −z with y up, as an OpenGL camera does, so the page sets
its camera's world matrix to the camera's pose and its projection from ``fovy`` and the
image's aspect: the same pinhole as :func:`davinci_sim.model.cameras.project_left`.
All lengths in m, world (cart) frame; quaternions ``wxyz`` as in MuJoCo.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import mujoco
import numpy as np

from davinci_sim.web.scene3d_model import (
    INFINITE_PLANE_HALF_EXTENT,
    moving_bodies,
    visible_geoms,
)

#: The endoscope's cameras, left then right (``model.cameras.add_endoscope_cameras``).
ENDOSCOPE_CAMERAS = ("ECM/left", "ECM/right")
#: First field of a pose message; an endoscope JPEG frame's first field (its frame number,
#: masked to 31 bits) never takes this value.
POSE_MAGIC = 0xFFFFFFFF
#: A pose message's header: magic (uint32), the tick's low 32 bits (uint32), sim time
#: (float64, s); then float32 values (:func:`pose_layout`).
POSE_HEADER = struct.Struct("<IId")
#: MuJoCo's defaults for a geom without a material (``mjsMaterial``: specular, shininess).
DEFAULT_SPECULAR, DEFAULT_SHININESS = 0.5, 0.5


@dataclass(frozen=True)
class PoseLayout:
    """Where each pose sits in a pose message's float32 values."""

    bodies: tuple[int, ...]
    """Moving body ids: 7 values each (position, quaternion wxyz), in this order."""
    cameras: tuple[int, ...]
    """Camera ids (left, right): 7 values each, after the bodies."""
    lights: tuple[int, ...]
    """Light ids: 6 values each (position, direction), after the cameras."""

    @property
    def size(self) -> int:
        """Number of float32 values after the header."""
        return 7 * (len(self.bodies) + len(self.cameras)) + 6 * len(self.lights)


def endoscope_camera_ids(model: mujoco.MjModel) -> tuple[int, ...]:
    """Ids of :data:`ENDOSCOPE_CAMERAS`; ``ValueError`` if the model has no endoscope."""
    ids = tuple(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, n) for n in ENDOSCOPE_CAMERAS)
    if min(ids) < 0:
        raise ValueError("the model has no endoscope (cameras ECM/left and ECM/right)")
    return ids


def pose_layout(model: mujoco.MjModel) -> PoseLayout:
    """The layout of this model's pose messages: the moving bodies that carry a visible geom,
    the endoscope cameras, every light."""
    drawn = {g.body for g in visible_geoms(model)}
    bodies = tuple(int(b) for b in moving_bodies(model) if int(b) in drawn)
    return PoseLayout(bodies, endoscope_camera_ids(model), tuple(range(model.nlight)))


def _material(model: mujoco.MjModel, geom: int) -> tuple[float, float]:
    matid = int(model.geom_matid[geom])
    if matid < 0:
        return DEFAULT_SPECULAR, DEFAULT_SHININESS
    return float(model.mat_specular[matid]), float(model.mat_shininess[matid])


def _floats(a) -> list[float]:
    return [float(x) for x in np.asarray(a, dtype=float).reshape(-1)]


def scene_message(
    model: mujoco.MjModel, data: mujoco.MjData, baseline_m: float, layout: PoseLayout | None = None
) -> dict:
    """The page's scene (JSON-ready), with the static bodies' poses from ``data`` (after
    ``mj_kinematics``). ``baseline_m``: the endoscope's stereo baseline (the cameras'
    distance, also in their poses; the page shows it). ``layout``: the model's
    :func:`pose_layout`, when the caller has it."""
    layout = pose_layout(model) if layout is None else layout
    geoms = []
    for g in visible_geoms(model):
        size = np.asarray(g.size, dtype=float)
        if g.shape == "plane":  # (0: infinite in MuJoCo; drawn this large)
            size = np.where(size[:2] > 0, size[:2], INFINITE_PLANE_HALF_EXTENT)
        specular, shininess = _material(model, g.geom)
        geom = {
            "id": g.geom,
            "body": g.body,
            "shape": g.shape,
            "size": _floats(size),
            "rgba": _floats(g.rgba),
            "specular": specular,
            "shininess": shininess,
            "pos": _floats(g.p_body_geom),
            "quat": _floats(g.q_body_geom),
        }
        if g.mesh is not None:
            geom["vertices"] = _floats(g.mesh[0])
            geom["faces"] = [int(i) for i in np.asarray(g.mesh[1]).reshape(-1)]
        geoms.append(geom)
    bodies = sorted({g["body"] for g in geoms})
    cameras = []
    for c in layout.cameras:
        cameras.append({
            "name": model.camera(c).name,
            "fovy_deg": float(model.cam_fovy[c]),
            "width": int(model.cam_resolution[c][0]),
            "height": int(model.cam_resolution[c][1]),
        })  # fmt: skip
    lights = []
    for k in layout.lights:
        lights.append({
            "directional": int(model.light_type[k]) == int(mujoco.mjtLightType.mjLIGHT_DIRECTIONAL),
            "diffuse": _floats(model.light_diffuse[k]),
            "ambient": _floats(model.light_ambient[k]),
            "specular": _floats(model.light_specular[k]),
            "cutoff_deg": float(model.light_cutoff[k]),
            "exponent": float(model.light_exponent[k]),
            "attenuation": _floats(model.light_attenuation[k]),
            "active": bool(model.light_active[k]),
        })  # fmt: skip
    head = model.vis.headlight
    extent = float(model.stat.extent)
    return {
        "op": "scene",
        "geoms": geoms,
        "bodies": {str(b): _floats(np.concatenate([data.xpos[b], data.xquat[b]])) for b in bodies},
        "layout": {
            "bodies": list(layout.bodies),
            "cameras": len(layout.cameras),
            "lights": len(layout.lights),
        },  # fmt: skip
        "cameras": cameras,
        "baseline_m": float(baseline_m),
        "lights": lights,
        "headlight": {
            "active": bool(head.active),
            "ambient": _floats(head.ambient),
            "diffuse": _floats(head.diffuse),
            "specular": _floats(head.specular),
        },
        "znear": float(model.vis.map.znear) * extent,
        "zfar": float(model.vis.map.zfar) * extent,
        "haze": _floats(model.vis.rgba.haze),
    }


class PoseStream:
    """Pose messages of one model from joint positions; see the module docstring.

    Args:
        model: the compiled model the page draws (the same as the server renders).
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.layout = pose_layout(model)
        self._bodies = np.asarray(self.layout.bodies, dtype=int)
        self._cameras = np.asarray(self.layout.cameras, dtype=int)
        self._lights = np.asarray(self.layout.lights, dtype=int)
        self._quat = np.empty((len(self._cameras), 4))
        mujoco.mj_kinematics(model, self.data)
        mujoco.mj_camlight(model, self.data)

    def scene(self, baseline_m: float) -> dict:
        """:func:`scene_message` of this model at the last joint positions given."""
        return scene_message(self.model, self.data, baseline_m, self.layout)

    def message(self, qpos, tick: int, t: float) -> bytes:
        """The pose message of joint positions ``qpos`` (nq,) at tick ``tick``, time ``t`` s.

        Raises:
            ValueError: ``qpos`` of the wrong size or not finite (nothing is changed).
        """
        q = np.asarray(qpos, dtype=float)
        if q.shape != (self.model.nq,) or not np.all(np.isfinite(q)):
            raise ValueError(f"qpos must be {self.model.nq} finite values, got shape {q.shape}")
        d = self.data
        d.qpos[:] = q
        mujoco.mj_kinematics(self.model, d)
        mujoco.mj_camlight(self.model, d)
        for k, c in enumerate(self._cameras):
            mujoco.mju_mat2Quat(self._quat[k], d.cam_xmat[c])
        b, c, li = self._bodies, self._cameras, self._lights
        values = np.concatenate([
            np.hstack([d.xpos[b], d.xquat[b]]).reshape(-1),
            np.hstack([d.cam_xpos[c], self._quat]).reshape(-1),
            np.hstack([d.light_xpos[li], d.light_xdir[li]]).reshape(-1),
        ]).astype(np.float32)  # fmt: skip
        return POSE_HEADER.pack(POSE_MAGIC, tick & 0xFFFFFFFF, float(t)) + values.tobytes()


def decode_poses(message: bytes, layout: PoseLayout) -> dict[str, np.ndarray]:
    """A pose message's values (for tests and tools): ``bodies`` (n, 7), ``cameras`` (2, 7),
    ``lights`` (k, 6), ``tick`` and ``time``.

    Raises:
        ValueError: not a pose message of this layout.
    """
    magic, tick, t = POSE_HEADER.unpack_from(message)
    values = np.frombuffer(message, np.float32, offset=POSE_HEADER.size)
    if magic != POSE_MAGIC or values.size != layout.size:
        raise ValueError(f"not a pose message of this layout ({values.size} values)")
    nb, nc = 7 * len(layout.bodies), 7 * len(layout.cameras)
    return {
        "tick": np.int64(tick),
        "time": np.float64(t),
        "bodies": values[:nb].reshape(-1, 7),
        "cameras": values[nb : nb + nc].reshape(-1, 7),
        "lights": values[nb + nc :].reshape(-1, 6),
    }
