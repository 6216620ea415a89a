"""Virtual fixtures as batch force laws, and their adapter to the haptic loop's force fields.

A *fixture* is any object with ``force(position, velocity) -> force``: tool tip positions
(m) and velocities (m/s), ``(..., 3)``, in the fixture's frame, to forces on the hand
``(..., 3)`` (N) in the same axes; pure and vectorised, so that one fixture serves one
haptic tick or a batch of simulated trials. The fixtures of this package:
:class:`~davinci_sim.haptics.viscous.ViscousGuidance` (the seed's),
:class:`~davinci_sim.haptics.spring.SpringGuidance`,
:class:`~davinci_sim.haptics.wall.PlaneWall`, :class:`~davinci_sim.haptics.wall.SphereWall`,
and sums of them (:func:`~davinci_sim.haptics.combine.combine`).

:class:`FixtureField` wraps a fixture as a
:class:`~davinci_sim.haptics.field.ForceField` (``field(state) -> force``) for the console's
haptic loop: it reads the tool tip from the :class:`~davinci_sim.haptics.field.HapticState`
(camera frame), moves it into the fixture's frame, and returns the force in camera axes,
which are the HRSV axes of the hand (see :mod:`davinci_sim.haptics.field`). Forces act at
the hand as computed from the *tool's* motion, as in the seed (no scaling by the teleop).
"""

from __future__ import annotations

from typing import Literal, Protocol, runtime_checkable

import numpy as np

from davinci_sim.geometry.so3 import rotate_rows

# (the viscous law's compiled row, compiled or loaded from numba's cache with this module:
# the first haptic tick of a fixture must not wait for it inside the loop)
from davinci_sim.haptics import fixture_row
from davinci_sim.haptics.field import HapticState
from davinci_sim.haptics.velocity import DEFAULT_CUTOFF_HZ, VelocityFilter

Frame = Literal["camera", "world"]
VelocitySource = Literal["measured", "filtered"]


@runtime_checkable
class Fixture(Protocol):
    """``force(position, velocity) -> force``, all ``(..., 3)`` in the fixture's frame."""

    def force(self, position, velocity) -> np.ndarray: ...


def fixture_force_camera(
    fixture: Fixture,
    T_frame_camera: np.ndarray | None,
    p_camera_tip: np.ndarray,
    v_camera_tip: np.ndarray,
) -> np.ndarray:
    """The force (..., 3), N, camera axes, of ``fixture`` on tool tips at ``p_camera_tip``
    (m) moving at ``v_camera_tip`` (m/s), (..., 3) in the camera frame: the tips moved into
    the fixture's frame (``T_frame_camera``, 4x4: the camera in the fixture's frame; None:
    the fixture is in the camera frame), the force rotated back. Elementwise rotations (the
    same bits in any batch, see :func:`~davinci_sim.geometry.so3.rotate_rows`)."""
    if T_frame_camera is None:
        return np.asarray(fixture.force(p_camera_tip, v_camera_tip), dtype=float)
    R, t = T_frame_camera[:3, :3], T_frame_camera[:3, 3]
    f = fixture.force(rotate_rows(R, p_camera_tip) + t, rotate_rows(R, v_camera_tip))
    return rotate_rows(R.T, np.asarray(f, dtype=float))


