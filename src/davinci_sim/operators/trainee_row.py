"""The synthetic trainee's step as one compiled call over its rows (numba only: imported where
:data:`davinci_sim.kinematics.jit.ENABLED`).

:func:`command_rows` is :meth:`~davinci_sim.operators.trainee.SyntheticTrainee.command`
after its checks and its noise draw: the co-contraction's step, perception through the
delay line, the reach and path starts, the minimum-jerk plans now and one delay ago
(:mod:`~davinci_sim.operators.plan`, the path's ``point_at``/``tangent_at``), the visual
correction, the motor noise and tremor filters and the equilibrium point's integration,
row by row on floats. The numpy operations are elementwise per trial, so each row's floats
come out of the same operations in the same order (a row's ``np.linalg.norm`` over axis 1
sums its three squares left to right, as :func:`_norm3` does): the same bits, alone or in
any batch (``tests/operators/test_trainee_row.py``). ``SyntheticTrainee``'s numpy step
stays the fallback and the oracle. The study's batch and the live trainee's hand both step
through it.
"""

from __future__ import annotations

import math

import numpy as np

from davinci_sim.kinematics.jit import helper, jit, warmed_up


@helper
def _norm3(x, y, z):
    """``np.linalg.norm`` of one row of three (its squares summed left to right)."""
    return math.sqrt(x * x + y * y + z * z)


@helper
def _minimum_jerk(u):
    """:func:`~davinci_sim.operators.plan.minimum_jerk` of one ``u`` (clipped to [0, 1]; a
    NaN stays NaN, as ``np.clip`` leaves it)."""
    if u < 0.0:
        u = 0.0
    elif u > 1.0:
        u = 1.0
    u2 = u * u
    w = 1.0 - u
    return u2 * u * (10.0 - 15.0 * u + 6.0 * u2), 30.0 * u2 * (w * w)


@helper
def plan_arc_row(knots, T, since):
    """The planned arc length (m) and speed (m/s) ``since`` s into a trial's strokes of
    durations ``T`` (S,) between the arc lengths ``knots`` (S + 1,): the ``s`` of
    :func:`~davinci_sim.operators.plan.path_plan`, before clipping to the path."""
    S = T.shape[0]
    count = 0
    end = T[0]
    for j in range(S):  # the strokes' ends (np.cumsum: summed in order)
        if j:
            end = end + T[j]
        if since >= end:
            count += 1
    k = min(count, S - 1)
    end = T[0]
    for j in range(1, k + 1):
        end = end + T[j]
    start = end - T[k]
    u = (since - start) / T[k]
    g, dg = _minimum_jerk(u)
    length = knots[k + 1] - knots[k]
    s = knots[k] + length * g
    speed = length * dg / T[k] if (u > 0.0 and u < 1.0) else 0.0
    return s, speed


@helper
def _path_plan_row(cum, seglen, starts, edges, knots, T, since, p_out, v_out):
    """:func:`~davinci_sim.operators.plan.path_plan` of one trial (its stroke durations
    ``T`` (S,), ``since`` s into the plan) into ``p_out``, ``v_out`` (3,): the path's point
    and tangent as ``Polyline.point_at``/``tangent_at`` find them (``cum`` its cumulative
    lengths, ``seglen``, ``starts``, ``edges`` its segments)."""
    s, speed = plan_arc_row(knots, T, since)
    # Polyline.point_at / tangent_at: s clipped to the path, its segment by searchsorted
    total = cum[cum.shape[0] - 1]
    if s < 0.0:
        s = 0.0
    elif s > total:
        s = total
    i = 0
    for m in range(cum.shape[0]):  # (searchsorted, side="right", minus one)
        if cum[m] <= s:
            i = m
    n_seg = seglen.shape[0]
    if i > n_seg - 1:
        i = n_seg - 1
    uu = (s - cum[i]) / seglen[i]
    for j in range(3):
        p_out[j] = starts[i, j] + uu * edges[i, j]
        v_out[j] = speed * (edges[i, j] / seglen[i])


@helper
def _plan_row(
    t, t_reach, reach_from, reach_time, p_start, t_follow, cum, seglen, starts, edges, knots,
    T, p_out, v_out,
):  # fmt: skip
    """``SyntheticTrainee.plan`` of one trial at ``t``: the straight reach to point 1, or the
    path's strokes once following; returns whether there is a plan (the tool seen)."""
    valid = t >= t_reach
    tt = t - t_reach if valid else 0.0
    # straight_plan(reach_from, p_start, reach_time, tt)
    u = tt / reach_time
    g, dg = _minimum_jerk(u)
    coef = dg / reach_time if (u > 0.0 and u < 1.0) else 0.0
    for j in range(3):
        d = p_start[j] - reach_from[j]
        p_out[j] = reach_from[j] + g * d
        v_out[j] = coef * d
    if t >= t_follow:
        _path_plan_row(cum, seglen, starts, edges, knots, T, t - t_follow, p_out, v_out)
    return valid


