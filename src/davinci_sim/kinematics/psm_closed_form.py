"""The PSM closed-form IK as one compiled kernel over rows (numba, through
:mod:`davinci_sim.kinematics.jit`): the live arm solves a batch of one, the study's batch engine
a batch of n trials, with the same code (:func:`~davinci_sim.kinematics.psm_ik.psm_ik_closed_form`
and :func:`~davinci_sim.kinematics.psm_ik.psm_ik_closed_form_batch`).

The derivation is in :mod:`davinci_sim.kinematics.psm_ik`'s docstring; frames and units are
its own (goals ``T_rcm_tip`` in the RCM frame, m; joints rad / m). Per row the kernel finds
every closed-form candidate, normalises it (dvrk.md 1.8: revolute joints wrapped, the roll
nearest the seed's), picks the in-limit one nearest the seed, checks it by FK and applies the
45 mm insertion rule (dvrk.md 1.7). What needs Python (the rare rows whose answer must be
polished by the reference DLS iteration, and the messages) is left to the callers, by
``status``. The pieces it shares with the other solvers are the same functions
(:func:`~davinci_sim.kinematics.jit.helper`): ``tool_origin``, ``rxrz`` and
``shaft_angle_pairs`` of :mod:`~davinci_sim.kinematics.rcm`, ``wrap_within``,
``nearest_turn`` and ``pose_errors`` of :mod:`~davinci_sim.kinematics.ik_base`, the FK
of :mod:`~davinci_sim.kinematics.fk_compiled`.
"""

from __future__ import annotations

import math

from davinci_sim.geometry.so3 import mat3_mul
from davinci_sim.kinematics.fk_compiled import tip_pose_row
from davinci_sim.kinematics.ik_base import (
    nearest_turn,
    pose_errors,
    wrap_angle,
    wrap_within,
)
from davinci_sim.kinematics.jit import helper, jit
from davinci_sim.kinematics.rcm import rxrz, shaft_angle_pairs, tool_origin
from davinci_sim.kinematics.scratch import local, local_bool

#: ``status`` of a row: the answer is final (``success`` says whether within limits).
SOLVED = 0
#: The goal is closer than 1 mm to the RCM: rejected, ``q`` is the seed (dvrk.md 1.8).
TOO_CLOSE = 1
#: No closed-form candidate (goal out of the workspace): ``q`` is the seed.
NO_SOLUTION = 2
#: The best candidate misses the goal by more than the tolerance (near-degenerate wrist):
#: ``q`` is that candidate, for the caller to polish with the reference iteration.
POLISH = 3

#: dvrk.md 1.8: goals closer than this to the RCM are rejected (m).
MIN_GOAL_DISTANCE_FROM_RCM = 0.001
#: dvrk.md 1.7 ``SafeDistanceFromRCM``: minimum RCM to shaft-end (frame 4) distance (m).
SAFE_DISTANCE_FROM_RCM = 0.045
#: Index of the roll joint and of the insertion (dvrk.md 1.2).
ROLL = 3
INSERTION = 2


@helper
def insertion_rule(q3: float, seed3: float, shaft0: float) -> float:
    """dvrk.md 1.8: the insertion (m) keeping the shaft end (frame 4, at ``q3 + shaft0`` on
    the shaft) ≥ 45 mm from the RCM; ``q3`` itself when it already does. A seed already
    shallower than allowed (e.g. while engaging the tool) is never pulled out further."""
    if abs(q3 + shaft0) >= SAFE_DISTANCE_FROM_RCM:
        return q3
    q_min = SAFE_DISTANCE_FROM_RCM - shaft0
    return max(q3, seed3) if seed3 < q_min else q_min


