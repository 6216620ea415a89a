"""Attractive spring guidance towards a reference path (beyond the seed).

A classic guidance virtual fixture: a spring of stiffness k pulls the tool tip towards the
closest point of the path and a damper resists only the motion *towards or away from* the
path, so progress along the path is free:

    F = k·φ − c·ramp·(v·φ̂)·φ̂,   then scaled down to at most F_max,

with φ the deviation (tool tip → closest path point, m), v the tool tip velocity (m/s),
ramp = min(1, ‖φ‖/transition). Unlike the seed's viscous fixture
(:mod:`davinci_sim.haptics.viscous`), a static tool off the path does feel a force.

The ramp keeps the damping continuous where φ̂ is undefined (on the path, φ̂ can point any
way across it); the spring term k·φ is continuous by itself. Away from the path's medial
axis the force is continuous in position and velocity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics.path_query import closest_point

_EPS = 1e-12


def spring_guidance(
    velocity,
    deviation,
    *,
    stiffness,
    damping=0.0,
    max_force=np.inf,
    transition: float = 0.0005,
) -> np.ndarray:
    """Spring-damper force towards the path, (..., 3), N (see the module docstring).

    Args:
        velocity: tool tip velocity, (..., 3), m/s.
        deviation: φ, tool tip → closest path point, (..., 3), m.
        stiffness: k, N/m (≥ 0), scalar or broadcastable to the batch shape.
        damping: c, N·s/m (≥ 0), on the velocity component along φ̂.
        max_force: magnitude cap, N (> 0).
        transition: width of the ramp of the damping near the path, m (> 0).
    """
    v = np.asarray(velocity, dtype=float)
    phi = np.asarray(deviation, dtype=float)
    if v.shape[-1:] != (3,) or phi.shape[-1:] != (3,):
        raise ValueError(
            f"velocity and deviation must have shape (..., 3), got {v.shape} and {phi.shape}"
        )
    k = np.asarray(stiffness, dtype=float)
    c = np.asarray(damping, dtype=float)
    cap = np.asarray(max_force, dtype=float)
    if np.any(k < 0) or np.any(c < 0) or np.any(cap <= 0) or not transition > 0:
        raise ValueError("stiffness and damping must be >= 0, max_force and transition > 0")
    dist = np.linalg.norm(phi, axis=-1)
    phi_hat = np.where((dist > _EPS)[..., None], phi / np.maximum(dist, _EPS)[..., None], 0.0)
    ramp = np.minimum(1.0, dist / transition)
    v_normal = np.einsum("...j,...j->...", v, phi_hat)
    f = k[..., None] * phi - (c * ramp * v_normal)[..., None] * phi_hat
    norm = np.linalg.norm(f, axis=-1)
    scale = np.where(norm > cap, cap / np.maximum(norm, _EPS), 1.0)
    return f * scale[..., None]


@dataclass(frozen=True, eq=False)
class SpringGuidance:
    """Spring guidance towards ``path``: ``force(p, v)`` in the path's frame."""

    path: Polyline
    stiffness: float
    """N/m."""
    damping: float = 0.0
    """N·s/m, on the velocity component towards/away from the path."""
    max_force: float = 5.0
    """N."""
    transition: float = 0.0005
    """m."""

    def __post_init__(self) -> None:
        for name in ("stiffness", "damping", "max_force", "transition"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise ValueError(
                    f"SpringGuidance.{name} must be a finite number >= 0, got {value!r}"
                )
        if self.max_force <= 0 or self.transition <= 0:
            raise ValueError("SpringGuidance.max_force and transition must be > 0")

    def force(self, position, velocity) -> np.ndarray:
        deviation = closest_point(self.path, position).deviation  # (one tip: compiled)
        return spring_guidance(
            velocity,
            deviation,
            stiffness=self.stiffness,
            damping=self.damping,
            max_force=self.max_force,
            transition=self.transition,
        )
