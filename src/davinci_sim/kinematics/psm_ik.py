"""PSM inverse kinematics: the dVRK reference (generic DLS) and an exact closed form.

Both take the goal ``T_rcm_tip`` in the RCM frame (the PSM chain base, dvrk.md 1.2) and the
current joints as seed, and apply the dVRK PSM post-processing (dvrk.md 1.8): goals closer
than 1 mm to the RCM are rejected, the roll joint is put nearest the current roll mod 2π (the
nearest turn within the ±260° limits when the nearest one is not), and the shaft end (frame 4)
is kept at least 45 mm from the RCM (dvrk.md 1.7); see ``IKResult.adjusted``.

Closed form (derivation, frames i = modified-DH frames of the chain, θ_i = q_i + offsets):

* Frames 1-3 share the RCM as origin; frame 4 (and 5) sits on the shaft axis z₃ at signed
  distance L = q₃ + d₃ + offset₃ + d₄ (−0.0156 + q₃ for the Classic PSM). The tool point is
  o₆ = o₅ + a₆·x₅ (+ d₆·z₆), a₆ = 0.0091 m, and x₅ ⟂ z₆.
* From the goal, R₆ = R_goal·R_toolᵀ is known. Since R₆ = R₅·Rx(α₆)·Rz(θ₆):
  x₅ = cθ₆·x₆ − sθ₆·y₆ and z₅ = sα₆(sθ₆·x₆ + cθ₆·y₆) + cα₆·z₆, both functions of θ₆ only.
* The wrist-pitch point o₅ = p − a₆·x₅(θ₆) lies on the shaft, z₃ = σ·o₅/|o₅| (σ = sign L), and
  the joint-5 twist requires z₃·z₅ = cα₅. With x₅ ⟂ z₅ this reads, with P = R₆ᵀp,
  sα₆(P_x sθ₆ + P_y cθ₆) = −cα₆ P_z + σ cα₅ |o₅(θ₆)|, i.e. R cos(θ₆ − φ) = C: two roots.
  For exact right angles cα₅ = 0 and this is closed form; the dVRK JSON alphas are ±1.5708,
  3.7e-6 rad off ±π/2, so the small |o₅| term is resolved by a fixed-point iteration that
  contracts by ~cα₅·a₆/R per step (2-3 steps to machine precision).
* z₃ gives θ₁, θ₂ exactly for any twists: z₃ = Rx(α₁)Rz(θ₁)Rx(α₂)Rz(θ₂)·Rx(α₃)ẑ; the z row
  fixes cos θ₂ (two roots), the x-y rows then fix θ₁. q₃ = σ|o₅| − (d₃ + offset₃ + d₄).
* R₃ᵀR₅ = Rz(θ₄)·Rx(α₅)·Rz(θ₅) gives θ₄ (roll) and θ₅ (wrist pitch) by atan2.

Up to 2 (θ₆) × 2 (θ₂) × σ candidates; the one within joint limits nearest the seed wins.
Each answer is checked by FK. The closed form is one compiled kernel over rows
(:mod:`~davinci_sim.kinematics.psm_closed_form`): :func:`psm_ik_closed_form` solves a batch of one
(the live arm), :func:`psm_ik_closed_form_batch` a batch of n (the study's trials). The one
degenerate geometry (RCM on the wrist-yaw axis, where θ₆
is undetermined) needs a wrist pitch near ±90°, outside the ±80° limits; should it spoil an
answer anyway, DLS steps polish it (counted in ``iterations``) and the result is rechecked.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from davinci_sim.kinematics import fk
from davinci_sim.kinematics.arms import load_arm
from davinci_sim.kinematics.chain import DHChain
from davinci_sim.kinematics.dls import dls_solve
from davinci_sim.kinematics.fk import fk_tuple
from davinci_sim.kinematics.ik_base import (
    LIMIT_SLACK,
    POSITION_TOLERANCE,
    ROTATION_TOLERANCE,
    IKResult,
    check_goal,
    check_seed,
    failed_result,
    goal_and_seed,
    goal_tuple,
    make_result,
    pose_errors,
)
from davinci_sim.kinematics.jit import kernel_array, warm
from davinci_sim.kinematics.psm_closed_form import (
    INSERTION,
    MIN_GOAL_DISTANCE_FROM_RCM,
    NO_SOLUTION,
    POLISH,
    SAFE_DISTANCE_FROM_RCM,
    SOLVED,
    TOO_CLOSE,
    closed_form_rows,
    insertion_rule,
    normalise_row,
)

# --- chain geometry ---------------------------------------------------------------------------


@dataclass(frozen=True)
class PSMGeometry:
    """The constants of a PSM chain the closed form needs (lengths m, angles rad)."""

    ca: tuple[float, ...]
    """cos α_i, i = 1..6."""
    sa: tuple[float, ...]
    """sin α_i, i = 1..6."""
    theta0: tuple[float, ...]
    """Constant angle part θ_i − q_i (theta + offset; theta for the prismatic joint 3)."""
    shaft0: float
    """d₃ + offset₃ + d₄: frame 4 is at (q₃ + shaft0)·z₃ from the RCM (−0.0156 m)."""
    shaft_limits: tuple[tuple[float, float], ...]
    """(qmin, qmax) of yaw, pitch (rad) and insertion (m), with the IK limit slack."""
    a6: float
    d6: float
    R_tool_T: tuple[float, ...]
    """Rotation of the tooltip offset, transposed, row-major."""
    p_tool: tuple[float, float, float]

    @classmethod
    def from_chain(cls, chain: DHChain) -> PSMGeometry:
        """Read and check the constants; ValueError if the chain is not RCM + 2-axis wrist."""
        j = chain.joints
        types = tuple(x.joint_type for x in j)
        expected = ("revolute", "revolute", "prismatic", "revolute", "revolute", "revolute")
        problems = []
        if chain.convention != "modified" or types != expected:
            problems.append("needs a modified-DH R-R-P-R-R-R chain")
        else:
            zero = {
                "a1": j[0].a, "d1": j[0].d, "a2": j[1].a, "d2": j[1].d, "a3": j[2].a,
                "alpha4": j[3].alpha, "a4": j[3].a, "a5": j[4].a, "d5": j[4].d,
            }  # fmt: skip
            problems += [f"{k}={v} must be 0" for k, v in zero.items() if v != 0.0]
            if abs(math.sin(j[4].alpha)) < 0.5 or abs(math.sin(j[5].alpha)) < 0.5:
                problems.append("wrist twists alpha5, alpha6 must be near ±90°")
        if problems:
            raise ValueError(f"{chain.name}: not a Classic PSM geometry: {'; '.join(problems)}")
        T = chain.T_last_tip
        return cls(
            ca=tuple(math.cos(x.alpha) for x in j),
            sa=tuple(math.sin(x.alpha) for x in j),
            theta0=tuple(float(x.theta + x.offset) if x.is_revolute else float(x.theta) for x in j),
            shaft0=float(j[2].d + j[2].offset + j[3].d),
            shaft_limits=tuple((x.qmin - LIMIT_SLACK, x.qmax + LIMIT_SLACK) for x in j[:3]),
            a6=float(j[5].a),
            d6=float(j[5].d),
            R_tool_T=tuple(float(T[c, r]) for r in range(3) for c in range(3)),
            p_tool=(float(T[0, 3]), float(T[1, 3]), float(T[2, 3])),
        )


_GEOMETRY: weakref.WeakKeyDictionary[DHChain, PSMGeometry] = weakref.WeakKeyDictionary()


def psm_geometry(chain: DHChain) -> PSMGeometry:
    """Cached :meth:`PSMGeometry.from_chain`."""
    g = _GEOMETRY.get(chain)
    if g is None:
        g = _GEOMETRY[chain] = PSMGeometry.from_chain(chain)
    return g


# --- closed form ----------------------------------------------------------------------------


@dataclass(frozen=True)
class _Packed:
    """A PSM chain's constants as the kernel's arrays (see ``closed_form_rows``), cached."""

    geometry: np.ndarray
    tool: np.ndarray
    revolute: np.ndarray
    lim_lo: np.ndarray
    lim_hi: np.ndarray
    fk: tuple


_PACKED: weakref.WeakKeyDictionary[DHChain, _Packed] = weakref.WeakKeyDictionary()


def _packed(chain: DHChain) -> _Packed:
    p = _PACKED.get(chain)
    if p is None:
        g = psm_geometry(chain)
        geometry = [*g.ca, *g.sa, *g.theta0, g.shaft0, g.a6, g.d6]
        geometry += [x for lo_hi in g.shaft_limits for x in lo_hi]
        p = _PACKED[chain] = _Packed(
            np.array(geometry, dtype=float),
            np.array([*g.R_tool_T, *g.p_tool], dtype=float),
            np.array([j.is_revolute for j in chain.joints]),
            np.array([j.qmin - LIMIT_SLACK for j in chain.joints]),
            np.array([j.qmax + LIMIT_SLACK for j in chain.joints]),
            fk._consts(chain).packed,
        )
    return p


def _solve_rows(chain: DHChain, T: np.ndarray, S: np.ndarray, tolerance: np.ndarray):
    """The kernel on checked goals (n, 4, 4) and seeds (n, 6): q, success, status, info."""
    n = T.shape[0]
    p = _packed(chain)
    q, success = np.empty((n, 6)), np.empty(n, dtype=bool)
    status, info = np.empty(n, dtype=np.int64), np.empty((n, 5))
    closed_form_rows(
        p.geometry, p.tool, p.revolute, p.lim_lo, p.lim_hi, *p.fk,
        kernel_array(T), kernel_array(S), kernel_array(tolerance), q, success, status, info,
    )  # fmt: skip
    return q, success, status, info


def _normalise(chain: DHChain, q, seed) -> list[float]:
    """Wrap revolute joints (dvrk.md 1.8), then put the roll nearest the current roll (the
    kernel's ``normalise_row``)."""
    p = _packed(chain)
    out = np.array(q, dtype=float)
    normalise_row(out, np.asarray(seed, float), p.revolute, p.lim_lo, p.lim_hi)
    return out.tolist()


def _row_result(
    chain: DHChain,
    g: PSMGeometry,
    goal: tuple[float, ...],
    seed: list[float],
    q: np.ndarray,
    status: int,
    info: np.ndarray,
    position_tolerance: float,
    rotation_tolerance: float,
) -> IKResult:
    """The :class:`IKResult` of one row of the kernel: messages, and the reference DLS
    polish of the rare ``POLISH`` rows."""
    steps = int(info[0])
    if status == TOO_CLOSE:
        d = math.sqrt(goal[9] ** 2 + goal[10] ** 2 + goal[11] ** 2)
        return failed_result(
            chain,
            seed,
            goal,
            f"goal {d * 1e3:.3g} mm from the RCM, closer than "
            f"{MIN_GOAL_DISTANCE_FROM_RCM * 1e3:.0f} mm (dvrk.md 1.8); q is the seed",
        )
    if status == NO_SOLUTION:
        return failed_result(
            chain, seed, goal, "no closed-form solution (goal out of the PSM workspace)", steps
        )
    if status == POLISH:
        # Near-degenerate wrist geometry: polish with the reference iteration.
        sol = dls_solve(chain, goal, q.tolist())
        q = _normalise(chain, sol.q, seed)
        errors = pose_errors(fk_tuple(chain, q), goal)
        return _finish(
            chain, g, q, seed, goal, steps + sol.iterations, None, errors,
            position_tolerance, rotation_tolerance,
        )  # fmt: skip
    adjusted = None
    if info[4]:
        adjusted = _adjusted_message(float(info[3]), float(q[INSERTION]))
    return make_result(
        chain,
        q.tolist(),
        goal,
        iterations=steps,
        adjusted=adjusted,
        errors=(float(info[1]), float(info[2])),
        position_tolerance=position_tolerance,
        rotation_tolerance=rotation_tolerance,
    )


def _adjusted_message(old: float, new: float) -> str:
    return (
        f"insertion {old:.6g} m -> {new:.6g} m to keep the shaft end "
        f"{SAFE_DISTANCE_FROM_RCM * 1e3:.0f} mm from the RCM"
    )


def _insertion_safety(
    g: PSMGeometry, q: list[float], seed: list[float]
) -> tuple[list[float], str | None]:
    """dvrk.md 1.8: keep the shaft end (frame 4) ≥ 45 mm from the RCM (the kernel's
    ``insertion_rule``), with the message saying so."""
    new = insertion_rule(q[INSERTION], seed[INSERTION], g.shaft0)
    if new == q[INSERTION]:
        return q, None
    q = list(q)
    old, q[INSERTION] = q[INSERTION], new
    return q, _adjusted_message(old, new)


def _finish(
    chain: DHChain,
    g: PSMGeometry,
    q: list[float],
    seed: list[float],
    goal: tuple[float, ...],
    iterations: int,
    failure: str | None,
    errors: tuple[float, float] | None,
    position_tolerance: float,
    rotation_tolerance: float,
) -> IKResult:
    """Shared PSM tail: check the pose reached, then apply the insertion safety rule."""
    if errors is None:
        errors = pose_errors(fk_tuple(chain, q), goal)
    if failure is None and (errors[0] > position_tolerance or errors[1] > rotation_tolerance):
        failure = (
            f"pose not reached: position error {errors[0]:.3g} m, "
            f"rotation error {errors[1]:.3g} rad"
        )
    q, adjusted = _insertion_safety(g, q, seed)
    return make_result(
        chain,
        q,
        goal,
        iterations=iterations,
        failure=failure,
        adjusted=adjusted,
        errors=None if adjusted else errors,
        position_tolerance=position_tolerance,
        rotation_tolerance=rotation_tolerance,
    )


def _too_close(chain: DHChain, seed, goal) -> IKResult | None:
    d = math.sqrt(goal[9] ** 2 + goal[10] ** 2 + goal[11] ** 2)
    if d >= MIN_GOAL_DISTANCE_FROM_RCM:
        return None
    return _row_result(chain, psm_geometry(chain), goal, seed, None, TOO_CLOSE, (0,), 0.0, 0.0)


def psm_ik_closed_form(
    chain: DHChain,
    T_rcm_tip,
    q_seed,
    *,
    position_tolerance: float = POSITION_TOLERANCE,
    rotation_tolerance: float = ROTATION_TOLERANCE,
) -> IKResult:
    """Exact closed-form PSM IK (see the module docstring), with the dVRK post-processing:
    the kernel on a batch of one.

    Args:
        chain: a PSM chain (yaw, pitch, insertion, roll, wrist pitch, wrist yaw + tooltip).
        T_rcm_tip: goal pose of the tool tip in the RCM frame, (4, 4), m.
        q_seed: current joints (6,), rad / m: picks the branch (nearest) and drives the roll
            and insertion-safety rules.
        position_tolerance, rotation_tolerance: acceptance of the FK check (m, rad).

    Returns:
        IKResult; ``iterations`` counts fixed-point steps of the wrist equation.

    Raises:
        ValueError: on a badly shaped or non-finite goal or seed, or a non-PSM chain.
    """
    g = psm_geometry(chain)  # raises for a chain that is not a PSM
    T, S = check_goal(T_rcm_tip), check_seed(chain, q_seed)
    q, success, status, info = _solve_rows(
        chain,
        T.reshape(1, 4, 4),
        S.reshape(1, 6),
        _tolerance(position_tolerance, rotation_tolerance),
    )
    if success[0] and status[0] == SOLVED and not info[0, 4]:
        # The common answer, as make_result builds it (pose within the tolerances, checked by
        # the kernel; joints within the limits, the same test as limit_violations).
        return IKResult(
            q=q[0],
            success=True,
            message="ok",
            iterations=int(info[0, 0]),
            position_error=float(info[0, 1]),
            rotation_error=float(info[0, 2]),
            reached=True,
        )
    return _row_result(
        chain, g, goal_tuple(T), S.tolist(), q[0], int(status[0]), info[0],
        position_tolerance, rotation_tolerance,
    )  # fmt: skip


_DEFAULT_TOLERANCE = np.array([POSITION_TOLERANCE, ROTATION_TOLERANCE])
_DEFAULT_TOLERANCE.setflags(write=False)


def _tolerance(position_tolerance: float, rotation_tolerance: float) -> np.ndarray:
    if position_tolerance == POSITION_TOLERANCE and rotation_tolerance == ROTATION_TOLERANCE:
        return _DEFAULT_TOLERANCE
    return np.array([position_tolerance, rotation_tolerance], dtype=float)


class BatchIKResult(NamedTuple):
    """Answers of :func:`psm_ik_closed_form_batch`, row i for goal i."""

    q: np.ndarray
    """Joint values, rad (revolute) / m (insertion), shape ``(n, 6)``."""
    success: np.ndarray
    """``IKResult.success`` of each row, bool, shape ``(n,)``."""


def psm_ik_closed_form_batch(
    chain: DHChain,
    T_rcm_tip,
    q_seed,
    *,
    position_tolerance: float = POSITION_TOLERANCE,
    rotation_tolerance: float = ROTATION_TOLERANCE,
) -> BatchIKResult:
    """:func:`psm_ik_closed_form` for n goals at once (the same kernel, n rows): row i is
    ``psm_ik_closed_form(chain, T_rcm_tip[i], q_seed[i])``'s ``q`` and ``success``, bit for
    bit.

    Args:
        chain: a PSM chain (yaw, pitch, insertion, roll, wrist pitch, wrist yaw + tooltip).
        T_rcm_tip: goal poses of the tool tip in the RCM frame, (n, 4, 4), m.
        q_seed: current joints of each arm, (n, 6), rad / m.
        position_tolerance, rotation_tolerance: acceptance of the FK check (m, rad).

    Raises:
        ValueError: on badly shaped or non-finite goals or seeds, or a non-PSM chain.
    """
    g = psm_geometry(chain)
    T, S = _check_inputs(chain, T_rcm_tip, q_seed)
    tolerance = _tolerance(position_tolerance, rotation_tolerance)
    q, success, status, info = _solve_rows(chain, T, S, tolerance)
    for i in np.flatnonzero(status == POLISH):
        goal = tuple(T[i, :3, :3].ravel().tolist() + T[i, :3, 3].tolist())
        r = _row_result(
            chain, g, goal, S[i].tolist(), q[i], POLISH, info[i],
            position_tolerance, rotation_tolerance,
        )  # fmt: skip
        q[i], success[i] = r.q, r.success
    return BatchIKResult(q=q, success=success)


def _check_inputs(chain: DHChain, T_rcm_tip, q_seed) -> tuple[np.ndarray, np.ndarray]:
    T = np.ascontiguousarray(T_rcm_tip, dtype=float)
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise ValueError(f"T_rcm_tip must have shape (n, 4, 4), got {T.shape}")
    S = np.ascontiguousarray(q_seed, dtype=float)
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


def psm_ik_reference(
    chain: DHChain,
    T_rcm_tip,
    q_seed,
    *,
    position_tolerance: float = POSITION_TOLERANCE,
    rotation_tolerance: float = ROTATION_TOLERANCE,
) -> IKResult:
    """The dVRK PSM IK: generic DLS seeded with the current joints + PSM rules (dvrk.md 1.8).

    Same arguments and result as :func:`psm_ik_closed_form`; ``iterations`` counts DLS steps.
    Slow (hundreds of µs to ms) but literal; kept as the oracle for the closed form.
    """
    g = psm_geometry(chain)
    goal, seed = goal_and_seed(chain, T_rcm_tip, q_seed)
    early = _too_close(chain, seed, goal)
    if early is not None:
        return early
    sol = dls_solve(chain, goal, seed)
    q = _normalise(chain, sol.q, seed)
    failure = None if sol.converged else f"DLS did not converge in {sol.iterations} iterations"
    return _finish(
        chain,
        g,
        q,
        seed,
        goal,
        sol.iterations,
        failure,
        None,
        position_tolerance,
        rotation_tolerance,
    )


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import, as
    :mod:`~davinci_sim.kinematics.fk_compiled` does: never in the middle of a 1 kHz loop.
    (A first Cartesian command compiled it in the simulation's thread: the loop stood still
    for seconds, half a minute on a busy machine with an empty cache, with no message.)"""
    chain = load_arm("PSM1").chain
    q = np.array([0.0, 0.0, 0.12, 0.0, 0.0, 0.0])
    psm_ik_closed_form(chain, fk.forward_kinematics(chain, q), q)


warm(_warm_up)


__all__ = [
    "BatchIKResult",
    "MIN_GOAL_DISTANCE_FROM_RCM",
    "SAFE_DISTANCE_FROM_RCM",
    "PSMGeometry",
    "psm_geometry",
    "psm_ik_closed_form",
    "psm_ik_closed_form_batch",
    "psm_ik_reference",
]