@helper
def normalise_row(q, seed, revolute, lim_lo, lim_hi) -> None:
    """dvrk.md 1.8, in place on ``q`` (6,): revolute joints wrapped (into their limits
    ``lim_lo``/``lim_hi``, slack included, where ±2π allows), then the roll put nearest the
    seed's roll mod 2π. Past the roll's limit (±260°) that turn is out of it, as the dVRK's
    is, and the arm clips it (``clip_jp`` after the IK): the tool stops turning there.
    (Another turn within the limit, 360° away, was taken here before: a servo stream that
    rolled the tool past its limit then asked for a whole turn back in one tick, and the
    arm faulted on its tracking error.)"""
    for j in range(q.shape[0]):
        if revolute[j]:
            q[j] = wrap_within(q[j], lim_lo[j], lim_hi[j])
    q[ROLL] = nearest_turn(q[ROLL], seed[ROLL])


@helper
def _wrist_root(A, B, C0, k, pp, a6, Px, Py, sgn):
    """One root θ of A sθ + B cθ = C0 + k·√(pp − 2a₆(Px cθ − Py sθ) + a₆²) (k = σ·cα₅,
    tiny), the branch of sign ``sgn`` of the acos, by fixed-point iteration: ``(found, θ,
    steps)``."""
    Rm = math.sqrt(A * A + B * B)
    if Rm < 1e-12:
        return False, 0.0, 0
    phi = math.atan2(A, B)
    th = 0.0
    found = False
    steps = 0
    c = C0 / Rm
    for _ in range(12):
        if abs(c) > 1.0:
            found = False
            break
        new = phi + sgn * math.acos(c)
        steps += 1
        if found and abs(new - th) <= 1e-15:
            th = new
            break
        th = new
        found = True
        # |o₅|² = |p|² − 2a₆ p·x₅ + a₆², p·x₅ = Px cθ − Py sθ
        rho2 = pp - 2.0 * a6 * (Px * math.cos(th) - Py * math.sin(th)) + a6 * a6
        rho = math.sqrt(max(0.0, rho2))
        c = (C0 + k * rho) / Rm
    return found, th, steps


@helper
def _complete_wrist(ca, sa, t0, R6, th1, th2, q3, th6, q) -> None:
    """Roll and wrist pitch from R₃ᵀR₅ = Rz(θ₄)·Rx(α₅)·Rz(θ₅); the joint vector into ``q``."""
    M6 = rxrz(ca[5], sa[5], th6)
    R5 = mat3_mul(R6, (M6[0], M6[3], M6[6], M6[1], M6[4], M6[7], M6[2], M6[5], M6[8]))
    R3 = mat3_mul(
        mat3_mul(rxrz(ca[0], sa[0], th1), rxrz(ca[1], sa[1], th2)), rxrz(ca[2], sa[2], t0[2])
    )
    # Only the entries 02, 12, 20, 21 of M = R₃ᵀR₅ are needed.
    M02 = R3[0] * R5[2] + R3[3] * R5[5] + R3[6] * R5[8]
    M12 = R3[1] * R5[2] + R3[4] * R5[5] + R3[7] * R5[8]
    M20 = R3[2] * R5[0] + R3[5] * R5[3] + R3[8] * R5[6]
    M21 = R3[2] * R5[1] + R3[5] * R5[4] + R3[8] * R5[7]
    s5 = sa[4]
    q[0] = th1 - t0[0]
    q[1] = th2 - t0[1]
    q[2] = q3
    q[3] = math.atan2(s5 * M02, -s5 * M12) - t0[3]
    q[4] = math.atan2(s5 * M20, s5 * M21) - t0[4]
    q[5] = th6 - t0[5]


@helper
def _row_errors(fk_links, fk_modified, fk_tool, fk_tool_is_identity, q, goal, F, J, frames):
    """Position and rotation error (m, rad) of FK(q) against the flat goal tuple."""
    tip_pose_row(fk_links, fk_modified, fk_tool, fk_tool_is_identity, q, F, J, False, frames)
    f = (
        F[0, 0], F[0, 1], F[0, 2], F[1, 0], F[1, 1], F[1, 2], F[2, 0], F[2, 1], F[2, 2],
        F[0, 3], F[1, 3], F[2, 3],
    )  # fmt: skip
    return pose_errors(f, goal)


