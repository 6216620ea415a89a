"""The viscous guidance virtual fixture of the seed paper (§II-C, equations (1)-(7)).

The force pulls the tool tip back towards a reference path, with a magnitude that grows with
the tool's speed (hence "viscous"): a static tool feels nothing. With v the tool tip velocity
(m/s), φ the deviation (the vector from the tool tip to the closest point of the path, m),
v̂ = v/‖v‖ and φ̂ = φ/‖φ‖ their unit vectors (the seed prints (3)-(6) with v and φ; as the
text and Fig. 3 make clear they are directions, and only unit vectors keep b in [0, B] and
θ in [0, π]):

* (3) anisotropic coefficient ``b = B·sqrt((1 − v̂·φ̂)/2)``, in [0, B]: B when moving straight
  away from the path, 0 when moving straight towards it. With α the angle between v̂ and φ̂,
  b = B·sin(α/2).
* (1)-(2) magnitude ``G = min(G_max, ‖b·v‖)``. **Erratum**: as printed, (1)-(2) select the
  *larger* of G_max and ‖b·v‖, which would make every force at least G_max, even for a
  static tool; the text says the maximum force is constrained "to prevent the assistance
  force from being too aggressive" and the authors' prototype computes ``min(b·|v|, F)``,
  so G_max is a cap (the seed README).
* (4) direction ``φ̂`` when moving away from the path (v̂·φ̂ < 0), else
  ``rotate(v̂, θ, n)``, with (5) ``θ = (1 + v̂·φ̂)·π/2`` and (6) ``n = v̂ × φ̂``: the velocity
  direction turned towards φ̂ by θ. Sideways motion (v̂·φ̂ = 0, θ = π/2) gives φ̂, so the two
  cases of (4) meet continuously; motion straight at the path (θ → π) gives −v̂, a brake.
* (7) ``G = G·direction``.

Degenerate cases, all continuous and finite:

* v = 0: G = 0 (the seed relies on this: "the user will not be affected by force when
  staying static").
* v̂ ∥ φ̂, where n = 0 and the rotation axis is undefined: moving straight away is the
  first case of (4) (direction φ̂, no rotation needed); moving straight at the path has
  b = 0, so G = 0. The rotation is computed in closed form in the plane of v̂ and φ̂,
  ``cos θ·v̂ + sin θ·(φ̂ − (v̂·φ̂)v̂)/sin α``, where ``sin θ/sin α → 0`` as α → 0: no division
  by zero, no jump.
* φ = 0 (tool on the path): φ̂ is undefined and, as printed, the seed's force does not
  vanish there (sideways motion on the path gives b·‖v‖ = B‖v‖/√2): it flips direction as
  the tool crosses the path, a discontinuity of up to 2·min(G_max, B‖v‖/√2). The default
  is the law as printed (``transition = 0``; G = 0 only exactly on the path), as the seed's
  prototype ran it on a real console. An option scales G by ``min(1, ‖φ‖/transition)``:
  zero on the path, growing linearly over the first ``transition`` metres, exactly the
  seed's law beyond. Measured with the study's (calibrated) trainees on ``seed_path``
  (B = 40, G_max = 5, ``benchmarks/bench_ramp.py``): as printed, the force on the hand turns
  by more than 90° from one tick to the next 0.12 times per second (one flip every ~8 s);
  a 0.05 mm ramp (below the hand's tremor) removes them for 2 % less mean force; the 0.5 mm
  ramp used before removed 29 % of the mean force and the deviation grew by 22 %. The
  live console keeps the law as printed too (one law for the console and the study); a
  user who feels the flips on a real MTM can set ``transition: 0.00005``.

The remaining discontinuity is the path's, not the law's: on the medial axis of the path
(points equidistant from two parts of it, see :mod:`davinci_sim.geometry.path`) φ itself
jumps, and so does the force.

Frames: v, φ and the force share one frame (the path's, or the camera's: the law commutes
with rotations); forces in N.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics.path_query import closest_point
from davinci_sim.kinematics.jit import ENABLED as _COMPILED
from davinci_sim.kinematics.jit import helper, jit, warm

#: Default width of the ramp that makes the force vanish on the path, m: 0, the seed's law
#: as printed, in the study and on the live console alike (a ramp is an explicit option:
#: ``transition`` of a task file's viscous entry, ``study --transition``; see the module
#: docstring for what it changes).
DEFAULT_TRANSITION = 0.0

_EPS = 1e-12


class ViscousTerms(NamedTuple):
    """The intermediate quantities of (1)-(7), each over the batch shape."""

    force: np.ndarray
    """Guidance force G, (..., 3), N."""
    magnitude: np.ndarray
    """‖G‖ = G of (1) after the cap and the on-path ramp, (...), N."""
    b: np.ndarray
    """Anisotropic coefficient of (3), (...), N·s/m."""
    direction: np.ndarray
    """Unit force direction of (4), (..., 3) (φ̂ when v = 0; 0 when φ = 0)."""
    cos_angle: np.ndarray
    """v̂·φ̂ (0 when v or φ is zero)."""


def unit_rows(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The unit vectors of the rows of ``x`` (..., 3) (0 for a row of norm <= 1e-12) and the
    rows' norms (...)."""
    n = np.linalg.norm(x, axis=-1)
    safe = np.where(n > _EPS, n, 1.0)
    return np.where((n > _EPS)[..., None], x / safe[..., None], 0.0), n


