"""Safety limits on every wrench sent to an MTM: maximum force/torque and rate of change.

:func:`clamp_wrenches` is the pure law, for a batch of devices (a study's trials) or one
(:func:`clamp_wrench`, a batch of one: the same kernel, so a device gets the same bits alone
or in a batch); :class:`WrenchLimiter` keeps the previous output so the rate limit can apply
tick after tick. Wrenches are 6-vectors, force (N) then torque (N·m). The kernel is compiled
with numba when it is available (:mod:`davinci_sim.kinematics.jit`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from davinci_sim.kinematics.jit import jit, warm


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


def clamp_wrench(wrench, previous, limits: WrenchLimits, dt: float) -> tuple[np.ndarray, bool]:
    """Clamp ``wrench`` to the magnitude limits, then limit its change from ``previous``.

    Both clamps keep the direction of what they shorten (the magnitude clamp scales the
    force/torque vector; the rate clamp moves from ``previous`` towards the target along a
    straight line), so a clamped wrench never points elsewhere than asked. Since
    ``previous`` itself is within the limits, so is the result. One row of
    :func:`clamp_wrenches`.

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
    prev = np.asarray(previous, dtype=float).reshape(1, 6)
    out = clamp_wrenches(w.reshape(1, 6), prev, limits, dt)[0]
    clamped = float(np.max(np.abs(out - w))) > 1e-12
    return out, clamped


def clamp_wrenches(wrench, previous, limits: WrenchLimits, dt: float) -> np.ndarray:
    """The clamps of :func:`clamp_wrench` for a batch ``(n, 6)`` of finite wrenches with
    their ``previous`` ``(n, 6)`` (a study's trials, one device each); returns ``(n, 6)``."""
    w = np.ascontiguousarray(wrench, dtype=float).reshape(-1, 6)
    prev = np.ascontiguousarray(previous, dtype=float).reshape(-1, 6)
    out = np.empty_like(w)
    _clamp_rows(
        w,
        prev,
        float(limits.max_force),
        float(limits.max_torque),
        float(limits.max_force_rate * dt),
        float(limits.max_torque_rate * dt),
        out,
    )
    return out


@jit
def _clamp_rows(w, prev, max_force, max_torque, max_force_step, max_torque_step, out):
    """Row by row, for the force (columns 0-2) then the torque (3-5): the target is the
    request scaled down to its magnitude limit where longer; the output moves from ``prev``
    towards it by at most the step (rate × dt). Elementwise: a row's bits do not depend on
    the batch."""
    for i in range(w.shape[0]):
        for part in range(2):
            j = 3 * part
            limit = max_force if part == 0 else max_torque
            step = max_force_step if part == 0 else max_torque_step
            x, y, z = w[i, j], w[i, j + 1], w[i, j + 2]
            # Squares summed as (x² + z²) + y²: the order numpy's einsum used when the study
            # in docs/study was computed, so its rows stay bit-identical.
            n = math.sqrt((x * x + z * z) + y * y)
            if n > limit:
                k = limit / n
                x, y, z = x * k, y * k, z * k
            px, py, pz = prev[i, j], prev[i, j + 1], prev[i, j + 2]
            dx, dy, dz = x - px, y - py, z - pz
            n = math.sqrt((dx * dx + dz * dz) + dy * dy)
            if n > step:
                k = step / n
                dx, dy, dz = dx * k, dy * k, dz * k
            out[i, j] = px + dx
            out[i, j + 1] = py + dy
            out[i, j + 2] = pz + dz


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

    def limit_checked(self, wrench: np.ndarray) -> np.ndarray:
        """:meth:`limit` of a wrench already checked as 6 finite floats (a device's
        ``servo_cf`` checks it at its edge): the same clamp and the same ``active``, the
        wrench not checked again (this runs at 1 kHz)."""
        out = clamp_wrenches(wrench.reshape(1, 6), self.previous.reshape(1, 6), self.limits,
                             self.dt)[0]  # fmt: skip
        # clamp_wrench's test, max |out − w| > 1e-12, on floats (all finite here).
        pairs = zip(out.tolist(), wrench.tolist(), strict=True)
        self.active = any(abs(a - b) > 1e-12 for a, b in pairs)
        self.previous = out
        return out.copy()

    def reset(self) -> None:
        """Forget the history: the next wrench ramps up from zero (after a safety stop)."""
        self.previous = np.zeros(6)
        self.active = False


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import, as
    :mod:`~davinci_sim.kinematics.fk_compiled` does: never in the middle of a 1 kHz loop.
    (The first wrench of a device would otherwise compile it in the simulation's thread.)"""
    clamp_wrench(np.zeros(6), np.zeros(6), WrenchLimits(), 0.001)


warm(_warm_up)
