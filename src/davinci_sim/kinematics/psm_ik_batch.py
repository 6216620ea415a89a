"""Batched closed-form PSM inverse kinematics: :func:`psm_ik_closed_form` for n arms at once.

Frames and units are those of the scalar solver (:mod:`davinci_sim.kinematics.psm_ik`): each
goal ``T_rcm_tip[i]`` is the tool-tip pose in the RCM frame (the PSM chain base, dvrk.md 1.2),
positions in m; the seeds and answers are joint vectors (yaw, pitch rad, insertion m, roll,
wrist pitch, wrist yaw rad). The derivation is the one in the scalar module docstring.

Row i of the answer equals ``psm_ik_closed_form(chain, T_rcm_tip[i], q_seed[i])`` (``q`` to
rounding, ~1e-15; ``success`` exactly), including the dVRK post-processing (dvrk.md 1.8):
revolute joints wrapped, roll nearest the seed's roll mod 2π within its limits, the in-limit
candidate nearest the seed, the FK check, the 1 mm RCM rule and the 45 mm insertion rule
(dvrk.md 1.7). How:

* the common case is vectorised over rows: σ = +1 shaft branch (tool outside the cannula),
  both wrist roots θ₆ by the fixed-point iteration run for a fixed number of steps, both θ₂
  roots of the shaft direction, so 4 candidates per row, then normalisation, choice, one
  batched FK check and the 45 mm insertion rule (a clamp, exact in numpy too);
* every row where that path is not certain to reproduce the scalar answer falls back to the
  scalar solver: goal within 1 mm of the RCM, σ = −1 possible (the wrist-yaw point within
  a₆ + 15.6 mm of the RCM, i.e. the tool inside the cannula, insertion below ~35 mm), a
  wrist or shaft equation near or past tangency (missing or ill-conditioned root, degenerate
  wrist), a candidate, choice or insertion-rule decision within rounding of its boundary
  (limit, wrap point, half turn, tie), an FK error not well inside the tolerance (the scalar
  solver would polish it by DLS or report it), or any non-finite intermediate.

In a uniform sample of the joint space the fallback rows are the insertions below ~35 mm
(~14 % of the 0-240 mm range); with insertion ≥ 35 mm none were seen, so the batch costs a
few µs per row (see ``benchmarks/bench_kinematics.py``) and equals the scalar solver exactly.

Plain numpy on arrays of shape (n,) or (4, n): at n ≈ 200 the per-call overhead of numpy is
paid once per batch instead of once per arm.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from davinci_sim.kinematics.chain import DHChain
from davinci_sim.kinematics.fk import forward_kinematics
from davinci_sim.kinematics.ik_base import (
    LIMIT_SLACK,
    POSITION_TOLERANCE,
    ROTATION_TOLERANCE,
    TWO_PI,
)
from davinci_sim.kinematics.psm_ik import (
    INSERTION,
    MIN_GOAL_DISTANCE_FROM_RCM,
    ROLL,
    SAFE_DISTANCE_FROM_RCM,
    PSMGeometry,
    psm_geometry,
    psm_ik_closed_form,
)

#: Fixed-point steps of the wrist equation. It contracts by ~cα₅·a₆/R ≈ 1e-6 per step
#: (psm_ik module docstring), so 4 steps reach machine precision for any R above ~1 mm.
WRIST_STEPS = 4
#: Distance (dimensionless or rad/m) from a decision boundary (limit, wrap point, tie, root
#: tangency) below which rounding could make the batch and the scalar solver disagree; such
#: rows go to the scalar solver. Rounding differences are ~1e-15, so this is generous.
_MARGIN = 1e-10
#: Cosines this close to ±1 make acos ill-conditioned (error ~eps/√(1−|c|)): fall back.
_COS_MARGIN = 1e-6


class BatchIKResult(NamedTuple):
    """Answers of :func:`psm_ik_closed_form_batch`, row i for goal i."""

    q: np.ndarray
    """Joint values, rad (revolute) / m (insertion), shape ``(n, 6)``."""
    success: np.ndarray
    """``IKResult.success`` of each row, bool, shape ``(n,)``."""


def _check_inputs(chain: DHChain, T_rcm_tip, q_seed) -> tuple[np.ndarray, np.ndarray]:
    T = np.asarray(T_rcm_tip, dtype=float)
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise ValueError(f"T_rcm_tip must have shape (n, 4, 4), got {T.shape}")
    S = np.asarray(q_seed, dtype=float)
    if S.shape != (T.shape[0], chain.dof):
        raise ValueError(
            f"{chain.name}: q_seed must have shape ({T.shape[0]}, {chain.dof}) to match "
            f"T_rcm_tip, got {S.shape}"
        )
    if not np.all(np.isfinite(T)):
        bad = np.flatnonzero(~np.all(np.isfinite(T), axis=(1, 2)))
        raise ValueError(f"T_rcm_tip must be finite; non-finite rows {bad[:10].tolist()}")
    if not np.all(np.isfinite(S)):
        bad = np.flatnonzero(~np.all(np.isfinite(S), axis=1))
        raise ValueError(
            f"{chain.name}: q_seed must be finite; non-finite rows {bad[:10].tolist()}"
        )
    return T, S


@dataclass(frozen=True)
class _Limits:
    """Joint limits of a chain as arrays (with the IK slack), cached per chain."""

    revolute: np.ndarray
    """Indices of the revolute joints."""
    lo: np.ndarray
    hi: np.ndarray
    """qmin − slack, qmax + slack, shape (dof,)."""
    mid: np.ndarray
    half: np.ndarray
    """(hi + lo)/2, (hi − lo)/2: x within limits ⇔ |x − mid| ≤ half (one comparison)."""
    wide: tuple[int, ...]
    """Revolute joints where ``wrap_revolute`` may shift a wrapped value by ±2π."""


_LIMITS: weakref.WeakKeyDictionary[DHChain, _Limits] = weakref.WeakKeyDictionary()


def _limits(chain: DHChain) -> _Limits:
    lim = _LIMITS.get(chain)
    if lim is None:
        lo = np.array([j.qmin - LIMIT_SLACK for j in chain.joints])
        hi = np.array([j.qmax + LIMIT_SLACK for j in chain.joints])
        rev = [i for i, j in enumerate(chain.joints) if j.is_revolute]
        # A shift is possible only if a wrapped value can be out of the limits and its ±2π
        # image in them (not for the roll: ±260° contains all of (−π, π]).
        wide = tuple(
            i
            for i in rev
            if (lo[i] < -math.pi or hi[i] > math.pi) and (lo[i] > -math.pi or hi[i] < math.pi)
        )
        lim = _LIMITS[chain] = _Limits(
            np.array(rev), lo, hi, 0.5 * (hi + lo), 0.5 * (hi - lo), wide
        )
    return lim


def _wrap(x: np.ndarray) -> np.ndarray:
    """``wrap_angle`` elementwise: to (−π, π] (to rounding: float ``%`` is slow in numpy)."""
    return x + TWO_PI * np.floor((math.pi - x) / TWO_PI)


def _at_wrap_point(w: np.ndarray) -> np.ndarray:
    """Wrapped angles within rounding of ±π, where ``wrap_angle`` jumps by 2π."""
    return math.pi - np.abs(w) <= _MARGIN


def _near_limit(x: np.ndarray, mid, half) -> np.ndarray:
    """``x`` within rounding of lo = mid − half or hi = mid + half."""
    return np.abs(np.abs(x - mid) - half) <= _MARGIN


def _vectorised(
    chain: DHChain,
    g: PSMGeometry,
    T: np.ndarray,
    S: np.ndarray,
    position_tolerance: float,
    rotation_tolerance: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The common case for all rows: (q (n, 6), success (n,), sure (n,)).

    Rows with ``sure`` False must be recomputed by the scalar solver; their q and success
    here are meaningless. Candidate arrays are (4, n): θ₆ root 0 with +s₂, with −s₂, then
    θ₆ root 1 likewise, the order of the scalar ``_candidates`` (ties resolve alike).
    """
    n = T.shape[0]
    ca, sa, t0, a6 = g.ca, g.sa, g.theta0, g.a6
    unsure = np.zeros(n, dtype=bool)
    with np.errstate(all="ignore"):  # NaNs are caught by the finiteness checks below
        # dvrk.md 1.8: goals closer than 1 mm to the RCM are rejected with q = seed.
        p_goal = T[:, :3, 3]
        unsure |= np.sqrt(np.sum(p_goal * p_goal, axis=1)) < MIN_GOAL_DISTANCE_FROM_RCM + _MARGIN

        # R₆ = R_goal·R_toolᵀ and the wrist-yaw origin p (scalar ``_candidates``).
        R6 = T[:, :3, :3] @ np.array(g.R_tool_T).reshape(3, 3)
        p = p_goal - R6 @ np.array(g.p_tool)
        if g.d6 != 0.0:
            p = p - g.d6 * R6[:, :, 2]
        x6, y6 = R6[:, :, 0], R6[:, :, 1]
        Px, Py, Pz = np.einsum("nij,ni->jn", R6, p)  # P = R₆ᵀp
        pp = np.sum(p * p, axis=1)
        # σ = −1 (frame 4 behind the RCM) only exists with the tool inside the cannula: the
        # scalar solver handles those rows.
        unsure |= np.sqrt(pp) - a6 <= -g.shaft0 - g.shaft_limits[2][0] + 1e-9 + _MARGIN

        # Wrist roots (σ = +1): A sθ + B cθ = C0 + k·|o₅(θ)|, both signs of the acos.
        A, B, C0, k = sa[5] * Px, sa[5] * Py, -ca[5] * Pz, ca[4]
        Rm = np.hypot(A, B)
        unsure |= Rm < _COS_MARGIN  # degenerate wrist (RCM on the wrist-yaw axis)
        phi = np.arctan2(A, B)
        sgn = np.array([[1.0], [-1.0]])
        c = np.broadcast_to(C0 / Rm, (2, n))
        c_max = np.abs(c)
        for _ in range(WRIST_STEPS):
            th6 = phi + sgn * np.arccos(c)
            c6, s6 = np.cos(th6), np.sin(th6)
            # |o₅|² = |p|² − 2a₆ p·x₅ + a₆², p·x₅ = Px cθ − Py sθ
            rho2 = pp - 2.0 * a6 * (Px * c6 - Py * s6) + a6 * a6
            c = (C0 + k * np.sqrt(np.maximum(0.0, rho2))) / Rm
            c_max = np.fmax(c_max, np.abs(c))
        # Past tangency the scalar loses a root; near it acos is ill-conditioned.
        unsure |= ~np.all(c_max <= 1.0 - _COS_MARGIN, axis=0)

        # o₅ = p − a₆·x₅, x₅ = cθ₆·x₆ − sθ₆·y₆: the shaft direction z₃ = o₅/|o₅|, (2, n, 3).
        o5 = p - a6 * (c6[..., None] * x6 - s6[..., None] * y6)
        rho = np.sqrt(np.sum(o5 * o5, axis=2))
        unsure |= np.any(rho < _COS_MARGIN, axis=0)
        z3 = o5 / rho[..., None]

        # Shaft angles (rcm.shaft_angles): the z row fixes cos θ₂ (two roots), x-y give θ₁.
        vy, vz = -sa[2], ca[2]
        wx = z3[..., 0]
        wy = ca[0] * z3[..., 1] + sa[0] * z3[..., 2]
        wz = -sa[0] * z3[..., 1] + ca[0] * z3[..., 2]
        c2 = (wz - ca[1] * vz) / (sa[1] * vy)
        unsure |= ~np.all(np.abs(c2) <= 1.0 - _COS_MARGIN, axis=0)
        unsure |= np.any(wx * wx + wy * wy < _COS_MARGIN**2, axis=0)  # yaw undetermined
        s2 = np.sqrt(np.maximum(0.0, 1.0 - c2 * c2))
        two = [0, 0, 1, 1]
        s = s2[two] * np.array([[1.0], [-1.0], [1.0], [-1.0]])
        c2 = c2[two]
        th1 = np.arctan2(wy, wx)[two] - np.arctan2(ca[1] * vy * c2 - sa[1] * vz, -vy * s)
        th2 = np.arctan2(s, c2)
        th6, c6, s6 = th6[two], c6[two], s6[two]
        q3 = rho[two] - g.shaft0

        # Roll and wrist pitch from M = R₃ᵀR₅ = Rz(θ₄)·Rx(α₅)·Rz(θ₅) (scalar
        # ``_complete_wrist``); only M₀₂, M₁₂, M₂₀, M₂₁ are needed, i.e. columns 0-2 of R₃
        # and of R₅ = R₆·(Rx(α₆)Rz(θ₆))ᵀ, whose columns are R₆ times the rows of Rx(α₆)Rz(θ₆).
        r6x, r6y, r6z = (R6[None, :, :, j] for j in range(3))  # (1, n, 3)
        c6_, s6_ = c6[..., None], s6[..., None]
        r5x = r6x * c6_ - r6y * s6_
        r5y = (r6x * s6_ + r6y * c6_) * ca[5] - r6z * sa[5]
        r5z = (r6x * s6_ + r6y * c6_) * sa[5] + r6z * ca[5]
        # R₃ = Rx(α₁)Rz(θ₁)·G, G = Rx(α₂)Rz(θ₂)Rx(α₃)Rz(θ₃⁰), written out: at this size a
        # batched 3x3 matmul costs more than the products.
        ct1, st1, ct2, st2 = np.cos(th1), np.sin(th1), np.cos(th2), np.sin(th2)
        ct3, st3 = math.cos(t0[2]), math.sin(t0[2])
        g0 = (ct2, st2 * ca[1], st2 * sa[1])  # columns of Rx(α₂)Rz(θ₂)Rx(α₃)
        g1 = (
            -st2 * ca[2],
            ct2 * ca[1] * ca[2] - sa[1] * sa[2],
            ct2 * sa[1] * ca[2] + ca[1] * sa[2],
        )
        g2 = (
            st2 * sa[2],
            -ct2 * ca[1] * sa[2] - sa[1] * ca[2],
            -ct2 * sa[1] * sa[2] + ca[1] * ca[2],
        )
        if ct3 != 1.0:
            g0, g1 = (
                tuple(u * ct3 + v * st3 for u, v in zip(g0, g1, strict=True)),
                tuple(v * ct3 - u * st3 for u, v in zip(g0, g1, strict=True)),
            )

        def r3col(u):  # Rx(α₁)Rz(θ₁)·u
            return (
                ct1 * u[0] - st1 * u[1],
                (st1 * u[0] + ct1 * u[1]) * ca[0] - sa[0] * u[2],
                (st1 * u[0] + ct1 * u[1]) * sa[0] + ca[0] * u[2],
            )

        def dot(u, v):
            return u[0] * v[..., 0] + u[1] * v[..., 1] + u[2] * v[..., 2]

        r3x, r3y, r3z = r3col(g0), r3col(g1), r3col(g2)
        M02, M12 = dot(r3x, r5z), dot(r3y, r5z)
        M20, M21 = dot(r3z, r5x), dot(r3z, r5y)
        s5 = sa[4]
        th4 = np.arctan2(s5 * M02, -s5 * M12)
        th5 = np.arctan2(s5 * M20, s5 * M21)
        # Joint-major layout (dof, 4, n): per-joint slices and reductions over joints are
        # then contiguous elementwise operations.
        Q = np.stack([th1 - t0[0], th2 - t0[1], q3, th4 - t0[3], th5 - t0[4], th6 - t0[5]])
        unsure |= ~np.isfinite(Q.sum(axis=(0, 1)))

        # dvrk.md 1.8 normalisation (scalar ``_normalise``), and which candidates have yaw,
        # pitch, insertion within limits (scalar ``inside``): the others compete only when a
        # row has none.
        lim = _limits(chain)
        Q, inside, within, near = _normalise(lim, Q, S)
        unsure |= near
        eligible = inside | ~np.any(inside, axis=0)

        # Choice (scalar ``_nearest``): within limits first, then nearest the seed; the first
        # candidate on a tie. Near-ties go to the scalar solver.
        d = Q - S.T[:, None, :]
        d2 = np.sum(d * d, axis=0)
        best_class = np.any(eligible & within, axis=0)
        d2 = np.where(eligible & (within | ~best_class), d2, np.inf)
        pick = np.argmin(d2, axis=0)
        rows = np.arange(n)
        best = d2[pick, rows]
        d2[pick, rows] = np.inf
        unsure |= np.min(d2, axis=0) - best <= _MARGIN * (1.0 + best)
        q = Q[:, pick, rows].T.copy()
        success = within[pick, rows]

        # FK check of the chosen q, before the insertion rule (scalar ``_finish``); anything
        # not well inside the tolerance is for the scalar solver (which polishes it by DLS or
        # reports the error).
        F = forward_kinematics(chain, q)
        dp = F[:, :3, 3] - p_goal
        dp = np.sqrt(np.sum(dp * dp, axis=1))
        E = np.matmul(F[:, :3, :3].transpose(0, 2, 1), T[:, :3, :3])  # RᵀR_goal
        sn = 0.5 * np.sqrt(
            (E[:, 2, 1] - E[:, 1, 2]) ** 2
            + (E[:, 0, 2] - E[:, 2, 0]) ** 2
            + (E[:, 1, 0] - E[:, 0, 1]) ** 2
        )
        dr = np.arctan2(sn, 0.5 * (E[:, 0, 0] + E[:, 1, 1] + E[:, 2, 2] - 1.0))
        unsure |= ~(dp <= 0.5 * position_tolerance) | ~(dr <= 0.5 * rotation_tolerance)

        # dvrk.md 1.7/1.8 insertion rule (scalar ``_insertion_safety``): the shaft end
        # (frame 4, at q₃ + shaft0 > 0 on this σ = +1 branch) stays ≥ 45 mm from the RCM;
        # when the seed is already shallower, never pull out further. An adjusted answer
        # keeps its success if within limits (the pose error is then on purpose).
        q_min = SAFE_DISTANCE_FROM_RCM - g.shaft0
        q3, seed3 = q[:, INSERTION], S[:, INSERTION]
        shallow = q3 + g.shaft0 < SAFE_DISTANCE_FROM_RCM
        unsure |= np.abs(q3 + g.shaft0 - SAFE_DISTANCE_FROM_RCM) <= _MARGIN
        unsure |= shallow & (np.abs(seed3 - q_min) <= _MARGIN)
        new3 = np.where(seed3 < q_min, np.maximum(q3, seed3), q_min)
        q[:, INSERTION] = np.where(shallow, new3, q3)
        # ``within`` also tested the unadjusted insertion; on σ = +1 it is > 15.6 mm, within
        # its limits, so only the adjusted value can change the verdict.
        success &= np.abs(q[:, INSERTION] - lim.mid[INSERTION]) <= lim.half[INSERTION]
        unsure |= _near_limit(q[:, INSERTION], lim.mid[INSERTION], lim.half[INSERTION])
    return q, success, ~unsure


