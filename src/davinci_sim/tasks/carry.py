"""An object carried in the jaws along a path, and the wrist turns the path asks for.

A path task's optional ``carry`` section (:class:`CarrySpec`): a torus held at its rim in
the jaws of the task's PSM, and the turn of the tool from its start orientation as a
function of progress along the path (rotation vectors in the task's frame, rad, at knots of
progress 0..1, linear between). Rota's Path task has one (``rota_path``: their torus's size
from their scene, the turns their control group made, ``scripts/rota_wrist.py``).

The torus is drawn on the wrist (visual only, it moves with the tool: the tip point's
distance to the path is what the task scores, as theirs did). Its plane holds the jaws'
direction (tip z) and the hinge axis (tip x): the jaws close across it (tip y) on the tube
``grasp_depth`` m ahead of the tip point, and the ring reaches on beyond the jaws.

The turns are the orientation ``task check`` checks the tool can reach at each knot's
point: the start orientation at the task's keyframe, turned by the knot's rotation.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from davinci_sim.geometry.so3 import rotation_from_vector
from davinci_sim.tasks.base import TaskError
from davinci_sim.tasks.schema import NONNEGATIVE, POINT, ListOf, Number, Record, Vector

#: The ``carry`` section's schema (:mod:`davinci_sim.tasks.schema`).
CARRY_SCHEMA = Record(
    {
        "torus_radius": Number(above=0.0),
        "tube_radius": Number(above=0.0),
        "grasp_depth": NONNEGATIVE,
        "progress": ListOf(
            Number(minimum=0.0, maximum=1.0), min_items=2, what="fractions of the path"
        ),  # fmt: skip
        "turn": ListOf(POINT, min_items=2, what="rotation vectors [x, y, z] (rad)"),
        "rgba": Vector(4, "r, g, b, a", Number(minimum=0.0, maximum=1.0)),
    },
    required=("torus_radius", "tube_radius"),
)


@dataclass(frozen=True, eq=False)
class CarrySpec:
    """A torus carried in the jaws and the wrist's turns along the path (task frame)."""

    torus_radius: float
    """The radius of the tube's centre line, m."""
    tube_radius: float
    """The tube's radius, m."""
    grasp_depth: float = 0.006
    """The gripped tube's centre from the tip point along the jaws, m."""
    progress: tuple[float, ...] = (0.0, 1.0)
    """Knots of progress along the path (fractions of its length), increasing, from 0 to 1."""
    turn: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))
    """(k, 3) the tool's turn from its start orientation at each knot: rotation vectors
    (axis · angle) in the task's frame, rad."""
    rgba: tuple[float, float, float, float] = (0.95, 0.55, 0.15, 1.0)

    def __post_init__(self) -> None:
        turn = np.array(self.turn, dtype=float)
        knots = tuple(float(s) for s in self.progress)
        if turn.shape != (len(knots), 3) or not np.all(np.isfinite(turn)):
            raise TaskError(f"carry: turn must be one rotation vector [x, y, z] per progress "
                            f"knot ({len(knots)}), got shape {turn.shape}")  # fmt: skip
        if (
            knots[0] != 0.0
            or knots[-1] != 1.0
            or any(b <= a for a, b in zip(knots, knots[1:], strict=False))
        ):
            raise TaskError(f"carry: progress must increase from 0 to 1, got {list(knots)}")
        if not (self.torus_radius > self.tube_radius > 0.0 and self.grasp_depth >= 0.0):
            raise TaskError("carry: needs torus_radius > tube_radius > 0 and grasp_depth >= 0")
        turn.setflags(write=False)
        object.__setattr__(self, "turn", turn)
        object.__setattr__(self, "progress", knots)
        object.__setattr__(self, "rgba", tuple(float(c) for c in self.rgba))

    def turn_at(self, s) -> np.ndarray:
        """The turn (3,) at progress ``s`` (a fraction, clipped to [0, 1]): linear between
        the knots, rotation vector in the task's frame, rad."""
        x = float(np.clip(s, 0.0, 1.0))
        return np.array([np.interp(x, self.progress, self.turn[:, i]) for i in range(3)])

    def R_turn(self, s) -> np.ndarray:  # noqa: N802 (a rotation matrix)
        """(3, 3) the rotation of :meth:`turn_at` (task frame)."""
        return rotation_from_vector(self.turn_at(s))

    def draw(self, wrist, site, prefix: str) -> None:
        """The torus on the ``wrist`` body (an ``MjsBody``) at the tip ``site`` (an
        ``MjsSite`` of that body), visual only."""
        from davinci_sim.tasks.exercise_parts import VisualBody  # (it imports the path kind)

        R = np.empty(9)
        mujoco.mju_quat2Mat(R, np.asarray(site.quat, dtype=float))
        R = R.reshape(3, 3)
        centre = (
            np.asarray(site.pos, dtype=float) + (self.grasp_depth + self.torus_radius) * R[:, 2]
        )
        torus = VisualBody(wrist, "carried", prefix)
        torus.ring("carried_torus", centre, R[:, 1], self.torus_radius, self.tube_radius,
                   self.rgba, segments=20)  # fmt: skip

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CarrySpec:
        kw = dict(data)
        if "progress" in kw:
            kw["progress"] = tuple(kw["progress"])
        if "rgba" in kw:
            kw["rgba"] = tuple(kw["rgba"])
        try:
            return cls(**kw)
        except TypeError as e:
            raise TaskError(f"carry: {e}") from e

    def to_dict(self) -> dict[str, Any]:
        return {
            "torus_radius": self.torus_radius,
            "tube_radius": self.tube_radius,
            "grasp_depth": self.grasp_depth,
            "progress": list(self.progress),
            "turn": self.turn.tolist(),
            "rgba": list(self.rgba),
        }
