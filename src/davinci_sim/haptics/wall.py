"""Forbidden-region virtual fixtures: a stiff, damped wall at a boundary surface.

A forbidden region is described by its penetration depth g(p) (m, > 0 inside the region,
≤ 0 outside) and the unit normal n(p) that points out of it. Inside, the wall pushes back:

    F = max(0, k·g − c·ramp(g)·(v·n))·n,   ramp(g) = min(1, g/damping_depth),

stiffness k (N/m), damping c (N·s/m) on the normal velocity (v·n < 0 when going deeper), the
``max(0, ·)`` so that the wall never pulls the tool in when it leaves (a unilateral
constraint), and at most ``max_force``. The damping grows over the first ``damping_depth``
of penetration instead of switching on at the surface, so that the force is continuous
across the boundary (a damper that starts at full strength gives a jump of c·|v·n| on
contact; the ramp is the linear-in-depth damping of the Hunt & Crossley (1975) contact
model, saturated).

Surfaces: :class:`PlaneWall` (a half-space) and :class:`SphereWall` (inside of a sphere,
e.g. an organ to avoid, or outside of it, a region to stay in). All positions, velocities
and forces in one frame, m, m/s, N; vectorised over ``(..., 3)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

_EPS = 1e-12


def wall_force(
    penetration,
    normal,
    velocity,
    *,
    stiffness,
    damping=0.0,
    damping_depth: float = 0.001,
    max_force=np.inf,
) -> np.ndarray:
    """Force (..., 3), N, of a wall with the given penetration (...) and unit normal
    (..., 3) out of the forbidden region (see the module docstring)."""
    g = np.asarray(penetration, dtype=float)
    n = np.asarray(normal, dtype=float)
    v = np.asarray(velocity, dtype=float)
    if n.shape[-1:] != (3,) or v.shape[-1:] != (3,):
        raise ValueError(f"normal and velocity must be (..., 3), got {n.shape}, {v.shape}")
    if not damping_depth > 0:
        raise ValueError(f"damping_depth must be > 0, got {damping_depth!r}")
    depth = np.maximum(g, 0.0)
    ramp = np.minimum(1.0, depth / damping_depth)
    v_n = np.einsum("...j,...j->...", v, n)
    push = np.maximum(0.0, stiffness * depth - damping * ramp * v_n)
    push = np.minimum(push, max_force)
    return push[..., None] * n


def _check(owner: str, **values) -> None:
    for name, value in values.items():
        if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
            raise ValueError(f"{owner}.{name} must be a finite number >= 0, got {value!r}")


class _Wall:
    """The force of a wall from its ``penetration`` (depth, outward normal) and its gains."""

    stiffness: float
    damping: float
    damping_depth: float
    max_force: float

    def penetration(self, position) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def force(self, position, velocity) -> np.ndarray:
        g, n = self.penetration(position)
        return wall_force(
            g,
            n,
            velocity,
            stiffness=self.stiffness,
            damping=self.damping,
            damping_depth=self.damping_depth,
            max_force=self.max_force,
        )


@dataclass(frozen=True, eq=False)
class PlaneWall(_Wall):
    """The half-space behind a plane: forbidden where ``(p − point)·normal < 0``.

    ``normal`` points to the allowed side (it is normalised).
    """

    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    stiffness: float = 500.0
    """N/m (our default, as every default of this module)."""
    damping: float = 5.0
    """N·s/m."""
    damping_depth: float = 0.001
    """m."""
    max_force: float = 5.0
    """N."""

    def __post_init__(self) -> None:
        n = np.asarray(self.normal, dtype=float)
        if n.shape != (3,) or np.linalg.norm(n) < 1e-9 or np.asarray(self.point).shape != (3,):
            raise ValueError(f"PlaneWall needs a 3-D point and a non-zero normal, got {self!r}")
        _check(
            "PlaneWall",
            stiffness=self.stiffness,
            damping=self.damping,
            damping_depth=self.damping_depth,
            max_force=self.max_force,
        )
        object.__setattr__(self, "normal", tuple((n / np.linalg.norm(n)).tolist()))

    def penetration(self, position) -> tuple[np.ndarray, np.ndarray]:
        """``(g, n)``: depth behind the plane (..., m) and the outward normal (..., 3)."""
        p = np.asarray(position, dtype=float)
        n = np.asarray(self.normal)
        g = -np.einsum("...j,j->...", p - np.asarray(self.point, dtype=float), n)
        return g, np.broadcast_to(n, p.shape)


@dataclass(frozen=True, eq=False)
class SphereWall(_Wall):
    """A sphere; ``keep_out`` (default) forbids its inside, else its outside.

    At the exact centre of a keep-out sphere the push direction is undefined; it is then
    ``fallback_normal``.
    """

    center: tuple[float, float, float]
    radius: float
    keep_out: bool = True
    stiffness: float = 500.0
    """N/m."""
    damping: float = 5.0
    """N·s/m."""
    damping_depth: float = 0.001
    """m."""
    max_force: float = 5.0
    """N."""
    fallback_normal: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        if np.asarray(self.center).shape != (3,):
            raise ValueError(f"SphereWall.center must be 3 numbers, got {self.center!r}")
        _check(
            "SphereWall",
            radius=self.radius,
            stiffness=self.stiffness,
            damping=self.damping,
            damping_depth=self.damping_depth,
            max_force=self.max_force,
        )

    def penetration(self, position) -> tuple[np.ndarray, np.ndarray]:
        p = np.asarray(position, dtype=float)
        r = p - np.asarray(self.center, dtype=float)
        d = np.linalg.norm(r, axis=-1)
        radial = np.where(
            (d > _EPS)[..., None], r / np.maximum(d, _EPS)[..., None], self.fallback_normal
        )
        if self.keep_out:
            return self.radius - d, radial
        return d - self.radius, -radial