def _normalise(
    lim: _Limits, Q: np.ndarray, S: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Scalar ``_normalise`` on candidates Q (dof, k, n), with the limit tests of each.

    dvrk.md 1.8: revolute joints wrapped to (−π, π] (moved ±2π into the limits where needed),
    then the roll put nearest the seed's roll mod 2π, preferring a turn within the limits
    (``nearest_turn_within``).

    Returns the normalised candidates; ``inside`` (k, n): yaw, pitch and insertion within
    limits before any shift (the scalar ``_candidates`` test); ``within`` (k, n): all joints
    within limits after normalisation (``within_limits``); ``near`` (n,): rows where one of
    these decisions is within rounding of its boundary.
    """
    mid, half = lim.mid[:, None, None], lim.half[:, None, None]
    rev = lim.revolute
    W = Q.copy()
    W[rev] = _wrap(Q[rev])
    near = np.any(_at_wrap_point(W[rev]), axis=0)
    # distance to the nearest limit, positive inside
    margin = half - np.abs(W - mid)
    inside = np.min(margin[:3], axis=0) >= 0.0
    near |= np.min(np.abs(margin[:3]), axis=0) <= _MARGIN
    for i in lim.wide:
        x, lo, hi = W[i], lim.lo[i], lim.hi[i]
        out = (x < lo) | (x > hi)
        down = out & (lo <= x - TWO_PI) & (x - TWO_PI <= hi)
        up = out & ~down & (lo <= x + TWO_PI) & (x + TWO_PI <= hi)
        for y in (x - TWO_PI, x, x + TWO_PI):
            near |= _near_limit(y, lim.mid[i], lim.half[i])
        W[i] = np.where(down, x - TWO_PI, np.where(up, x + TWO_PI, x))
    # nearest_turn_within(x, seed roll, qmin, qmax), which adds LIMIT_SLACK itself: its
    # bounds are those of ``lim``. round() is half-to-even in Python and numpy alike.
    x, ref, m, h = W[ROLL], S[:, ROLL], lim.mid[ROLL], lim.half[ROLL]
    r = (ref - x) / TWO_PI
    near |= np.abs(r - np.floor(r) - 0.5) <= _MARGIN
    base = x + TWO_PI * np.round(r)
    minus, plus = base - TWO_PI, base + TWO_PI
    ok_b, ok_m, ok_p = (np.abs(y - m) <= h for y in (base, minus, plus))
    for y in (base, minus, plus):
        near |= _near_limit(y, m, h)
    # min over the in-limit turns by |y − ref|, base − 2π first on a tie
    dm, dp = np.abs(minus - ref), np.abs(plus - ref)
    take_p = ok_p & (~ok_m | (dp < dm))
    near |= ok_m & ok_p & (np.abs(dp - dm) <= _MARGIN)
    W[ROLL] = np.where(ok_b, base, np.where(take_p, plus, np.where(ok_m, minus, base)))
    for i in (*lim.wide, ROLL):  # the joints changed since ``margin`` was computed
        margin[i] = lim.half[i] - np.abs(W[i] - lim.mid[i])
    within = np.min(margin, axis=0) >= 0.0
    near |= np.min(np.abs(margin), axis=0) <= _MARGIN
    return W, inside, within, np.any(near, axis=0)


def psm_ik_closed_form_batch(
    chain: DHChain,
    T_rcm_tip,
    q_seed,
    *,
    position_tolerance: float = POSITION_TOLERANCE,
    rotation_tolerance: float = ROTATION_TOLERANCE,
) -> BatchIKResult:
    """:func:`~davinci_sim.kinematics.psm_ik.psm_ik_closed_form` for n goals at once.

    Args:
        chain: a PSM chain (yaw, pitch, insertion, roll, wrist pitch, wrist yaw + tooltip).
        T_rcm_tip: goal poses of the tool tip in the RCM frame, (n, 4, 4), m.
        q_seed: current joints of each arm, (n, 6), rad / m.
        position_tolerance, rotation_tolerance: acceptance of the FK check (m, rad).

    Returns:
        BatchIKResult; row i equals the scalar solver's ``q`` and ``success`` for row i.

    Raises:
        ValueError: on badly shaped or non-finite goals or seeds, or a non-PSM chain.
    """
    g = psm_geometry(chain)
    T, S = _check_inputs(chain, T_rcm_tip, q_seed)
    n = T.shape[0]
    if n == 0:
        return BatchIKResult(q=np.empty((0, chain.dof)), success=np.empty(0, dtype=bool))
    q, success, sure = _vectorised(chain, g, T, S, position_tolerance, rotation_tolerance)
    for i in np.flatnonzero(~sure):
        r = psm_ik_closed_form(
            chain,
            T[i],
            S[i],
            position_tolerance=position_tolerance,
            rotation_tolerance=rotation_tolerance,
        )
        q[i], success[i] = r.q, r.success
    return BatchIKResult(q=q, success=success)


def fallback_fraction(
    chain: DHChain,
    T_rcm_tip,
    q_seed,
    *,
    position_tolerance: float = POSITION_TOLERANCE,
    rotation_tolerance: float = ROTATION_TOLERANCE,
) -> float:
    """Fraction of rows :func:`psm_ik_closed_form_batch` would hand to the scalar solver."""
    T, S = _check_inputs(chain, T_rcm_tip, q_seed)
    if T.shape[0] == 0:
        return 0.0
    _, _, sure = _vectorised(
        chain, psm_geometry(chain), T, S, position_tolerance, rotation_tolerance
    )
    return float(np.mean(~sure))


__all__ = ["BatchIKResult", "fallback_fraction", "psm_ik_closed_form_batch"]
