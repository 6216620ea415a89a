"""Safety limits on every wrench sent to an MTM: maximum force/torque and rate of change.

:func:`clamp_wrench` is the pure law; :class:`WrenchLimiter` keeps the previous output so the
rate limit can apply tick after tick. Wrenches are 6-vectors, force (N) then torque (N·m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class WrenchLimits:
    """Limits on a wrench sent to an MTM (our defaults, see each field).

    ``math.inf`` disables a limit; every limit must be > 0.
    """

    max_force: float = 10.0
    """Largest force magnitude, N. The seed paper's guidance forces went up to 8 N."""
    max_torque: float = 0.2
    """Largest torque magnitude, N·m (the MTM wrist motors give about 0.1 N·m, dvrk.md 1.5)."""
    max_force_rate: float = 1000.0
    """Largest change of the force vector, N/s (1 N per 1 ms tick)."""
    max_torque_rate: float = 20.0
    """Largest change of the torque vector, N·m/s."""

    def __post_init__(self) -> None:
        for name in ("max_force", "max_torque", "max_force_rate", "max_torque_rate"):
            value = getattr(self, name)
            if not isinstance(value, int | float) or math.isnan(value) or value <= 0:
                raise ValueError(f"WrenchLimits.{name} must be a number > 0, got {value!r}")


def _limit_norm(v: list[float], limit: float) -> list[float]:
    """``v`` scaled down to norm ``limit`` if longer (floats: this runs every tick)."""
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if n > limit:
        k = limit / n
        return [v[0] * k, v[1] * k, v[2] * k]
    return v


def _toward(prev: list[float], target: list[float], max_step: float) -> list[float]:
    step = _limit_norm([target[0] - prev[0], target[1] - prev[1], target[2] - prev[2]], max_step)
    return [prev[0] + step[0], prev[1] + step[1], prev[2] + step[2]]


def clamp_wrench(wrench, previous, limits: WrenchLimits, dt: float) -> tuple[np.ndarray, bool]:
    """Clamp ``wrench`` to the magnitude limits, then limit its change from ``previous``.

    Both clamps keep the direction of what they shorten (the magnitude clamp scales the
    force/torque vector; the rate clamp moves from ``previous`` towards the target along a
    straight line), so a clamped wrench never points elsewhere than asked. Since
    ``previous`` itself is within the limits, so is the result.

    Args:
        wrench: requested wrench (6,), N and N·m.
        previous: wrench sent one tick before (6,).
        limits: the limits.
        dt: time since ``previous`` was sent, s (> 0).

    Returns:
        ``(clamped wrench, whether any limit was active)``.

    Raises:
        ValueError: for a wrench that is not 6 finite numbers, or ``dt <= 0``.
    """
    w = np.asarray(wrench, dtype=float)
    if w.shape != (6,) or not np.isfinite(w).all():
        raise ValueError(f"wrench must be 6 finite numbers (N, N·m), got {wrench!r}")
    if not dt > 0:
        raise ValueError(f"dt must be > 0, got {dt!r}")
    wl = w.tolist()
    prev = np.asarray(previous, dtype=float).tolist()
    force = _limit_norm(wl[:3], limits.max_force)
    torque = _limit_norm(wl[3:], limits.max_torque)
    force = _toward(prev[:3], force, limits.max_force_rate * dt)
    torque = _toward(prev[3:], torque, limits.max_torque_rate * dt)
    out = force + torque
    clamped = max(abs(a - b) for a, b in zip(out, wl, strict=True)) > 1e-12
    return np.array(out), clamped


def clamp_wrenches(wrench, previous, limits: WrenchLimits, dt: float) -> np.ndarray:
    """:func:`clamp_wrench` for a batch ``(n, 6)`` of finite wrenches (a study's trials, one
    device each): the same two clamps, row by row; returns the clamped ``(n, 6)``."""
    w = np.asarray(wrench, dtype=float)
    prev = np.asarray(previous, dtype=float)
    out = np.empty_like(w)
    for part, limit, rate in (
        (slice(0, 3), limits.max_force, limits.max_force_rate),
        (slice(3, 6), limits.max_torque, limits.max_torque_rate),
    ):
        target = limit_norms(w[:, part], limit)
        out[:, part] = prev[:, part] + limit_norms(target - prev[:, part], rate * dt)
    return out


def limit_norms(v: np.ndarray, limit: float) -> np.ndarray:
    """Rows of ``v`` (n, 3) scaled down to norm ``limit`` where longer (direction kept)."""
    n = np.sqrt(np.einsum("ij,ij->i", v, v))
    long = n > limit
    return v * np.where(long, limit / np.where(long, n, 1.0), 1.0)[:, None]


class WrenchLimiter:
    """Applies :func:`clamp_wrench` tick after tick, remembering the last output."""

    def __init__(self, limits: WrenchLimits | None = None, dt: float = 0.001) -> None:
        self.limits = limits or WrenchLimits()
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt!r}")
        self.dt = dt
        self.previous = np.zeros(6)
        """The last wrench let through (6,), N and N·m."""
        self.active = False
        """Whether the last call clamped anything."""

    def limit(self, wrench) -> np.ndarray:
        """The wrench to send now; raises ``ValueError`` for a non-finite or mis-shaped one."""
        out, self.active = clamp_wrench(wrench, self.previous, self.limits, self.dt)
        self.previous = out
        return out.copy()

    def reset(self) -> None:
        """Forget the history: the next wrench ramps up from zero (after a safety stop)."""
        self.previous = np.zeros(6)
        self.active = False