def viscous_guidance_terms(
    velocity, deviation, *, B, G_max, transition: float = DEFAULT_TRANSITION
) -> ViscousTerms:
    """Equations (1)-(7) with their intermediate terms; see the module docstring.

    Args:
        velocity: tool tip velocity v, (..., 3), m/s.
        deviation: φ, from the tool tip to the closest point of the path, (..., 3), m.
        B: viscosity coefficient, N·s/m (≥ 0), scalar or broadcastable to the batch shape
            (e.g. one condition per trial).
        G_max: force cap, N (≥ 0), scalar or broadcastable to the batch shape.
        transition: width of the on-path ramp, m (0: the law as printed).
    """
    v = np.asarray(velocity, dtype=float)
    phi = np.asarray(deviation, dtype=float)
    if v.shape[-1:] != (3,) or phi.shape[-1:] != (3,):
        raise ValueError(
            f"velocity and deviation must have shape (..., 3), got {v.shape} and {phi.shape}"
        )
    B = np.asarray(B, dtype=float)
    G_max = np.asarray(G_max, dtype=float)
    if (B < 0).any() or (G_max < 0).any() or not (transition >= 0):
        raise ValueError(
            f"B, G_max and transition must be >= 0, got {B!r}, {G_max!r}, {transition!r}"
        )
    v_hat, speed = unit_rows(v)
    phi_hat, dist = unit_rows(phi)
    c = np.clip(np.einsum("...j,...j->...", v_hat, phi_hat), -1.0, 1.0)
    b = B * np.sqrt((1.0 - c) / 2.0)  # (3)
    G = np.minimum(G_max, b * speed)  # (1)-(2), with G_max as the cap (erratum)
    if transition > 0:
        G = G * np.minimum(1.0, dist / transition)
    else:
        G = np.where(dist > _EPS, G, 0.0)
    # (4)-(6): rotate v̂ by θ = (1 + c)π/2 about n = v̂ × φ̂, written in the (v̂, ŵ) plane with
    # ŵ = (φ̂ − c v̂)/sin α. cos θ = −sin(cπ/2), sin θ = cos(cπ/2) = sin((1 − c)π/2).
    sin_alpha = np.sqrt(np.clip((1.0 - c) * (1.0 + c), 0.0, None))
    safe_sin = np.where(sin_alpha > 1e-9, sin_alpha, 1.0)
    ratio = np.where(sin_alpha > 1e-9, np.sin((1.0 - c) * math.pi / 2) / safe_sin, 0.0)
    rotated = -np.sin(c * math.pi / 2)[..., None] * v_hat + ratio[..., None] * (
        phi_hat - c[..., None] * v_hat
    )
    direction = np.where((c < 0.0)[..., None] | (speed <= _EPS)[..., None], phi_hat, rotated)
    return ViscousTerms(G[..., None] * direction, G, b, direction, c)  # (7)


