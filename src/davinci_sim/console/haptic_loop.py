"""The haptic loop: force fields → safety limits → wrench on each MTM, every tick.

Registered as the ``haptics`` component after the console and the teleoperations, it runs in
``post_step`` (after the physics step of the tick): for each PSM teleoperation that is
following and has fields, it builds the :class:`~davinci_sim.haptics.field.HapticState`,
sums the fields' wrenches and sends the sum through the device's
:meth:`~davinci_sim.devices.MasterDevice.servo_cf`, which clamps it (magnitude and rate,
:mod:`davinci_sim.devices.safety`) and refuses it for a stale device. When following stops
the teleoperation itself zeroes the wrench (clutch) or takes the MTM back (alignment).
With no field registered the loop costs nothing.

A field that raises or returns something other than 3 or 6 finite numbers is skipped for
that tick (its contribution is zero) and reported on the ``haptics`` error channel, at most
once per second per field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from davinci_sim.console import haptic_row
from davinci_sim.haptics.field import HapticState, as_wrench
from davinci_sim.haptics.fixture import FixtureField
from davinci_sim.sim.channels import Channels
from davinci_sim.sim.state import capture, restore
from davinci_sim.sim.types import ACCEPTED, CommandResult

if TYPE_CHECKING:
    from davinci_sim.console.console import Console
    from davinci_sim.console.teleop_psm import TeleopPSM
    from davinci_sim.sim.simulation import Simulation

ENABLED = haptic_row.COMPILED
"""Whether the loop uses the compiled tick of :mod:`.haptic_row` where it applies (off: the
Python path, e.g. to compare)."""

#: Errors of one field are reported at most this often (s).
FIELD_ERROR_INTERVAL = 1.0


@dataclass
class _Entry:
    name: str
    field: object
    mtm: str | None
    last_error: float = -math.inf


@dataclass(frozen=True, eq=False)
class HapticsState:
    """What the haptic loop publishes."""

    fields: tuple[tuple[str, str | None], ...]
    """(field name, MTM or None for all) of each registered field."""
    requested: dict[str, np.ndarray] = field(default_factory=dict)
    """MTM -> the fields' summed wrench at the last tick it was computed (6,)."""
    sent: dict[str, np.ndarray] = field(default_factory=dict)
    """MTM -> the wrench the device got after the safety limits (6,)."""