#: The arguments of :func:`command_rows` after ``k`` and ``t``, in order (the chunked
#: study passes them to :func:`command_row` as one tuple).
ARGS = (
    "dt", "scale", "start_tolerance", "min_reach_time", "p_start", "knots", "cum", "seglen",
    "starts", "edges", "y", "force", "feel", "stiffening", "co_contraction", "obs",
    "delay_steps", "t_reach", "reach_from", "reach_time", "speed", "t_follow", "reaction_time",
    "v_plan", "mass", "feedforward", "crossover", "durations", "white", "motor_ab", "motor",
    "noise_k", "tremor_a1", "tremor_a2", "tremor_norm", "tremor_x", "tremor_y1", "tremor_y2",
    "tremor_gain", "last_tremor", "x_eq", "v_eq",
)  # fmt: skip


@jit
def command_rows(
    k, t, dt, scale, start_tolerance, min_reach_time, p_start, knots, cum, seglen, starts,
    edges, y, force, feel, stiffening, co_contraction, obs, delay_steps, t_reach, reach_from,
    reach_time, speed, t_follow, reaction_time, v_plan, mass, feedforward, crossover,
    durations, white, motor_ab, motor, noise_k, tremor_a1, tremor_a2, tremor_norm, tremor_x,
    tremor_y1, tremor_y2, tremor_gain, last_tremor, x_eq, v_eq,
):  # fmt: skip
    """One step ``k`` (time ``t`` = k·dt, s) of every trainee row, in place.

    The arguments are :class:`~davinci_sim.operators.trainee.SyntheticTrainee`'s arrays
    (one row per trial) and constants: ``y`` (n, 3) the tool tips seen now (camera, m),
    ``force`` (n, 3) the MTM's force on the hands (HRSV, N), felt when ``feel``
    (``stiffening``: gain, threshold N, maximum, dt/τ); the path's plan constants
    (``p_start``, ``knots``, the polyline's ``cum``, ``seglen``, ``starts``, ``edges``);
    ``white`` (n, 6) this step's normals (tremor's three, then the motor noise's);
    ``motor_ab`` the motor filter's (a, b); the tremor's resonators (``tremor_a1``,
    ``tremor_a2``, ``tremor_norm`` its unit-variance gain, (n,); states ``tremor_x``,
    ``tremor_y1``, ``tremor_y2`` (2, n, 3)) and force gain ``tremor_gain`` (n,). Writes the
    state arrays and ``x_eq`` (n, 3), the equilibrium points (HRSV, m)."""
    scratch = np.empty((6, 3))
    args = (
        dt, scale, start_tolerance, min_reach_time, p_start, knots, cum, seglen, starts, edges,
        y, force, feel, stiffening, co_contraction, obs, delay_steps, t_reach, reach_from,
        reach_time, speed, t_follow, reaction_time, v_plan, mass, feedforward, crossover,
        durations, white, motor_ab, motor, noise_k, tremor_a1, tremor_a2, tremor_norm,
        tremor_x, tremor_y1, tremor_y2, tremor_gain, last_tremor, x_eq, v_eq,
    )  # fmt: skip
    for i in range(y.shape[0]):
        command_row(i, k, t, white[i], args, scratch)


