"""The seed's viscous fixture on one tool tip as one compiled row: the velocity filter, the tip
into the fixture's frame, the path's closest point, the viscous law, the force back in camera
axes (:class:`~davinci_sim.haptics.fixture.FixtureField` of a
:class:`~davinci_sim.haptics.viscous.ViscousGuidance` in the world frame with the filtered
velocity).

:func:`viscous_fixture_row` is the one per-row form of that chain: the live haptic loop calls
it through :func:`viscous_fixture_force` (one tip a tick), the study's compiled tick for each
of its rows (``study/tick_kernel.py``). Each step is the batch law's operations in their
order (``filtered_velocity_step``, ``rotate_rows``, ``closest_point``, ``_viscous_into``,
``FixtureSum``'s sum from zeros), so the bits are those of the Python path
(``tests/haptics/test_fixture_row.py``).

:func:`fixture_law_row` is the same chain with the law chosen by ``law``: :data:`VISCOUS` (the
seed's), :data:`VISCOUS_ELASTIC` (Rota's fixture,
:class:`~davinci_sim.haptics.viscous_elastic.ViscousElasticGuidance`: the viscous law
uncapped, the logistic elastic pull, the sum capped and scaled) or :data:`SPRING`
(:class:`~davinci_sim.haptics.spring.SpringGuidance`), each with its parameters
(:func:`law_parameters`). Their numpy forms are the oracles within 1e-12 N, not bit for
bit (``einsum`` sums in its own order; the elastic law's ``exp``
is libm's, and numpy's SIMD ``exp`` differs from it in the last bit for ~5 % of arguments
on AVX-512 machines); the live field and the console's compiled ticks both call this row,
so they agree bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from davinci_sim.geometry.path import BRUTE_FORCE_MAX_SEGMENTS, Polyline, brute_force_constants
from davinci_sim.haptics.compiled_law import call_law
from davinci_sim.haptics.path_query import _closest_point_into
from davinci_sim.haptics.viscous import DEFAULT_TRANSITION, _viscous_into
from davinci_sim.haptics.viscous_elastic import SLOPE_DIVISOR
from davinci_sim.kinematics.jit import helper, jit, warm


def path_constants(path: Polyline) -> tuple | None:
    """``path``'s arrays for the compiled closest point (new writable C arrays: one compiled
    signature, whatever flags the path's own arrays have), or None for a path the brute
    force does not serve (longer than :data:`BRUTE_FORCE_MAX_SEGMENTS`: the k-d tree)."""
    if len(path.segment_lengths) > BRUTE_FORCE_MAX_SEGMENTS:
        return None
    parts = (path.centre, *brute_force_constants(path), path.starts, path.edges,
             path.cumulative_length, path.segment_lengths)  # fmt: skip
    return tuple(np.array(a, dtype=float, order="C") for a in parts)


#: The laws :func:`fixture_law_row` computes (its ``law``).
VISCOUS, VISCOUS_ELASTIC, SPRING, USER = 0, 1, 2, 3
#: The parameters of a law that takes none but ``B``, ``G_max`` and ``transition`` (the
#: rows' one signature: six floats).
NO_PARAMS = np.zeros(6)
_EPS = 1e-12
#: The path a zero law runs on (no fixture: the viscous law at B = G_max = 0; any path
#: serves, its force is ±0).
ZERO_LAW_PATH = Polyline(np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]]))


def law_parameters(law) -> np.ndarray:
    """A fixture law's parameters as :func:`fixture_law_row` takes them (six floats): a
    :class:`~davinci_sim.haptics.viscous_elastic.ViscousElasticGuidance`'s ``(K_e,
    threshold, half, slope, max_force, assistance)`` (N, m, m, 1/m, N, 1), a
    :class:`~davinci_sim.haptics.spring.SpringGuidance`'s ``(stiffness, damping, max_force,
    transition, 0, 0)`` (N/m, N·s/m, N, m)."""
    from davinci_sim.haptics.spring import SpringGuidance

    if isinstance(law, SpringGuidance):
        return np.array([law.stiffness, law.damping, law.max_force, law.transition, 0.0, 0.0],
                        dtype=float)  # fmt: skip
    return np.array([law.elastic_gain, law.threshold, law.half, law.slope, law.max_force,
                     law.assistance], dtype=float)  # fmt: skip


def compiled_law_of(part) -> tuple | None:
    """The law :func:`fixture_law_row` computes for one fixture (not a sum): ``(law, B,
    G_max, transition, path, law_fn, params)`` (a user law's address ``law_fn``, 0 for the
    shipped laws), or None where it has no compiled law: a fixture other than the seed's
    viscous law (with one ``B`` and ``G_max``), Rota's viscous-elastic one, a spring or a
    user's compiled law. The one mapping the live field and the study's batch share."""
    from davinci_sim.haptics.compiled_law import UserLawGuidance
    from davinci_sim.haptics.spring import SpringGuidance
    from davinci_sim.haptics.viscous import ViscousGuidance
    from davinci_sim.haptics.viscous_elastic import ViscousElasticGuidance

    kind = type(part)
    if kind is ViscousGuidance:
        if not (isinstance(part.B, float) and isinstance(part.G_max, float)):
            return None
        return (VISCOUS, part.B, part.G_max, float(part.transition), part.path, 0,
                NO_PARAMS.copy())  # fmt: skip
    if kind is ViscousElasticGuidance:
        return (VISCOUS_ELASTIC, float(part.B), math.inf, 0.0, part.path, 0,
                law_parameters(part))  # fmt: skip
    if kind is SpringGuidance:
        return SPRING, 0.0, math.inf, 0.0, part.path, 0, law_parameters(part)
    if kind is UserLawGuidance:
        return USER, 0.0, math.inf, 0.0, part.path, part.law.address, part.parameters
    return None


@helper
def _spring_into(v, phi, params, out):
    """``spring_guidance`` of one row: ``v`` and ``phi`` (3,) m/s and m, ``params`` its
    :func:`law_parameters`; the force into ``out`` (3,), N."""
    k, c, cap, transition = params[0], params[1], params[2], params[3]
    dist = math.sqrt((phi[0] * phi[0] + phi[1] * phi[1]) + phi[2] * phi[2])
    safe = max(dist, _EPS)
    ramp = min(1.0, dist / transition)
    hx, hy, hz = (phi[0] / safe, phi[1] / safe, phi[2] / safe) if dist > _EPS else (0.0, 0.0, 0.0)
    along = c * ramp * ((v[0] * hx + v[1] * hy) + v[2] * hz)
    out[0], out[1], out[2] = (
        k * phi[0] - along * hx,
        k * phi[1] - along * hy,
        k * phi[2] - along * hz,
    )
    norm = math.sqrt((out[0] * out[0] + out[1] * out[1]) + out[2] * out[2])
    scale = cap / max(norm, _EPS) if norm > cap else 1.0
    for i in range(3):
        out[i] = out[i] * scale


@helper
def _viscous_elastic_into(v, phi, B, elastic, out):
    """``viscous_elastic_guidance`` of one row: ``v`` and ``phi`` (3,) m/s and m, ``B``
    N·s/m, ``elastic`` its :func:`law_parameters`; the force into ``out`` (3,), N."""
    gain, threshold, half, slope = elastic[0], elastic[1], elastic[2], elastic[3]
    max_force, assistance = elastic[4], elastic[5]
    _viscous_into(v, phi, B, math.inf, DEFAULT_TRANSITION, out)  # (uncapped)
    dist = math.sqrt((phi[0] * phi[0] + phi[1] * phi[1]) + phi[2] * phi[2])
    steep = max(slope, 1.0 / half) / SLOPE_DIVISOR
    z = -steep * (dist - threshold - half)
    e = math.exp(-abs(z))
    share = 1.0 / (1.0 + e) if z <= 0 else e / (1.0 + e)
    pull = gain * share
    for i in range(3):
        unit = phi[i] / dist if dist > _EPS else 0.0
        out[i] = out[i] + pull * unit
    norm = math.sqrt((out[0] * out[0] + out[1] * out[1]) + out[2] * out[2])
    scale = max_force / max(norm, _EPS) if norm > max_force else 1.0
    for i in range(3):
        out[i] = out[i] * (scale * assistance)


@helper
def viscous_fixture_row(
    T_task_camera, p_camera, vf_p, vf_v, started, vf_dt, vf_alpha,
    centre, basis, AE, AA, EE, starts, edges, cumulative, lengths,
    B, G_max, transition, summed, cp, pt, vt, f, f_camera,
):  # fmt: skip
    """The force ``f_camera`` (3,), N, camera axes, of the viscous fixture (``B``, N·s/m;
    ``G_max``, N; ``transition``; ``summed``: inside a ``FixtureSum`` of one) along the path
    (``centre`` … ``lengths``: its :func:`path_constants`, task frame) on the tool tip at
    ``p_camera`` (3,), m, camera frame. ``T_task_camera`` (4, 4): the camera in the task's
    frame. The velocity filter's memory ``vf_p``, ``vf_v`` (3,) is updated in place
    (``started``: it has a previous sample; ``vf_dt`` s, ``vf_alpha``); ``cp`` (8,),
    ``pt``, ``vt``, ``f`` (3,) scratch."""
    fixture_law_row(
        T_task_camera, p_camera, vf_p, vf_v, started, vf_dt, vf_alpha, centre, basis, AE, AA,
        EE, starts, edges, cumulative, lengths, B, G_max, transition, summed, VISCOUS, 0,
        NO_PARAMS, cp, pt, vt, f, f_camera,
    )  # fmt: skip


@helper
def fixture_law_row(
    T_task_camera, p_camera, vf_p, vf_v, started, vf_dt, vf_alpha,
    centre, basis, AE, AA, EE, starts, edges, cumulative, lengths,
    B, G_max, transition, summed, law, law_fn, params, cp, pt, vt, f, f_camera,
):  # fmt: skip
    """:func:`viscous_fixture_row` with the law ``law`` (:data:`VISCOUS`: ``B``, ``G_max``,
    ``transition``; :data:`VISCOUS_ELASTIC`: ``B`` and ``params``; :data:`SPRING`:
    ``params``; ``params``: :func:`law_parameters`; :data:`USER`: the user's compiled law at
    the address ``law_fn`` with ``params``, :mod:`~davinci_sim.haptics.compiled_law`)."""
    for i in range(3):  # the velocity filter (VelocityFilter.update)
        p = p_camera[i]
        if started:
            d = (p - vf_p[i]) / vf_dt
            vf_v[i] = vf_v[i] + vf_alpha * (d - vf_v[i])
        else:
            vf_v[i] = 0.0
        vf_p[i] = p
    for i in range(3):  # into the task's frame (rotate_rows, then the translation)
        pt[i] = (T_task_camera[i, 0] * p_camera[0] + T_task_camera[i, 1] * p_camera[1]) + (
            T_task_camera[i, 2] * p_camera[2]
        )
        pt[i] = pt[i] + T_task_camera[i, 3]
        vt[i] = (T_task_camera[i, 0] * vf_v[0] + T_task_camera[i, 1] * vf_v[1]) + (
            T_task_camera[i, 2] * vf_v[2]
        )
    _closest_point_into(pt, centre, basis, AE, AA, EE, starts, edges, cumulative, lengths, cp)
    if law == VISCOUS_ELASTIC:
        _viscous_elastic_into(vt, cp[3:6], B, params, f)
    elif law == SPRING:
        _spring_into(vt, cp[3:6], params, f)
    elif law == USER:
        call_law(law_fn, vt, cp[3:6], params, f)
    else:
        _viscous_into(vt, cp[3:6], B, G_max, transition, f)
    if summed:
        for i in range(3):
            f[i] = 0.0 + f[i]  # (FixtureSum: a sum started from zeros)
    for i in range(3):  # back to camera axes (rotate_rows by the rotation's transpose)
        f_camera[i] = (T_task_camera[0, i] * f[0] + T_task_camera[1, i] * f[1]) + (
            T_task_camera[2, i] * f[2]
        )


@jit
def fixture_force(
    T_task_camera, p_camera, vf_p, vf_v, started, vf_dt, vf_alpha,
    centre, basis, AE, AA, EE, starts, edges, cumulative, lengths,
    B, G_max, transition, summed, law, law_fn, params, f_camera,
):  # fmt: skip
    """:func:`fixture_law_row` of one tip (the live haptic tick), scratch allocated."""
    fixture_law_row(
        T_task_camera, p_camera, vf_p, vf_v, started, vf_dt, vf_alpha,
        centre, basis, AE, AA, EE, starts, edges, cumulative, lengths,
        B, G_max, transition, summed, law, law_fn, params, np.empty(8), np.empty(3), np.empty(3),
        np.empty(3), f_camera,
    )  # fmt: skip


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import, never in the 1 kHz loop, with the
    live field's argument types."""
    path = path_constants(ZERO_LAW_PATH)
    assert path is not None
    fixture_force(np.eye(4), np.zeros(3), np.zeros(3), np.zeros(3), True, 0.001, 0.5, *path,
                  1.0, 1.0, 0.0, True, VISCOUS, 0, NO_PARAMS.copy(), np.empty(3))  # fmt: skip


warm(_warm_up)
