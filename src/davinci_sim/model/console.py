"""The surgeon console: cabinet, stereo viewer, arm rest, pedals, and the two MTMs.

The console body's frame C has its origin on the floor below the operator's eyes, x to the
operator's right, y forward (towards the viewer), z up. The child body ``console/HRSV`` is
the HRSV frame of the dVRK (dvrk.md 1.5): origin between the operator's eyes, x to the
left, y up and z away from the user, the display pointing down at 60° from horizontal; the
MTM bases are placed in it at their configured ``T_reference_base``.
"""

from __future__ import annotations

import numpy as np

from davinci_sim.geometry.se3 import rot_z, transform
from davinci_sim.kinematics.arms import load_arm
from davinci_sim.model.frames import set_pose
from davinci_sim.model.mtm import add_mtm
from davinci_sim.model.shapes import Painter

EYE_HEIGHT = 1.25
"""Height of the HRSV origin (seated operator's eyes in the viewer), m."""

#: Rotation of HRSV in C: x_h = left, y_h = 0.5·up + 0.866·forward,
#: z_h = −0.866·up + 0.5·forward (the viewing direction, 60° below horizontal).
_S = np.sqrt(3.0) / 2.0
R_C_HRSV = np.array([[-1.0, 0.0, 0.0], [0.0, _S, 0.5], [0.0, 0.5, -_S]])

#: Where the console stands: operator's eyes above (x, y) = (−1.7, −1.25) facing +y, about
#: 2 m from the patient cart, looking towards the patient as in a real operating room.
CONSOLE_POSITION = (-1.7, -1.25)
CONSOLE_HEADING = 0.0


def T_world_console() -> np.ndarray:
    """Pose of the console frame C in the world (cart) frame."""
    x, y = CONSOLE_POSITION
    return transform(rot_z(CONSOLE_HEADING), [x, y, 0.0])


def add_console(world, mtms: tuple[str, ...]):
    """Add the console and the MTMs in ``mtms``; returns the HRSV body."""
    console = world.add_body(name="console")
    set_pose(console, T_world_console())
    paint = Painter(console, prefix="console/")
    # Base cabinet with the foot-pedal tray.
    paint.box([0.0, 0.62, 0.36], [0.50, 0.28, 0.36], "console")
    paint.box([0.0, 0.22, 0.04], [0.34, 0.14, 0.04], "console_dark")
    for x in (-0.2, -0.07, 0.07, 0.2):
        paint.box([x, 0.22, 0.09], [0.04, 0.07, 0.01], "black")
    # Side pillars and the head/viewer housing above the hand workspace.
    for x in (-0.48, 0.48):
        paint.box([x, 0.62, 1.0], [0.03, 0.26, 0.30], "console")
    paint.box([0.0, 0.58, 1.45], [0.50, 0.32, 0.17], "console")
    # Arm rest in front of the operator, below the hands (MTM grips at ≈ 0.9 m at q = 0).
    paint.capsule([-0.42, 0.12, 0.70], [0.42, 0.12, 0.70], 0.035, "console_dark")
    for x in (-0.42, 0.42):
        paint.capsule([x, 0.12, 0.70], [x, 0.36, 0.70], 0.03, "console_dark")
    hrsv = console.add_body(name="console/HRSV")
    set_pose(hrsv, transform(R_C_HRSV, [0.0, 0.0, EYE_HEIGHT]))
    site = hrsv.add_site(name="console/HRSV", size=[0.01, 0, 0])
    site.group = 5
    # Stereo viewer: eyepieces 64 mm apart just in front of the eyes, looking along +z_h,
    # and the viewer housing that joins the head housing above.
    view = Painter(hrsv, prefix="console/")
    for x in (0.032, -0.032):
        view.cylinder([x, 0, 0.015], [x, 0, 0.05], 0.017, "viewer_glass")
    view.box([0.0, 0.01, 0.10], [0.13, 0.06, 0.05], "console_dark")
    view.box([0.0, 0.10, 0.12], [0.13, 0.06, 0.09], "console_dark")
    for name in mtms:
        add_mtm(hrsv, name, load_arm(name))
    return hrsv
