"""Primitive geoms placed in a convenient design frame of a body, and explicit inertials.

The arm modules describe their shapes in frames that make the geometry easy to read (e.g.
the PSM pitch plane); :class:`Painter` converts to the body frame. Only MuJoCo primitives
are used (no meshes).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from davinci_sim.geometry.se3 import segment_rotation
from davinci_sim.model import contact
from davinci_sim.model.frames import mat_to_quat

_G = mujoco.mjtGeom


@dataclass
class Painter:
    """Adds geoms to ``body``; coordinates are in the frame ``T_body_design``."""

    body: object
    T_body_design: np.ndarray = field(default_factory=lambda: np.eye(4))
    prefix: str = ""

    def _point(self, p) -> np.ndarray:
        return self.T_body_design[:3, :3] @ np.asarray(p, dtype=float) + self.T_body_design[:3, 3]

    def add(self, kind, material, name, **kw):
        """Add a geom of any type (``kw``: MjSpec geom attributes in body coordinates)."""
        geom = self.body.add_geom(**kw)
        if name:
            geom.name = f"{self.prefix}{name}"
        geom.material = material
        # (a tool geom's collision bits are its arm's: the prefix "PSM1/" names it)
        arm = self.prefix.rstrip("/") if kind == "tool" else None
        contact.apply(geom, kind, arm)
        return geom

    def capsule(self, p0, p1, radius, material, *, kind="visual", name=""):
        """Capsule between two points."""
        return self.add(
            kind,
            material,
            name,
            type=_G.mjGEOM_CAPSULE,
            fromto=np.concatenate([self._point(p0), self._point(p1)]),
            size=[radius, 0, 0],
        )

    def cylinder(self, p0, p1, radius, material, *, kind="visual", name=""):
        """Cylinder between two points."""
        return self.add(
            kind,
            material,
            name,
            type=_G.mjGEOM_CYLINDER,
            fromto=np.concatenate([self._point(p0), self._point(p1)]),
            size=[radius, 0, 0],
        )

    def bar(self, p0, p1, half_width, half_height, material, *, kind="visual", name="", up=None):
        """Box between two points; ``up`` (design frame) orients the ``half_height`` side."""
        a, b = self._point(p0), self._point(p1)
        axis = b - a
        length = np.linalg.norm(axis)
        if up is None:
            R = segment_rotation(axis)
        else:
            z = axis / length
            y = self.T_body_design[:3, :3] @ np.asarray(up, dtype=float)
            y = y - np.dot(y, z) * z
            y /= np.linalg.norm(y)
            R = np.column_stack([np.cross(y, z), y, z])
        return self.add(
            kind,
            material,
            name,
            type=_G.mjGEOM_BOX,
            pos=(a + b) / 2,
            quat=mat_to_quat(R),
            size=[half_width, half_height, length / 2],
        )

    def box(self, center, half_sizes, material, *, R=None, kind="visual", name=""):
        """Box at ``center`` with ``half_sizes``; ``R`` rotates it in the design frame."""
        R_body = self.T_body_design[:3, :3] @ (np.eye(3) if R is None else np.asarray(R))
        return self.add(
            kind,
            material,
            name,
            type=_G.mjGEOM_BOX,
            pos=self._point(center),
            quat=mat_to_quat(R_body),
            size=np.asarray(half_sizes, dtype=float),
        )

    def sphere(self, center, radius, material, *, kind="visual", name=""):
        """Sphere at ``center``."""
        return self.add(
            kind,
            material,
            name,
            type=_G.mjGEOM_SPHERE,
            pos=self._point(center),
            size=[radius, 0, 0],
        )

    def ellipsoid(self, center, radii, material, *, R=None, kind="visual", name=""):
        """Ellipsoid at ``center`` with semi-axes ``radii``."""
        R_body = self.T_body_design[:3, :3] @ (np.eye(3) if R is None else np.asarray(R))
        return self.add(
            kind,
            material,
            name,
            type=_G.mjGEOM_ELLIPSOID,
            pos=self._point(center),
            quat=mat_to_quat(R_body),
            size=np.asarray(radii, dtype=float),
        )


def set_inertial(body, mass: float, com, inertia, *, T_body_design=None) -> None:
    """Explicit mass (kg), centre of mass and diagonal inertia (kg·m²) of ``body``.

    ``com`` is in the design frame ``T_body_design`` (default: the body frame); the inertia
    diagonal is about the body axes. Inertias are set explicitly rather than from the visual
    geoms, whose volume has little to do with the real parts' mass distribution.
    """
    T = np.eye(4) if T_body_design is None else T_body_design
    body.explicitinertial = True
    body.mass = float(mass)
    body.ipos = T[:3, :3] @ np.asarray(com, dtype=float) + T[:3, 3]
    body.iquat = [1.0, 0.0, 0.0, 0.0]
    body.inertia = np.broadcast_to(np.asarray(inertia, dtype=float), (3,)).copy()