class FixtureField:
    """A fixture as a haptic-loop force field (``field(state) -> (3,) force``, HRSV axes).

    Args:
        fixture: the batch force law.
        frame: the fixture's frame: ``"camera"`` (ECM tip; the fixture moves with the
            endoscope) or ``"world"`` (the cart; e.g. a path on the phantom, which stays put
            when the endoscope moves).
        velocity: ``"filtered"`` (default): low-pass filtered finite differences of the
            measured tip positions (:mod:`davinci_sim.haptics.velocity`), one filter per PSM;
            ``"measured"``: the PSM's ``measured_cv`` (the simulator's exact tip velocity).
        cutoff_hz, dt: of the velocity filter.
    """

    def __init__(
        self,
        fixture: Fixture,
        *,
        frame: Frame = "world",
        velocity: VelocitySource = "filtered",
        cutoff_hz: float = DEFAULT_CUTOFF_HZ,
        dt: float = 0.001,
    ) -> None:
        if not callable(getattr(fixture, "force", None)):
            raise TypeError(f"a fixture needs a force(position, velocity) method, got {fixture!r}")
        if frame not in ("camera", "world"):
            raise ValueError(f"unknown frame {frame!r}; frames: ['camera', 'world']")
        if velocity not in ("measured", "filtered"):
            raise ValueError(f"unknown velocity source {velocity!r}; ['measured', 'filtered']")
        self.fixture = fixture
        self.frame = frame
        self.velocity_source = velocity
        self.cutoff_hz = cutoff_hz
        self.dt = dt
        self._filters: dict[str, VelocityFilter] = {}
        self.__name__ = type(fixture).__name__
        self._row: tuple | None | bool = False  # (False: not looked for yet)

    def tip_velocity_camera(self, state: HapticState) -> np.ndarray:
        """The tool tip velocity this field uses, camera axes, m/s."""
        if self.velocity_source == "measured":
            return np.asarray(state.v_camera_tip, dtype=float)
        f = self._filters.get(state.psm)
        if f is None:
            f = self._filters[state.psm] = VelocityFilter(dt=self.dt, cutoff_hz=self.cutoff_hz)
        return f.update(state.p_camera_tip)

    def __call__(self, state: HapticState) -> np.ndarray:
        row = self.compiled_row()
        if row is not None:
            return self._compiled_force(state, row)
        p = np.asarray(state.p_camera_tip, dtype=float)
        v = self.tip_velocity_camera(state)
        T = None if self.frame == "camera" else np.asarray(state.T_world_camera, dtype=float)
        return fixture_force_camera(self.fixture, T, p, v)

    def compiled_row(self) -> tuple | None:
        """The field's compiled row and its constants (``fixture_row.fixture_force``, the
        path's constants, ``B``, ``G_max``, ``transition``, whether summed, the law, a user
        law's address and the law's parameters), or None where it has none (see
        :func:`_compiled_form`)."""
        if self._row is False:
            self._row = _compiled_form(self)
        return self._row  # type: ignore[return-value]

    def row_filter(self, psm: str) -> VelocityFilter:
        """The velocity filter of ``psm`` with writable memory, for the compiled row to
        update in place (created at the first call, as :meth:`tip_velocity_camera` does)."""
        f = self._filters.get(psm)
        if f is None:
            f = self._filters[psm] = VelocityFilter(dt=self.dt, cutoff_hz=self.cutoff_hz)
        if not (f._p.flags.writeable and f._v.flags.writeable):  # (e.g. restored views)
            f._p, f._v = np.array(f._p, dtype=float), np.array(f._v, dtype=float)
        return f

    def _compiled_force(self, state: HapticState, row: tuple) -> np.ndarray:
        """:meth:`__call__` by the compiled row (:mod:`~davinci_sim.haptics.fixture_row`):
        the same bits, the filter's memory updated in place."""
        f = self.row_filter(state.psm)
        out = np.empty(3)
        force, path, B, G_max, transition, summed, law, law_fn, params = row
        force(
            np.array(state.T_world_camera, dtype=float), np.array(state.p_camera_tip, dtype=float),
            f._p, f._v, bool(f._started), f.dt, f.alpha, *path, B, G_max, transition, summed,
            law, law_fn, params, out,
        )  # fmt: skip
        f._started[...] = True
        return out

    def reset(self) -> None:
        """Forget the velocity filters' history (e.g. after a clutch or a new repetition)."""
        self._filters.clear()

    def get_state(self) -> dict:
        """Each PSM's velocity filter's memory (:meth:`VelocityFilter.get_state`)."""
        return {psm: f.get_state() for psm, f in self._filters.items()}

    def set_state(self, state: dict) -> None:
        self._filters.clear()
        for psm, filter_state in state.items():
            f = self._filters[psm] = VelocityFilter(dt=self.dt, cutoff_hz=self.cutoff_hz)
            f.set_state(filter_state)


def _compiled_form(field: FixtureField) -> tuple | None:
    """``field``'s compiled row and its arguments (the row, path constants, ``B``, ``G_max``,
    ``transition``, whether summed, the law, a user law's address, its parameters), or None
    where it has none: numba off, a fixture with no compiled law
    (:func:`~davinci_sim.haptics.fixture_row.compiled_law_of`; alone or as a sum of one),
    the camera frame, the measured velocity, a path longer than the brute force serves."""
    from davinci_sim.haptics.combine import FixtureSum
    from davinci_sim.kinematics import jit

    if not jit.ENABLED or field.frame != "world" or field.velocity_source != "filtered":
        return None
    fixture, summed = field.fixture, False
    row = fixture_row.fixture_force
    if isinstance(fixture, FixtureSum) and not fixture.fixtures:
        # No force (a task's ``fixture: none``): the seed's viscous law at (B, G_max) =
        # (0, 0), Table I's unassisted condition, on any path. Its force is ±0, which the
        # haptic loop's sum makes +0.0 as it does the empty sum's zeros; the velocity filter
        # runs as it does for any field.
        path = fixture_row.path_constants(fixture_row.ZERO_LAW_PATH)
        return None if path is None else (row, path, 0.0, 0.0, 0.0, True, fixture_row.VISCOUS,
                                          0, fixture_row.NO_PARAMS.copy())  # fmt: skip
    if isinstance(fixture, FixtureSum) and len(fixture.fixtures) == 1:
        fixture, summed = fixture.fixtures[0], True
    law = fixture_row.compiled_law_of(fixture)
    if law is None:
        return None
    code, B, G_max, transition, path_, law_fn, params = law
    path = fixture_row.path_constants(path_)
    if path is None:
        return None
    return row, path, B, G_max, transition, summed, code, law_fn, params