@helper
def _minimum(a: float, b: float) -> float:
    """``np.minimum`` of two floats: NaN if either is, else the smaller (``a`` on a tie)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a <= b else b


@helper
def _clip(x: float, lo: float, hi: float) -> float:
    """``np.clip`` of a float: NaN stays NaN, -0.0 stays -0.0 against a bound of 0.0."""
    if x < lo:
        x = lo
    if x > hi:
        x = hi
    return x


@helper
def _viscous_into(v, phi, B, G_max, transition, out):
    """:func:`viscous_force_row`'s body, callable from other kernels (see it)."""
    speed = math.sqrt((v[0] * v[0] + v[1] * v[1]) + v[2] * v[2])
    dist = math.sqrt((phi[0] * phi[0] + phi[1] * phi[1]) + phi[2] * phi[2])
    s_v = speed if speed > _EPS else 1.0
    s_p = dist if dist > _EPS else 1.0
    vx, vy, vz = v[0] / s_v, v[1] / s_v, v[2] / s_v
    if not speed > _EPS:
        vx, vy, vz = 0.0, 0.0, 0.0
    px, py, pz = phi[0] / s_p, phi[1] / s_p, phi[2] / s_p
    if not dist > _EPS:
        px, py, pz = 0.0, 0.0, 0.0
    c = _clip((vx * px + vz * pz) + vy * py, -1.0, 1.0)
    b = B * math.sqrt((1.0 - c) / 2.0)
    G = _minimum(G_max, b * speed)
    if transition > 0:
        G = G * _minimum(1.0, dist / transition)
    elif not dist > _EPS:
        G = 0.0
    sin_alpha = math.sqrt(_clip((1.0 - c) * (1.0 + c), 0.0, math.inf))
    ratio = 0.0
    if sin_alpha > 1e-9:
        ratio = math.sin((1.0 - c) * math.pi / 2) / sin_alpha
    if c < 0.0 or speed <= _EPS:
        out[0], out[1], out[2] = G * px, G * py, G * pz
    else:
        k = -math.sin(c * math.pi / 2)
        out[0] = G * (k * vx + ratio * (px - c * vx))
        out[1] = G * (k * vy + ratio * (py - c * vy))
        out[2] = G * (k * vz + ratio * (pz - c * vz))


def viscous_guidance(
    velocity, deviation, *, B, G_max, transition: float = DEFAULT_TRANSITION
) -> np.ndarray:
    """Guidance force (..., 3), N, of equations (1)-(7) (see :func:`viscous_guidance_terms`)."""
    return viscous_guidance_terms(
        velocity, deviation, B=B, G_max=G_max, transition=transition
    ).force


