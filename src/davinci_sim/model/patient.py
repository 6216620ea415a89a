"""The floor, the operating table, the tissue phantom and the graspable bead.

The table's long axis is the cart's x axis and the patient lies across the cart's reach
(+y). The tissue surface is at :data:`TISSUE_SURFACE_Z`, a few cm below the instrument tips
at the dVRK home pose (tips at z ≈ 0.80-0.87 m for the simulated SUJ pose, dvrk.md 1.6-1.7).
"""

from __future__ import annotations

import mujoco
import numpy as np

from davinci_sim.geometry.se3 import rot_z, transform
from davinci_sim.model.frames import set_pose
from davinci_sim.model.shapes import Painter, set_inertial

TABLE_TOP_Z = 0.70
TISSUE_SURFACE_Z = 0.765
"""Top of the tissue pad, m (cart frame)."""
TABLE_CENTER_XY = (0.05, 1.22)
PAD_CENTER_XY = (0.09, 1.19)
PAD_HALF_XY = (0.21, 0.13)
BEAD_RADIUS = 0.0035
"""The bead is a 7 mm steel ball: a sphere is grasped the same way whatever its orientation
and, unlike a cube, clears the open jaws, which pivot about the wrist-yaw axis."""
BEAD_MASS = 0.0014
POST_HEIGHT = 0.010
"""The bead rests on a three-point seat on a post (as on a peg-transfer board) so that the
open jaws reach around it without digging into the tissue."""
POST_HALF_WIDTH = 0.0025
SEAT_BALL_RADIUS = 0.001
SEAT_CIRCLE_RADIUS = 0.0022


def bead_rest_height() -> float:
    """Height of the bead centre above the tissue when it sits on its seat, m."""
    reach = BEAD_RADIUS + SEAT_BALL_RADIUS
    return POST_HEIGHT + SEAT_BALL_RADIUS + np.sqrt(reach**2 - SEAT_CIRCLE_RADIUS**2)


def add_floor(world) -> None:
    """An infinite floor plane (it collides: a dropped bead stops on it)."""
    Painter(world).add("env", "floor", "floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05])


def add_table(world):
    """Operating table with a tissue pad and an organ-like bowel loop on it."""
    table = world.add_body(name="table")
    tx, ty = TABLE_CENTER_XY
    set_pose(table, transform(p=[tx, ty, 0.0]))
    paint = Painter(table, prefix="table/")
    paint.box([0, 0, TABLE_TOP_Z - 0.04], [1.0, 0.27, 0.04], "table", kind="env", name="top")
    paint.box([0, 0, TABLE_TOP_Z - 0.095], [0.95, 0.24, 0.015], "table_frame")
    paint.box([0, 0, 0.33], [0.18, 0.14, 0.27], "table_frame")
    paint.box([0, 0, 0.04], [0.55, 0.26, 0.04], "table_frame")
    px, py = PAD_CENTER_XY[0] - tx, PAD_CENTER_XY[1] - ty
    pad_half_z = (TISSUE_SURFACE_Z - TABLE_TOP_Z) / 2
    paint.box(
        [px, py, TABLE_TOP_Z + pad_half_z],
        [PAD_HALF_XY[0], PAD_HALF_XY[1], pad_half_z],
        "tissue",
        kind="env",
        name="tissue",
    )
    # A bowel-like loop of capsules on the pad, away from the PSM1 grasp spot (as the organ
    # of the paper's path-following task, seed fig. 5).
    r = 0.011
    z = TISSUE_SURFACE_Z + r * 0.8
    loop = np.array(
        [[0.07, -0.02], [0.12, -0.06], [0.19, -0.05], [0.22, 0.0], [0.19, 0.05], [0.13, 0.07]]
    )
    for (x0, y0), (x1, y1) in zip(loop[:-1], loop[1:], strict=True):
        paint.capsule(
            [px + x0 - 0.09, py + y0, z], [px + x1 - 0.09, py + y1, z], r, "organ", kind="env"
        )
    return table


def add_bead(world, position, yaw: float):
    """The graspable bead ``object/bead`` (free joint) resting in its cup at ``position``."""
    post = world.add_body(name="object/post")
    set_pose(post, transform(rot_z(yaw), [position[0], position[1], TISSUE_SURFACE_Z]))
    paint = Painter(post, prefix="object/")
    paint.box(
        [0, 0, POST_HEIGHT / 2],
        [POST_HALF_WIDTH, POST_HALF_WIDTH, POST_HEIGHT / 2],
        "shell_dark",
        kind="env",
        name="post",
    )
    # Three small balls: the bead rests on them as on a tripod.
    for angle in (0.0, 2 * np.pi / 3, 4 * np.pi / 3):
        center = [
            SEAT_CIRCLE_RADIUS * np.cos(angle),
            SEAT_CIRCLE_RADIUS * np.sin(angle),
            POST_HEIGHT + SEAT_BALL_RADIUS,
        ]
        paint.sphere(center, SEAT_BALL_RADIUS, "shell_dark", kind="env")
    bead = world.add_body(name="object/bead")
    set_pose(bead, transform(rot_z(yaw), position))
    bead.add_freejoint(name="object/bead")
    paint = Painter(bead, prefix="object/")
    paint.sphere([0, 0, 0], BEAD_RADIUS, "bead", kind="object", name="bead")
    set_inertial(bead, BEAD_MASS, [0, 0, 0], 0.4 * BEAD_MASS * BEAD_RADIUS**2)
    return bead
