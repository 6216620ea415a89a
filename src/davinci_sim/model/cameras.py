"""Cameras: the ECM stereo endoscope, the overview camera and user-defined external views."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from davinci_sim.geometry.se3 import look_at_rotation, rot_y, transform
from davinci_sim.kinematics.jit import helper
from davinci_sim.model.frames import set_pose

#: Classic SD 12 mm stereo endoscope: a diagonal field of view of about 70° is typical for
#: laparoscopes of that generation; on a 4:3 sensor that is 2·atan(0.6·tan 35°) ≈ 45°
#: vertically (≈ 57° horizontally).
DEFAULT_ENDOSCOPE_FOVY_DEG = 45.0


@dataclass(frozen=True)
class CameraConfig:
    """The stereo endoscope: image size (pixels), vertical field of view, stereo baseline."""

    width: int = 640
    height: int = 480
    fovy_deg: float = DEFAULT_ENDOSCOPE_FOVY_DEG
    baseline_m: float = 0.005

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"image size must be positive, got {self.width}x{self.height}")
        if not 0.0 < self.fovy_deg < 180.0:
            raise ValueError(f"fovy_deg must be in (0, 180), got {self.fovy_deg!r}")
        if self.baseline_m < 0.0:
            raise ValueError(f"baseline_m must be >= 0, got {self.baseline_m!r}")

    @property
    def focal_px(self) -> float:
        """The pinhole's focal length, px (:func:`focal_length_px` of this image)."""
        return focal_length_px(self.height, self.fovy_deg)


def focal_length_px(height: float, fovy_deg: float) -> float:
    """MuJoCo's pinhole focal length, px, of an image ``height`` px high with a vertical
    field of view of ``fovy_deg``: ``(h/2) / tan(fovy/2)`` (square pixels)."""
    return 0.5 * height / math.tan(math.radians(fovy_deg) / 2.0)


@helper
def in_left_image_floats(x, y, z, f_px, half_baseline, width, height) -> bool:
    """Whether the camera-frame point (``x``, ``y``, ``z``), m, projects inside the left
    image (:func:`project_left`'s arithmetic, in its order): focal length ``f_px`` px, the
    left camera ``half_baseline`` m towards +x, a ``width`` x ``height`` image. One point on
    floats: the compiled task ticks call it."""
    if not z > 1e-6:
        return False
    u = width / 2.0 - f_px * (x - half_baseline) / z
    v = height / 2.0 - f_px * y / z
    return 0 <= u < width and 0 <= v < height


@dataclass(frozen=True)
class ExternalCamera:
    """A fixed named camera in the world (cart) frame looking at ``target``."""

    name: str
    position: tuple[float, float, float]
    target: tuple[float, float, float]
    fovy_deg: float = 45.0


#: The default overview: the patient cart, the table and the surgeon console.
OVERVIEW = ExternalCamera("overview", (2.3, -2.9, 2.5), (-0.45, 0.2, 0.75), 50.0)


def T_tip_camera(side: float, baseline_m: float) -> np.ndarray:
    """Pose of one endoscope camera in the ECM tip frame (side +1 = left, −1 = right).

    The tip frame follows the ISI/HRSV convention (x to the left of the image, y up, z into
    the scene); a MuJoCo camera looks along −z with y up, hence the 180° turn about y. The
    left camera is half a baseline towards +x (the image's left).
    """
    return transform(p=[side * baseline_m / 2, 0.0, 0.0]) @ transform(rot_y(np.pi))


def add_endoscope_cameras(roll_body, T_roll_tip: np.ndarray, config: CameraConfig) -> None:
    """``ECM/left`` and ``ECM/right`` on the ECM roll body."""
    for name, side in (("left", 1.0), ("right", -1.0)):
        cam = roll_body.add_camera(name=f"ECM/{name}")
        set_pose(cam, np.asarray(T_roll_tip) @ T_tip_camera(side, config.baseline_m))
        cam.fovy = config.fovy_deg
        cam.resolution = [config.width, config.height]


def add_external_camera(world, camera: ExternalCamera) -> None:
    """A fixed world camera."""
    cam = world.add_camera(name=camera.name)
    R = look_at_rotation(camera.position, camera.target)
    set_pose(cam, transform(R, camera.position))
    cam.fovy = camera.fovy_deg


def project_left(p_camera, camera: CameraConfig) -> tuple[float, float] | None:
    """Pixel (u right, v down) of the camera-frame point ``p_camera`` (m; the ECM tip frame,
    x to the image's left, y up, z into the scene) in the left endoscope image, or None
    behind the camera: MuJoCo's pinhole, ``f = (h/2) / tan(fovy/2)``, principal point at the
    image centre, the left camera half a baseline towards +x (:func:`T_tip_camera`)."""
    x, y, z = (float(c) for c in p_camera)
    if z <= 1e-6:
        return None
    f = camera.focal_px
    x_left = x - camera.baseline_m / 2.0  # the left camera is half a baseline towards +x
    return (camera.width / 2.0 - f * x_left / z, camera.height / 2.0 - f * y / z)


def in_left_image(p_camera, camera: CameraConfig) -> np.ndarray:
    """(n,) bool: the camera-frame points ``p_camera`` (n, 3), m, project inside the left
    endoscope image (0 ≤ u < width, 0 ≤ v < height, in front of the camera): the rows of
    :func:`project_left`, for a batch of points."""
    p = np.asarray(p_camera, dtype=float).reshape(-1, 3)
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    front = z > 1e-6
    f = camera.focal_px
    zs = np.where(front, z, 1.0)
    u = camera.width / 2.0 - f * (x - camera.baseline_m / 2.0) / zs
    v = camera.height / 2.0 - f * y / zs
    return front & (u >= 0) & (u < camera.width) & (v >= 0) & (v < camera.height)