class HapticLoop:
    """The ``haptics`` component of a console; see the module docstring."""

    name = "haptics"

    def __init__(self, sim: Simulation, console: Console) -> None:
        self.sim = sim
        self.console = console
        self.channels = Channels(self.name)
        self._fields: dict[str, _Entry] = {}
        self._requested: dict[str, np.ndarray] = {}

    # ------------------------------------------------------------ fields
    def add_field(self, force_field, *, mtm: str | None = None, name: str | None = None) -> str:
        """Register ``force_field`` for ``mtm`` (None: every MTM); returns its name.

        Raises:
            TypeError: if it is not callable.
            ValueError: for a name already in use or an unknown MTM.
        """
        if not callable(force_field):
            raise TypeError(
                f"a force field must be callable (state -> wrench), got {force_field!r}"
            )
        mtms = {t.mtm_name for t in self.console.psm_teleops.values()}
        if mtm is not None and mtm not in mtms:
            raise ValueError(f"unknown MTM {mtm!r}; MTMs with a teleoperation: {sorted(mtms)}")
        if name is None:
            base = getattr(force_field, "__name__", type(force_field).__name__)
            name, i = base, 2
            while name in self._fields:
                name, i = f"{base}_{i}", i + 1
        if name in self._fields:
            raise ValueError(f"a force field named {name!r} is already registered")
        self._fields[name] = _Entry(name, force_field, mtm)
        return name

    def remove_field(self, name: str) -> CommandResult:
        if name not in self._fields:
            text = f"remove_field: no field {name!r}; fields: {list(self._fields)}"
            self.channels.message("error", text, self.sim.time)
            return CommandResult(False, f"{self.name}: {text}")
        del self._fields[name]
        return ACCEPTED

    def field_names(self) -> list[str]:
        return list(self._fields)

    def field(self, name: str):
        """The force field registered as ``name`` (KeyError if none)."""
        return self._fields[name].field

    # ------------------------------------------------------------ component
    def pre_step(self, t: float) -> None:
        """Nothing before the physics step: the loop runs in :meth:`post_step`."""

    def post_step(self, t: float) -> None:
        if not self._fields:
            return
        T_world_camera = None
        for teleop in self.console.psm_teleops.values():
            if not teleop.is_following():
                continue
            entries = self.entries_for(teleop.mtm_name)
            if not entries:
                continue
            if T_world_camera is None:
                T_world_camera = self._T_world_camera()
            if len(entries) == 1 and self._fixture_render(teleop, entries[0], t, T_world_camera):
                continue
            state = self.state(teleop, t, T_world_camera)
            total = np.zeros(6)
            for entry in entries:
                try:
                    total += as_wrench(entry.field(state))
                except Exception as e:  # a faulty field must not stop the loop
                    self._field_error(entry, e, t)
            self._requested[teleop.mtm_name] = total
            if math.isfinite(total.sum()):  # each term is finite (as_wrench); the sum too
                teleop.device._render_wrench(total)  # validated here: once, not three times
            else:
                teleop.device.servo_cf(total)  # (refused with the device's message)

    def _fixture_render(self, teleop: TeleopPSM, entry: _Entry, t: float, T_world_camera) -> bool:
        """The tick of ``teleop``'s MTM in one compiled call (:mod:`.haptic_row`) when its
        one field is a :class:`~davinci_sim.haptics.fixture.FixtureField` with a compiled row
        and its device renders compiled; False (nothing done) otherwise."""
        field_ = entry.field
        if not ENABLED or type(field_) is not FixtureField:
            return False
        row = field_.compiled_row()
        render = getattr(teleop.device, "render_args", None)
        args = None if row is None or render is None else render()
        if args is None:
            return False
        q, T_ref_base, J, previous, steps, ftmax = args
        psm = teleop.psm
        vf = field_.row_filter(psm.name)
        _, path, B, G_max, transition, summed, law, law_fn, params = row
        requested, limited, tau = np.empty(6), np.empty(6), np.empty(len(q))
        arguments = (
            T_world_camera, psm._measured_T(), vf._p, vf._v, bool(vf._started), vf.dt, vf.alpha,
            *path, B, G_max, transition, summed, law, law_fn, params, previous, steps,
            T_ref_base, J, ftmax, requested, limited, tau,
        )  # fmt: skip
        active = haptic_row.fixture_render(*arguments)
        vf._started[...] = True
        if active == haptic_row.NOT_FINITE:  # (the Python path's error and zero sum)
            try:
                as_wrench(requested[:3].copy())  # (the field's force: as_wrench's refusal)
            except ValueError as e:
                self._field_error(entry, e, t)
            self._requested[teleop.mtm_name] = total = np.zeros(6)
            teleop.device._render_wrench(total)
            return True
        self._requested[teleop.mtm_name] = requested
        teleop.device.rendered(limited, tau, bool(active), q, T_ref_base)
        return True

    def entries_for(self, mtm: str) -> list:
        """The fields rendered on ``mtm`` (those added for it and those for every MTM), in
        the order they were added."""
        return [e for e in self._fields.values() if e.mtm in (None, mtm)]

    def requested(self, mtm: str) -> np.ndarray | None:
        """The fields' summed wrench for ``mtm`` at the last tick it was computed (6,), HRSV
        axes, N and N·m (a copy), or None: what :meth:`snapshot` publishes, without building
        it (the task session reads it every tick)."""
        w = self._requested.get(mtm)
        return None if w is None else w.copy()

    def snapshot(self) -> HapticsState:
        sent = {}
        for teleop in self.console.psm_teleops.values():
            sent.setdefault(teleop.mtm_name, teleop.device.wrench())
        return HapticsState(
            fields=tuple((e.name, e.mtm) for e in self._fields.values()),
            requested={k: v.copy() for k, v in self._requested.items()},
            sent=sent,
        )

    # ------------------------------------------------------------ state
    def _T_world_camera(self) -> np.ndarray:
        if "ECM" not in self.sim.arms:
            return np.eye(4)
        T = self.sim.T_cart_camera()  # the cart frame is the world frame
        T.setflags(write=False)
        return T

    def state(
        self, teleop: TeleopPSM, t: float, T_world_camera: np.ndarray | None = None
    ) -> HapticState:
        """The :class:`HapticState` of ``teleop`` now (also useful to test a field)."""
        psm = teleop.psm
        sim = self.sim
        if T_world_camera is None:
            T_world_camera = self._T_world_camera()

        def tip() -> tuple[np.ndarray, np.ndarray]:
            return psm._measured_T(), psm._measured_twist()  # (measured_cp/cv, read-only)

        def pose() -> np.ndarray:
            return psm._measured_T()  # (measured_cp().T, read-only)

        def contact() -> np.ndarray:
            return T_world_camera[:3, :3].T @ sim.contact_force(psm.name)

        inp = teleop.device.input()
        return HapticState(
            time=t,
            mtm=teleop.mtm_name,
            psm=psm.name,
            T_world_camera=T_world_camera,
            T_hrsv_mtm=inp.T_hrsv_tip,
            twist_hrsv_mtm=inp.twist_hrsv_tip,
            gripper=inp.gripper,
            following=teleop.is_following(),
            tip=tip,
            jaw_provider=psm.jaw.measured_jp,
            contact_provider=contact,
            pose_provider=pose,
        )

    def _field_error(self, entry: _Entry, error: Exception, t: float) -> None:
        if t - entry.last_error >= FIELD_ERROR_INTERVAL:
            entry.last_error = t
            self.channels.message(
                "error", f"force field {entry.name!r} failed: {type(error).__name__}: {error}", t
            )

    # ------------------------------------------------------------ state
    def get_state(self) -> dict:
        """The last requested wrenches, and for each registered field its error throttle
        and its own state (``field.get_state()``, None for a field without state: a pure
        law). Which fields are registered is configuration: :meth:`set_state` needs the
        same ones."""
        fields = {}
        for name, entry in self._fields.items():
            get_state = getattr(entry.field, "get_state", None)
            fields[name] = (entry.last_error, None if get_state is None else get_state())
        return {"requested": capture(self, ("_requested",)), "fields": fields}

    def set_state(self, state: dict) -> None:
        """Put back a :meth:`get_state`.

        Raises:
            ValueError: if the state's fields are not the ones registered now.
        """
        if list(state["fields"]) != list(self._fields):
            raise ValueError(
                f"haptics: the state's force fields {list(state['fields'])} are not the "
                f"registered ones {list(self._fields)}"
            )
        restore(self, state["requested"], ("_requested",))
        for name, (last_error, field_state) in state["fields"].items():
            entry = self._fields[name]
            entry.last_error = last_error
            if field_state is not None:
                entry.field.set_state(field_state)
