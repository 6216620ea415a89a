"""Viscous guidance plus a sigmoid elastic pull, their sum capped: the fixture of Rota's
dVRK-console training study (training.md §4), kind ``viscous_elastic``.

Rota's MSc thesis (Politecnico di Milano 2022/23) guided trainees at a real dVRK surgeon
console with the sum of two forces on the tool tip, capped and then scaled by the day's
assistance factor (facts from its scene and scripts, repository
``alberto-rota/Enhanched-Haptic-Training-for-Robotic-Assisted-Surgery``:
``TrajectoryGuidanceVF.cs``, ``SumForces.cs``, ``Global.cs``, ``WrenchPublisher.cs``):

* the **viscous** term is Enayati et al.'s law, the one the seed prints (equations (3)-(7)
  of :mod:`davinci_sim.haptics.viscous`), with no cap of its own (``G_max`` = ∞);
* the **elastic** term pulls towards the path with a magnitude that rises as a logistic
  function of the distance d: ``K_e · σ(d) · φ̂``, ``σ(d) = 1 / (1 + exp(−(s / 0.2) ·
  (d − d_threshold − d_half)))``, where the slope s is raised to at least ``1 / d_half``
  (their script enforces that floor). With their values (K_e = 0.8 N, d_threshold = d_half
  = 2 mm, s = 500 /m) σ is 4.5e-5 on the path, 0.5 at 4 mm, 0.993 at 6 mm: a static tool
  off the path feels up to 0.8 N, unlike the viscous law alone;
* the **sum** is capped at ``max_force`` (3 N) in magnitude, then multiplied by
  ``assistance`` (their assisted group's 1.0, 0.75, 0.5, 0.25 over the training days).

Their closest point is the nearest of the trajectory's 2,600 vertices (44 µm apart); here it
is the nearest point of the polyline, which differs from it by at most half that spacing.

Frames: velocity, deviation and force share one frame (the path's or the camera's; the law
commutes with rotations); m, m/s, N.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics.path_query import closest_point
from davinci_sim.haptics.viscous import unit_rows, viscous_guidance_terms

#: The logistic's scale of their ``DistMapAttraction``: exp(−slope / 0.2 · (d − ...)).
SLOPE_DIVISOR = 0.2
_EPS = 1e-12


def elastic_share(distance, *, threshold: float, half: float, slope: float) -> np.ndarray:
    """σ(d) of the elastic term, in (0, 1): the logistic of ``distance`` (m), 0.5 at
    ``threshold + half`` (m), steepness ``max(slope, 1 / half) / 0.2`` per metre."""
    if not (threshold >= 0 and half > 0 and slope >= 0):
        raise ValueError(
            f"threshold and slope must be >= 0 and half > 0, got {threshold!r}, {half!r}, {slope!r}"
        )
    steep = max(float(slope), 1.0 / half) / SLOPE_DIVISOR
    d = np.asarray(distance, dtype=float)
    # (the logistic written with exp of a non-positive argument: no overflow far away)
    z = -steep * (d - threshold - half)
    e = np.exp(-np.abs(z))
    return np.where(z <= 0, 1.0 / (1.0 + e), e / (1.0 + e))


def viscous_elastic_guidance(
    velocity,
    deviation,
    *,
    B: float,
    elastic_gain: float,
    threshold: float,
    half: float,
    slope: float,
    max_force: float,
    assistance=1.0,
) -> np.ndarray:
    """The guidance force (..., 3), N (see the module docstring).

    Args:
        velocity: tool tip velocity, (..., 3), m/s.
        deviation: φ, from the tool tip to the closest point of the path, (..., 3), m.
        B: viscous gain, N·s/m (≥ 0).
        elastic_gain: K_e, N (≥ 0): the elastic pull far from the path.
        threshold, half: the logistic's 0.5 point is at ``threshold + half``, m.
        slope: the logistic's slope parameter, 1/m (raised to at least ``1 / half``).
        max_force: cap of the sum's magnitude, N (> 0).
        assistance: factor applied after the cap, in [0, 1], scalar or broadcastable to the
            batch shape (one per trial).
    """
    if not (elastic_gain >= 0 and max_force > 0):
        raise ValueError(f"elastic_gain must be >= 0 and max_force > 0, got "
                         f"{elastic_gain!r}, {max_force!r}")  # fmt: skip
    a = np.asarray(assistance, dtype=float)
    if np.any(~((a >= 0) & (a <= 1))):
        raise ValueError(f"assistance must be in [0, 1], got {assistance!r}")
    phi = np.asarray(deviation, dtype=float)
    viscous = viscous_guidance_terms(velocity, phi, B=B, G_max=math.inf).force
    phi_hat, dist = unit_rows(phi)
    share = elastic_share(dist, threshold=threshold, half=half, slope=slope)
    total = viscous + (elastic_gain * share)[..., None] * phi_hat
    norm = np.linalg.norm(total, axis=-1)
    scale = np.where(norm > max_force, max_force / np.maximum(norm, _EPS), 1.0)
    return total * (scale * a)[..., None]


@dataclass(frozen=True, eq=False)
class ViscousElasticGuidance:
    """The ``viscous_elastic`` fixture along ``path``: ``force(p, v)`` in the path's frame."""

    path: Polyline
    B: float
    """Viscous gain, N·s/m."""
    elastic_gain: float
    """K_e, N."""
    threshold: float
    """m."""
    half: float
    """m."""
    slope: float
    """1/m."""
    max_force: float = 3.0
    """Cap of the sum, N."""
    assistance: float = 1.0
    """Factor after the cap, in [0, 1]."""

    def __post_init__(self) -> None:
        for name in ("B", "elastic_gain", "threshold", "half", "slope", "max_force",
                     "assistance"):  # fmt: skip
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise ValueError(
                    f"ViscousElasticGuidance.{name} must be a finite number >= 0, got {value!r}"
                )
        if self.half <= 0 or self.max_force <= 0 or self.assistance > 1:
            raise ValueError("ViscousElasticGuidance: half and max_force must be > 0, "
                             "assistance in [0, 1]")  # fmt: skip

    def force(self, position, velocity) -> np.ndarray:
        deviation = closest_point(self.path, position).deviation
        return viscous_elastic_guidance(
            velocity, deviation, B=self.B, elastic_gain=self.elastic_gain,
            threshold=self.threshold, half=self.half, slope=self.slope,
            max_force=self.max_force, assistance=self.assistance,
        )  # fmt: skip


def describe_viscous_elastic(p) -> str:
    """The law in one line (the study's report and rows)."""
    return (
        f"viscous + elastic guidance: B={p.get('B'):g} N·s/m, elastic {p.get('elastic_gain'):g} N "
        f"(logistic at {1e3 * (p.get('threshold') + p.get('half')):g} mm), sum capped at "
        f"{p.get('max_force'):g} N, x{p.get('assistance', 1.0):g}"
    )