@jit
def closed_form_rows(
    geometry, tool, revolute, lim_lo, lim_hi, fk_links, fk_modified, fk_tool, fk_identity,
    T, S, tolerance, q_out, success, status, info,
):  # fmt: skip
    """Row by row, the closed-form PSM IK of goal ``T[i]`` (4, 4) from seed ``S[i]`` (6,).

    ``geometry``: cos α (6), sin α (6), θ0 (6), shaft0, a₆, d₆, the yaw/pitch/insertion
    limits with slack (lo, hi each); ``tool``: the tooltip rotation transposed (9,
    row-major) and offset (3); ``revolute``, ``lim_lo``,
    ``lim_hi`` (6,): joint kinds and limits with slack; ``fk_*``: the chain packed for
    :func:`~davinci_sim.kinematics.fk_compiled.tip_pose_row`; ``tolerance``: position (m)
    and rotation (rad) acceptance. Writes ``q_out`` (n, 6), ``success`` (n,) (SOLVED rows:
    within limits), ``status`` (n,) and ``info`` (n, 5): wrist steps, position and rotation
    error of ``q_out``, the insertion before the 45 mm rule, whether the rule moved it.
    Elementwise: a row's bits do not depend on the batch.
    """
    ca, sa, t0 = geometry[0:6], geometry[6:12], geometry[12:18]
    shaft0, a6, d6 = geometry[18], geometry[19], geometry[20]
    shaft_lo = (geometry[21], geometry[23], geometry[25])
    shaft_hi = (geometry[22], geometry[24], geometry[26])
    R_tool_T = (tool[0], tool[1], tool[2], tool[3], tool[4], tool[5], tool[6], tool[7], tool[8])
    p_tool = (tool[9], tool[10], tool[11])
    cand = local(8, 4)  # (θ₁, θ₂, q₃, θ₆) per candidate
    inside = local_bool(8)
    q = local(6)
    best = local(6)
    F = local(4, 4)
    J = local(6, 0)
    frames = local(6, 12)
    roots = local(2)
    for r in range(T.shape[0]):
        seed = S[r]
        goal = (
            T[r, 0, 0], T[r, 0, 1], T[r, 0, 2], T[r, 1, 0], T[r, 1, 1], T[r, 1, 2],
            T[r, 2, 0], T[r, 2, 1], T[r, 2, 2], T[r, 0, 3], T[r, 1, 3], T[r, 2, 3],
        )  # fmt: skip
        info[r, 0] = 0.0
        info[r, 1] = math.nan  # errors: only for the candidate rows (SOLVED, POLISH)
        info[r, 2] = math.nan
        info[r, 3] = seed[INSERTION]
        info[r, 4] = 0.0
        success[r] = False
        d = math.sqrt(goal[9] ** 2 + goal[10] ** 2 + goal[11] ** 2)
        if d < MIN_GOAL_DISTANCE_FROM_RCM:
            status[r] = TOO_CLOSE
            q_out[r] = seed
            continue
        # -- candidates (θ₁, θ₂, q₃, θ₆); shaft branches outside the yaw, pitch or insertion
        # limits only count when no branch is within them, so that a failure still has a q
        R6, px, py, pz = tool_origin(goal, R_tool_T, p_tool)
        if d6 != 0.0:
            px, py, pz = px - d6 * R6[2], py - d6 * R6[5], pz - d6 * R6[8]
        # P = R₆ᵀp: the RCM→tip vector in the frame-6 axes.
        Px = R6[0] * px + R6[3] * py + R6[6] * pz
        Py = R6[1] * px + R6[4] * py + R6[7] * pz
        Pz = R6[2] * px + R6[5] * py + R6[8] * pz
        pp = px * px + py * py + pz * pz
        # σ = −1 (frame 4 behind the RCM) only exists with the tool inside the cannula.
        n_sigma = 2 if math.sqrt(pp) - a6 <= -shaft0 - shaft_lo[2] + 1e-9 else 1
        n = 0
        steps = 0
        for i_sigma in range(n_sigma):
            sigma = 1.0 if i_sigma == 0 else -1.0
            n_roots = 0
            for sgn in (1.0, -1.0):
                found, th, k = _wrist_root(
                    sa[5] * Px, sa[5] * Py, -ca[5] * Pz, sigma * ca[4], pp, a6, Px, Py, sgn
                )
                steps += k
                if found:
                    roots[n_roots] = th
                    n_roots += 1
            if n_roots == 0:  # degenerate (RCM on the wrist-yaw axis): keep the seed's yaw
                roots[0] = seed[5] + t0[5]
                n_roots = 1
            for i_root in range(n_roots):
                th6 = roots[i_root]
                c6, s6 = math.cos(th6), math.sin(th6)
                # o₅ = p − a₆·x₅ with x₅ = cθ₆·x₆ − sθ₆·y₆
                ox = px - a6 * (c6 * R6[0] - s6 * R6[1])
                oy = py - a6 * (c6 * R6[3] - s6 * R6[4])
                oz = pz - a6 * (c6 * R6[6] - s6 * R6[7])
                rho = math.sqrt(ox * ox + oy * oy + oz * oz)
                if rho == 0.0:
                    continue
                q3 = sigma * rho - shaft0
                m, th1a, th2a, th1b, th2b = shaft_angle_pairs(
                    ca, sa, sigma * ox / rho, sigma * oy / rho, sigma * oz / rho
                )
                for i_pair in range(m):
                    th1 = th1a if i_pair == 0 else th1b
                    th2 = th2a if i_pair == 0 else th2b
                    y, p = wrap_angle(th1 - t0[0]), wrap_angle(th2 - t0[1])
                    inside[n] = (
                        shaft_lo[0] <= y <= shaft_hi[0]
                        and shaft_lo[1] <= p <= shaft_hi[1]
                        and shaft_lo[2] <= q3 <= shaft_hi[2]
                    )
                    cand[n, 0], cand[n, 1], cand[n, 2], cand[n, 3] = th1, th2, q3, th6
                    n += 1
        info[r, 0] = steps
        if n == 0:
            status[r] = NO_SOLUTION
            q_out[r] = seed
            continue
        any_inside = False
        for c in range(n):
            any_inside = any_inside or inside[c]
        # -- the in-limit candidate nearest the seed (the first on a tie); the roll's limit
        # does not choose: its turn is the one nearest the seed's, which the arm clips
        have, best_out, best_d = False, True, math.inf
        for c in range(n):
            if any_inside and not inside[c]:
                continue
            _complete_wrist(ca, sa, t0, R6, cand[c, 0], cand[c, 1], cand[c, 2], cand[c, 3], q)
            normalise_row(q, seed, revolute, lim_lo, lim_hi)
            out = False
            d2 = 0.0
            for j in range(6):
                out = out or (j != ROLL and not (lim_lo[j] <= q[j] <= lim_hi[j]))
                d2 += (q[j] - seed[j]) ** 2
            # min() over (out of limits, distance): the first of the least
            if not have or (best_out and not out) or (out == best_out and d2 < best_d):
                have, best_out, best_d = True, out, d2
                best[:] = q
        q_out[r] = best
        # -- FK check, then the 45 mm insertion rule
        dp, dr = _row_errors(fk_links, fk_modified, fk_tool, fk_identity, best, goal, F, J, frames)
        info[r, 1], info[r, 2] = dp, dr
        if dp > tolerance[0] or dr > tolerance[1]:
            status[r] = POLISH
            continue
        status[r] = SOLVED
        q3 = best[INSERTION]
        new3 = insertion_rule(q3, seed[INSERTION], shaft0)
        info[r, 3] = q3
        if new3 != q3:
            q_out[r, INSERTION] = new3
            info[r, 4] = 1.0
            dp, dr = _row_errors(
                fk_links, fk_modified, fk_tool, fk_identity, q_out[r], goal, F, J, frames
            )
            info[r, 1], info[r, 2] = dp, dr
        ok = True
        for j in range(6):
            ok = ok and lim_lo[j] <= q_out[r, j] <= lim_hi[j]
        success[r] = ok