@dataclass(frozen=True, eq=False)
class ViscousGuidance:
    """The seed's viscous fixture along ``path``: ``force(p, v)`` in the path's frame.

    Table I of the seed: (B, G_max) = (0, 0), (20, 2), (40, 5), (60, 8) N·s/m and N. ``B``
    and ``G_max`` are numbers, or arrays of one value per trial (n,) for a batch of trials
    in different conditions (positions and velocities then (n, 3)).
    """

    path: Polyline
    B: float | np.ndarray
    """Viscosity coefficient, N·s/m."""
    G_max: float | np.ndarray
    """Force cap, N."""
    transition: float = DEFAULT_TRANSITION
    """Width of the on-path ramp, m."""

    def __post_init__(self) -> None:
        for name in ("B", "G_max", "transition"):
            value = getattr(self, name)
            a = np.asarray(value, dtype=float)
            if a.ndim > 1 or not np.all(np.isfinite(a)) or np.any(a < 0):
                raise ValueError(
                    f"ViscousGuidance.{name} must be finite and >= 0 (a number or one per "
                    f"trial), got {value!r}"
                )
        if np.ndim(self.transition) != 0:
            raise ValueError(
                f"ViscousGuidance.transition must be a number, got {self.transition!r}"
            )
        object.__setattr__(self, "transition", float(self.transition))
        for name in ("B", "G_max"):
            value = getattr(self, name)
            if np.ndim(value) == 0:
                object.__setattr__(self, name, float(value))
            else:
                a = np.array(value, dtype=float)
                a.setflags(write=False)
                object.__setattr__(self, name, a)

    def terms(self, position, velocity) -> ViscousTerms:
        """(1)-(7) for tool tips at ``position`` (..., 3) moving at ``velocity`` (..., 3)."""
        deviation = closest_point(self.path, position).deviation  # (one tip: compiled)
        return viscous_guidance_terms(
            velocity, deviation, B=self.B, G_max=self.G_max, transition=self.transition
        )

    def force(self, position, velocity) -> np.ndarray:
        """Force on the hand (..., 3), N, in the path's frame."""
        p, v = np.asarray(position, dtype=float), np.asarray(velocity, dtype=float)
        if (
            _COMPILED
            and p.shape in ((3,), (1, 3))
            and v.shape == p.shape
            and isinstance(self.B, float)
            and isinstance(self.G_max, float)
        ):  # one tool tip (the live haptic tick): the compiled row, the same bits
            out = np.empty(p.shape)
            phi = closest_point(self.path, p).deviation.reshape(3)
            viscous_force_row(
                np.array(v.reshape(3), dtype=float, order="C"),  # (the warm-up signature)
                np.array(phi, dtype=float, order="C"),
                self.B,
                self.G_max,
                self.transition,
                out.reshape(3),
            )
            return out
        if (
            _COMPILED
            and p.ndim == 2
            and p.shape[1] == 3
            and v.shape == p.shape
            and isinstance(self.B, float)
            and isinstance(self.G_max, float)
        ):  # a batch of tips under one condition (the study's trials): compiled rows
            out = np.empty(p.shape)
            phi = closest_point(self.path, p).deviation
            viscous_force_rows(np.ascontiguousarray(v), np.ascontiguousarray(phi), self.B,
                               self.G_max, self.transition, out)  # fmt: skip
            return out
        return self.terms(position, velocity).force


@jit
def viscous_force_row(v, phi, B, G_max, transition, out):
    """:func:`viscous_guidance_terms`'s force for one tool tip, into ``out`` (3,): velocity
    ``v`` (3,), m/s, deviation ``phi`` (3,), m, ``B``, ``G_max``, ``transition`` floats.
    The same operations in the same order as the batch law (norms summed left to right, the
    dot product as numpy's ``einsum`` sums three terms, ``(x + z) + y``), so the same bits
    (``tests/haptics/test_viscous.py``): the live haptic tick's one row, compiled."""
    _viscous_into(v, phi, B, G_max, transition, out)


@jit
def viscous_force_rows(V, PHI, B, G_max, transition, out):
    """:func:`viscous_force_row` of every row of ``V`` and ``PHI`` (n, 3), into ``out``
    (n, 3), with one ``B``, ``G_max`` and ``transition``: a batch of trials under one
    condition (the study's), each row the bits of one tip."""
    for r in range(V.shape[0]):
        _viscous_into(V[r], PHI[r], B, G_max, transition, out[r])


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import, never in the 1 kHz loop."""
    viscous_force_row(np.ones(3), np.ones(3), 1.0, 1.0, 0.0, np.empty(3))
    viscous_force_rows(np.ones((2, 3)), np.ones((2, 3)), 1.0, 1.0, 0.0, np.empty((2, 3)))


warm(_warm_up)
