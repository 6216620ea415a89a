"""Combining fixtures: the force of several fixtures is the sum of their forces.

``combine(guidance, wall)`` is itself a fixture (``force(position, velocity)``), in the one
frame all its parts share. Nested sums are flattened. A sum can be capped as a whole by the
haptic loop's safety limits (:mod:`davinci_sim.devices.safety`), not here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from davinci_sim.haptics.fixture import Fixture


@dataclass(frozen=True, eq=False)
class FixtureSum:
    """The sum of ``fixtures``' forces."""

    fixtures: tuple[Fixture, ...]

    def __post_init__(self) -> None:
        for f in self.fixtures:
            if not callable(getattr(f, "force", None)):
                raise TypeError(f"not a fixture (no force(position, velocity)): {f!r}")

    def force(self, position, velocity) -> np.ndarray:
        p = np.asarray(position, dtype=float)
        total = np.zeros(np.broadcast_shapes(p.shape, np.shape(velocity)))
        for f in self.fixtures:
            total = total + np.asarray(f.force(position, velocity), dtype=float)
        return total


def combine(*fixtures: Fixture) -> FixtureSum:
    """A fixture whose force is the sum of ``fixtures``' (nested sums flattened)."""
    flat: list[Fixture] = []
    for f in fixtures:
        flat.extend(f.fixtures if isinstance(f, FixtureSum) else (f,))
    return FixtureSum(tuple(flat))