@helper
def command_row(i, k, t, white_i, args, scratch):
    """:func:`command_rows` of row ``i`` (``args``: its arguments after ``t``, in
    :data:`ARGS`' order; ``white_i`` (6,) the row's normals of this step, in place of
    ``white``'s row; ``scratch`` (6, 3))."""
    (dt, scale, start_tolerance, min_reach_time, p_start, knots, cum, seglen, starts, edges,
     y, force, feel, stiffening, co_contraction, obs, delay_steps, t_reach, reach_from,
     reach_time, speed, t_follow, reaction_time, v_plan, mass, feedforward, crossover,
     durations, _, motor_ab, motor, noise_k, tremor_a1, tremor_a2, tremor_norm, tremor_x,
     tremor_y1, tremor_y2, tremor_gain, last_tremor, x_eq, v_eq) = args  # fmt: skip
    size = obs.shape[1]
    p_now, v_now, p_then, v_then, u, ys = (scratch[0], scratch[1], scratch[2], scratch[3],
                                           scratch[4], scratch[5])  # fmt: skip
    a, b = motor_ab[0], motor_ab[1]
    if feel:  # SyntheticTrainee.feel
        excess = _norm3(force[i, 0], force[i, 1], force[i, 2]) - stiffening[1]
        target = min(stiffening[0] * max(excess, 0.0), stiffening[2])
        c = co_contraction[i]
        co_contraction[i] = c + (target - c) * stiffening[3]
    for j in range(3):
        obs[i, k % size, j] = y[i, j]
    d = delay_steps[i]
    seen = k >= d
    slot = (k - d) % size
    ys0, ys1, ys2 = obs[i, slot, 0], obs[i, slot, 1], obs[i, slot, 2]
    ys[0], ys[1], ys[2] = ys0, ys1, ys2
    t_seen = t - d * dt
    if seen and math.isinf(t_reach[i]):  # first sight: reach for point 1
        t_reach[i] = t
        reach_from[i, 0], reach_from[i, 1], reach_from[i, 2] = ys0, ys1, ys2
        distance = _norm3(p_start[0] - ys0, p_start[1] - ys1, p_start[2] - ys2)
        reach_time[i] = max(min_reach_time, distance / speed[i])
    if (
        seen
        and math.isinf(t_follow[i])
        and t >= t_reach[i] + reach_time[i]
        and _norm3(ys0 - p_start[0], ys1 - p_start[1], ys2 - p_start[2]) <= 0.5 * start_tolerance
    ):
        t_follow[i] = t + reaction_time[i]
    T = durations[i]
    valid_now = _plan_row(t, t_reach[i], reach_from[i], reach_time[i], p_start, t_follow[i],
                          cum, seglen, starts, edges, knots, T, p_now, v_now)  # fmt: skip
    valid_then = _plan_row(t_seen, t_reach[i], reach_from[i], reach_time[i], p_start,
                           t_follow[i], cum, seglen, starts, edges, knots, T, p_then,
                           v_then)  # fmt: skip
    correct = seen and valid_then
    for j in range(3):
        v = v_now[j] if valid_now else 0.0
        a_plan = (v - v_plan[i, j]) / (scale * dt)
        v_plan[i, j] = v
        feedforward[i, j] = mass[i] * a_plan
        error = p_then[j] - ys[j] if correct else 0.0
        u[j] = (v + crossover[i] * error) / scale
    size_u = noise_k[i] * _norm3(u[0], u[1], u[2])
    for j in range(3):
        n_motor = a * motor[i, j] + b * white_i[3 + j]
        motor[i, j] = n_motor
        uj = u[j] + size_u * n_motor
        # Tremor: two resonator sections (noise.Tremor.step), shifted one sample.
        w = white_i[j]
        x2, y1_0, y1_1 = tremor_x[1, i, j], tremor_y1[0, i, j], tremor_y1[1, i, j]
        y1 = tremor_a1[i] * y1_0 + tremor_a2[i] * y1_1 + w - x2
        y2 = tremor_a1[i] * tremor_y2[0, i, j] + tremor_a2[i] * tremor_y2[1, i, j] + y1 - y1_1
        tremor_x[1, i, j], tremor_x[0, i, j] = tremor_x[0, i, j], w
        tremor_y1[1, i, j], tremor_y1[0, i, j] = y1_0, y1
        tremor_y2[1, i, j], tremor_y2[0, i, j] = tremor_y2[0, i, j], y2
        last_tremor[i, j] = tremor_gain[i] * (tremor_norm[i] * y2)
        x_eq[i, j] = x_eq[i, j] + uj * dt
        v_eq[i, j] = uj


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import with the one signature the trainee
    calls it with: never inside a 1 kHz loop."""
    f1, f2, f3 = np.zeros(1), np.zeros((1, 3)), np.zeros((2, 1, 3))
    path = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]])
    command_rows(
        0, 0.0, 0.001, 0.5, 0.002, 0.3, np.zeros(3), np.array([0.0, 0.01]),
        np.array([0.0, 0.01]), np.array([0.01]), path[:1], np.diff(path, axis=0), f2, f2,
        False, np.zeros(4), np.zeros(1), np.zeros((1, 2, 3)), np.ones(1, dtype=np.int64),
        np.full(1, np.inf), np.zeros((1, 3)), np.ones(1), np.ones(1), np.full(1, np.inf),
        np.ones(1), np.zeros((1, 3)), np.ones(1), np.zeros((1, 3)), np.ones(1), np.ones((1, 1)),
        np.zeros((1, 6)), np.array([0.9, 0.1]), np.zeros((1, 3)), f1, f1, f1, np.ones(1),
        f3, f3.copy(), f3.copy(), f1, np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3)),
    )  # fmt: skip


READY = warmed_up(_warm_up, "the trainee's compiled step failed to compile: numpy steps it")
