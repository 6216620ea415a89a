"""The haptic loop's tick for one MTM whose one field is a fixture with a compiled law (the
seed's viscous law, Rota's viscous-elastic one, a spring), in one compiled call: the fixture's force
on the PSM's tool tip, the loop's sum, then the device's clamp and Jᵀw on the MTM.

For a following teleoperation the loop (:class:`~davinci_sim.console.haptic_loop.HapticLoop`)
builds the :class:`~davinci_sim.haptics.field.HapticState`, calls each field, checks and sums
their wrenches and sends the sum to the device: with the fixture's and the render's compiled
rows already in place, the Python between them cost ~50 µs a tick. :func:`fixture_render`
runs that chain — :func:`~davinci_sim.haptics.fixture_row.fixture_law_row` (the field's
row), the sum from zeros (``as_wrench`` then ``total +=``), and
:func:`~davinci_sim.devices.device_row.render_row` (the device's) — on the same inputs the
Python path reads (the tip's pose ``Arm._measured_T``, the MTM's kinematics), so the same bits
(``tests/console/test_haptic_row.py``). Where anything differs (another field or more than
one, a device that renders in Python, numba off) the loop takes its Python path, the oracle.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from davinci_sim.devices.device_row import render_row
from davinci_sim.haptics.fixture_row import NO_PARAMS, VISCOUS, fixture_law_row
from davinci_sim.kinematics import jit
from davinci_sim.kinematics.scratch import local

#: What :func:`fixture_render` returns when the fixture's force is not finite (nothing
#: rendered: the loop reports the field's error and renders its zero sum in Python).
NOT_FINITE = -1


@numba.njit(cache=True, nogil=True)
def fixture_render(
    T_world_camera, T_camera_tip, vf_p, vf_v, started, vf_dt, vf_alpha, centre, basis, AE,
    AA, EE, starts, edges, cumulative, lengths, B, G_max, transition, summed, law, law_fn,
    params, previous, steps, T_ref_base, J, ftmax, requested, limited, tau,
):  # fmt: skip
    """One MTM's haptic tick: the fixture's force (its ``law``, ``law_fn`` and ``params`` as
    :func:`~davinci_sim.haptics.fixture_row.fixture_law_row` takes them; N, camera axes; the
    velocity filter's memory ``vf_p``, ``vf_v`` updated in place) on the tool tip ``T_camera_tip``
    (4, 4, m), the fixture's path constants in the world frame (the camera's pose in it
    ``T_world_camera``); the loop's sum ``requested`` (6,), N and N·m; then the wrench let
    through ``limited`` (6,) and the MTM's efforts ``tau`` (dof,), :func:`render_row`'s
    (``previous``, ``steps``, ``T_ref_base``, ``J``, ``ftmax`` as it takes them). Returns
    whether the clamp changed the wrench (1 or 0), or :data:`NOT_FINITE` (the filter
    updated and the force in ``requested[:3]``, nothing else)."""
    # (in the frame: every tick, for each following MTM)
    p_camera, cp, pt, vt = local(3), local(8), local(3), local(3)
    f, f_camera = local(3), local(3)
    for i in range(3):
        p_camera[i] = T_camera_tip[i, 3]
    fixture_law_row(
        T_world_camera, p_camera, vf_p, vf_v, started, vf_dt, vf_alpha, centre, basis, AE,
        AA, EE, starts, edges, cumulative, lengths, B, G_max, transition, summed, law, law_fn,
        params, cp, pt, vt, f, f_camera,
    )  # fmt: skip
    for i in range(3):
        if not math.isfinite(f_camera[i]):
            for m in range(3):
                requested[m] = f_camera[m]
            return NOT_FINITE
    for i in range(3):  # (the loop's total: zeros, += the field's wrench, torque zeros)
        requested[i] = 0.0 + f_camera[i]
        requested[3 + i] = 0.0 + 0.0
    return 1 if render_row(requested, previous, steps, T_ref_base, J, ftmax, limited, tau) else 0


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import with the loop's one signature: the
    camera and tool poses and the MTM's Jacobian read-only (``Simulation._frames``,
    ``Arm._measured_T``, ``_measured_kinematics``), the base frame and effort limits either
    way."""
    from davinci_sim.haptics.fixture_row import ZERO_LAW_PATH, path_constants

    def readonly(a: np.ndarray) -> np.ndarray:
        a.setflags(write=False)
        return a

    path = path_constants(ZERO_LAW_PATH)
    assert path is not None
    for T_ref_base in (readonly(np.eye(4)), np.eye(4)):
        for ftmax in (readonly(np.ones(7)), np.ones(7)):
            args = (
                readonly(np.eye(4)), readonly(np.eye(4)), np.zeros(3), np.zeros(3), True,
                0.001, 0.5, *path, 1.0, 1.0, 0.0, True, VISCOUS, 0, NO_PARAMS.copy(), np.zeros(6),
                np.ones(4), T_ref_base,
                readonly(np.zeros((6, 7))), ftmax, np.empty(6), np.empty(6), np.empty(7),
            )  # fmt: skip
            fixture_render(*args)


COMPILED = jit.ENABLED and jit.warmed_up(_warm_up, "the haptic loop's compiled tick: Python runs")
