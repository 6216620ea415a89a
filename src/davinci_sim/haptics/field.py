"""The force-field interface of the haptic loop.

A force field is any callable ``field(state) -> wrench`` (a function, or an object with
``__call__``). Each tick, after the physics step, the haptic loop builds one
:class:`HapticState` per PSM teleoperation that is following, calls every field registered
for that MTM, sums their wrenches, clamps the sum to the device's safety limits and sends it
to the MTM. Fields should be pure functions of the state (keep their own state, such as a
filter, explicit and small).

The wrench is what the operator's hand feels at the MTM handle: a 6-vector, force (N) then
torque (N·m), or just a force (3,), **in the display frame HRSV**, which has the same axes
as the camera frame (x left, y up, z into the scene; the teleoperation maps one onto the
other). So a force computed from the tool tip's motion in the camera frame is returned as
is: pushing the tool towards +x_camera pushes the hand towards +x_HRSV.

Example, a viscous field resisting tool motion (5 N·s/m)::

    def viscous(state: HapticState):
        return -5.0 * state.twist_camera_tip[:3]

    console.haptics.add_field(viscous, mtm="MTMR")

The state computes what a field reads on first access (the tool tip's pose and twist, the
contact force on the instrument, which costs a pass over the contacts), so a field pays only
for what it uses.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from typing import Protocol, runtime_checkable

import numpy as np


def _readonly(a) -> np.ndarray:
    arr = np.asarray(a, dtype=float)
    if arr.flags.writeable:
        arr = arr.copy()
        arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class HapticState:
    """The state a force field sees at one tick (arrays are read-only).

    The tool-tip pose and twist, the jaw and the contact force are computed on first access
    (a field that does not use them costs nothing for them), from the simulation as it is
    during this tick's haptic step: read them inside the field call, do not keep the state
    for later. :meth:`from_values` builds a state from given values (tests, offline use).
    """

    time: float
    """Simulation time after the physics step, s."""
    mtm: str
    psm: str
    T_world_camera: np.ndarray
    """The camera (ECM tip) in the world (cart) frame, 4x4, m: for fields defined in the
    world, e.g. a path on the phantom (``T_world_tip = T_world_camera · T_camera_tip``)."""
    T_hrsv_mtm: np.ndarray
    """MTM handle in HRSV, 4x4, m (read at the start of the tick)."""
    twist_hrsv_mtm: np.ndarray
    """MTM handle velocity in HRSV axes (6,): linear m/s then angular rad/s."""
    gripper: float
    """MTM gripper opening, rad."""
    following: bool
    tip: Callable[[], tuple[np.ndarray, np.ndarray]] = field(repr=False)
    """Provider of ``(T_camera_tip, twist_camera_tip)``."""
    jaw_provider: Callable[[], float] = field(repr=False)
    contact_provider: Callable[[], np.ndarray] = field(repr=False)
    pose_provider: Callable[[], np.ndarray] | None = field(default=None, repr=False)
    """Provider of ``T_camera_tip`` alone (the same pose as ``tip``'s), so that a field
    reading only the pose does not pay for the twist; None: ``tip`` provides it."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "T_world_camera", _readonly(self.T_world_camera))
        object.__setattr__(self, "T_hrsv_mtm", _readonly(self.T_hrsv_mtm))
        object.__setattr__(self, "twist_hrsv_mtm", _readonly(self.twist_hrsv_mtm))

    @classmethod
    def from_values(
        cls,
        *,
        T_camera_tip,
        twist_camera_tip=(0.0,) * 6,
        T_world_camera=None,
        T_hrsv_mtm=None,
        twist_hrsv_mtm=(0.0,) * 6,
        gripper: float = 0.0,
        jaw: float = 0.0,
        contact_force_camera=(0.0, 0.0, 0.0),
        time: float = 0.0,
        mtm: str = "MTMR",
        psm: str = "PSM1",
        following: bool = True,
    ) -> HapticState:
        """A state with the given values (identity frames by default)."""
        T = _readonly(T_camera_tip)
        tw = _readonly(twist_camera_tip)
        f = _readonly(contact_force_camera)
        return cls(
            time=time,
            mtm=mtm,
            psm=psm,
            T_world_camera=np.eye(4) if T_world_camera is None else T_world_camera,
            T_hrsv_mtm=np.eye(4) if T_hrsv_mtm is None else T_hrsv_mtm,
            twist_hrsv_mtm=twist_hrsv_mtm,
            gripper=float(gripper),
            following=following,
            tip=lambda: (T, tw),
            jaw_provider=lambda: float(jaw),
            contact_provider=lambda: f,
        )

    @cached_property
    def _tip_state(self) -> tuple[np.ndarray, np.ndarray]:
        T, twist = self.tip()
        return _readonly(T), _readonly(twist)

    @cached_property
    def _pose(self) -> np.ndarray:
        if self.pose_provider is None or "_tip_state" in self.__dict__:
            return self._tip_state[0]
        return _readonly(self.pose_provider())

    @property
    def T_camera_tip(self) -> np.ndarray:
        """PSM tool tip in the camera (ECM tip) frame, 4x4, m (``PSMx/measured_cp``)."""
        return self._pose

    @property
    def twist_camera_tip(self) -> np.ndarray:
        """Tool tip velocity in camera axes (6,): linear m/s then angular rad/s."""
        return self._tip_state[1]

    @property
    def p_camera_tip(self) -> np.ndarray:
        """Tool tip position in the camera frame, m."""
        return self.T_camera_tip[:3, 3]

    @property
    def v_camera_tip(self) -> np.ndarray:
        """Tool tip linear velocity in camera axes, m/s."""
        return self.twist_camera_tip[:3]

    @cached_property
    def jaw(self) -> float:
        """PSM jaw opening, rad."""
        return float(self.jaw_provider())

    @cached_property
    def contact_force_camera(self) -> np.ndarray:
        """Contact force the environment exerts on the instrument, N, camera axes."""
        return _readonly(self.contact_provider())


@runtime_checkable
class ForceField(Protocol):
    """``field(state) -> wrench``: (6,) force N then torque N·m, or (3,) force, HRSV axes."""

    def __call__(self, state: HapticState): ...


def as_wrench(value) -> np.ndarray:
    """A field's output as a finite 6-vector.

    Raises:
        ValueError: if it is not 3 or 6 finite numbers.
    """
    w = np.asarray(value, dtype=float)
    if w.shape == (3,):
        w = np.concatenate([w, np.zeros(3)])
    if w.shape != (6,) or not np.isfinite(w).all():
        raise ValueError(f"a force field must return 3 or 6 finite numbers, got {value!r}")
    return w
