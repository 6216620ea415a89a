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
Each answer is checked by FK. The one degenerate geometry (RCM on the wrist-yaw axis, where θ₆
is undetermined) needs a wrist pitch near ±90°, outside the ±80° limits; should it spoil an
answer anyway, DLS steps polish it (counted in ``iterations``) and the result is rechecked.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

from davinci_sim.geometry.so3 import mat3_mul as _mul
from davinci_sim.kinematics.chain import DHChain
from davinci_sim.kinematics.dls import dls_solve
from davinci_sim.kinematics.fk import fk_tuple
from davinci_sim.kinematics.ik_base import (
    LIMIT_SLACK,
    POSITION_TOLERANCE,
    ROTATION_TOLERANCE,
    IKResult,
    failed_result,
    goal_and_seed,
    make_result,
    nearest_turn_within,
    pose_errors,
    within_limits,
    wrap_angle,
    wrap_revolute,
)
from davinci_sim.kinematics.rcm import rxrz as _rxrz
from davinci_sim.kinematics.rcm import shaft_angles, tool_origin

#: dvrk.md 1.8: goals closer than this to the RCM are rejected (m).
MIN_GOAL_DISTANCE_FROM_RCM = 0.001
#: dvrk.md 1.7 ``SafeDistanceFromRCM``: minimum RCM to shaft-end (frame 4) distance (m).
SAFE_DISTANCE_FROM_RCM = 0.045
#: Index of the roll joint (dvrk.md 1.2).
ROLL = 3
INSERTION = 2

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


def _wrist_roots(
    A: float, B: float, C0: float, k: float, pp: float, a6: float, Px: float, Py: float
) -> tuple[list[float], int]:
    """Roots θ of A sθ + B cθ = C0 + k·√(pp − 2a₆(Px cθ − Py sθ) + a₆²) (k = σ·cα₅, tiny)."""
    Rm = math.hypot(A, B)
    if Rm < 1e-12:
        return [], 0
    phi = math.atan2(A, B)
    roots = []
    steps = 0
    for sgn in (1.0, -1.0):
        th = None
        c = C0 / Rm
        for _ in range(12):
            if abs(c) > 1.0:
                th = None
                break
            new = phi + sgn * math.acos(c)
            steps += 1
            if th is not None and abs(new - th) <= 1e-15:
                th = new
                break
            th = new
            # |o₅|² = |p|² − 2a₆ p·x₅ + a₆², p·x₅ = Px cθ − Py sθ
            rho2 = pp - 2.0 * a6 * (Px * math.cos(th) - Py * math.sin(th)) + a6 * a6
            rho = math.sqrt(max(0.0, rho2))
            c = (C0 + k * rho) / Rm
        if th is not None:
            roots.append(th)
    return roots, steps


def _candidates(g: PSMGeometry, goal: tuple[float, ...], seed: list[float]):
    """Closed-form joint solutions (angles unwrapped) and the number of wrist steps.

    Shaft branches whose yaw, pitch or insertion is outside the limits are only completed
    (roll, wrist pitch) when no branch is within them, so that a failure still has a q.
    """
    R6, px, py, pz = tool_origin(goal, g.R_tool_T, g.p_tool)
    if g.d6 != 0.0:
        px, py, pz = px - g.d6 * R6[2], py - g.d6 * R6[5], pz - g.d6 * R6[8]
    x6 = (R6[0], R6[3], R6[6])
    y6 = (R6[1], R6[4], R6[7])
    # P = R₆ᵀp: the RCM→tip vector in the frame-6 axes.
    Px = x6[0] * px + x6[1] * py + x6[2] * pz
    Py = y6[0] * px + y6[1] * py + y6[2] * pz
    Pz = R6[2] * px + R6[5] * py + R6[8] * pz
    pp = px * px + py * py + pz * pz
    ca, sa, t0, a6 = g.ca, g.sa, g.theta0, g.a6
    # σ = −1 (frame 4 behind the RCM) only exists with the tool inside the cannula.
    sigmas = [1.0]
    if math.sqrt(pp) - a6 <= -g.shaft0 - g.shaft_limits[2][0] + 1e-9:
        sigmas.append(-1.0)
    inside, outside = [], []
    steps = 0
    for sigma in sigmas:
        roots, n = _wrist_roots(sa[5] * Px, sa[5] * Py, -ca[5] * Pz, sigma * ca[4], pp, a6, Px, Py)
        steps += n
        if not roots:  # degenerate (RCM on the wrist-yaw axis): keep the seed's wrist yaw
            roots = [seed[5] + t0[5]]
        for th6 in roots:
            c6, s6 = math.cos(th6), math.sin(th6)
            # o₅ = p − a₆·x₅ with x₅ = cθ₆·x₆ − sθ₆·y₆
            ox = px - a6 * (c6 * x6[0] - s6 * y6[0])
            oy = py - a6 * (c6 * x6[1] - s6 * y6[1])
            oz = pz - a6 * (c6 * x6[2] - s6 * y6[2])
            rho = math.sqrt(ox * ox + oy * oy + oz * oz)
            if rho == 0.0:
                continue
            q3 = sigma * rho - g.shaft0
            z3 = (sigma * ox / rho, sigma * oy / rho, sigma * oz / rho)
            for th1, th2 in shaft_angles(ca, sa, z3):
                shaft = (wrap_angle(th1 - t0[0]), wrap_angle(th2 - t0[1]), q3)
                ok = all(lo <= x <= hi for x, (lo, hi) in zip(shaft, g.shaft_limits, strict=True))
                (inside if ok else outside).append((th1, th2, q3, th6))
    out = [_complete_wrist(g, R6, *c) for c in (inside or outside)]
    return out, steps


def _complete_wrist(
    g: PSMGeometry, R6: tuple[float, ...], th1: float, th2: float, q3: float, th6: float
) -> list[float]:
    """Roll and wrist pitch from R₃ᵀR₅ = Rz(θ₄)·Rx(α₅)·Rz(θ₅); returns the joint vector."""
    ca, sa, t0 = g.ca, g.sa, g.theta0
    M6 = _rxrz(ca[5], sa[5], th6)
    R5 = _mul(R6, (M6[0], M6[3], M6[6], M6[1], M6[4], M6[7], M6[2], M6[5], M6[8]))
    R3 = _mul(_mul(_rxrz(ca[0], sa[0], th1), _rxrz(ca[1], sa[1], th2)), _rxrz(ca[2], sa[2], t0[2]))
    # Only the entries 02, 12, 20, 21 of M = R₃ᵀR₅ are needed.
    M02 = R3[0] * R5[2] + R3[3] * R5[5] + R3[6] * R5[8]
    M12 = R3[1] * R5[2] + R3[4] * R5[5] + R3[7] * R5[8]
    M20 = R3[2] * R5[0] + R3[5] * R5[3] + R3[8] * R5[6]
    M21 = R3[2] * R5[1] + R3[5] * R5[4] + R3[8] * R5[7]
    s5 = sa[4]
    th4 = math.atan2(s5 * M02, -s5 * M12)
    th5 = math.atan2(s5 * M20, s5 * M21)
    return [th1 - t0[0], th2 - t0[1], q3, th4 - t0[3], th5 - t0[4], th6 - t0[5]]


def _normalise(chain: DHChain, q: list[float], seed: list[float]) -> list[float]:
    """Wrap revolute joints (dvrk.md 1.8), then put the roll nearest the current roll."""
    q = wrap_revolute(chain, q)
    roll = chain.joints[ROLL]
    q[ROLL] = nearest_turn_within(q[ROLL], seed[ROLL], roll.qmin, roll.qmax)
    return q


def _nearest(chain: DHChain, candidates: list[list[float]], seed: list[float]) -> list[float]:
    """The candidate within joint limits nearest the seed (any candidate if none is)."""
    return min(
        candidates,
        key=lambda q: (
            not within_limits(chain, q),
            sum((a - b) ** 2 for a, b in zip(q, seed, strict=True)),
        ),
    )


def _insertion_safety(
    g: PSMGeometry, q: list[float], seed: list[float]
) -> tuple[list[float], str | None]:
    """dvrk.md 1.8: keep the shaft end (frame 4) ≥ 45 mm from the RCM."""
    if abs(q[INSERTION] + g.shaft0) >= SAFE_DISTANCE_FROM_RCM:
        return q, None
    q_min = SAFE_DISTANCE_FROM_RCM - g.shaft0
    # Already shallower than allowed (e.g. engaging the tool): never pull out further.
    new = max(q[INSERTION], seed[INSERTION]) if seed[INSERTION] < q_min else q_min
    if new == q[INSERTION]:
        return q, None
    q = list(q)
    old, q[INSERTION] = q[INSERTION], new
    return q, (
        f"insertion {old:.6g} m -> {new:.6g} m to keep the shaft end "
        f"{SAFE_DISTANCE_FROM_RCM * 1e3:.0f} mm from the RCM"
    )


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
    return failed_result(
        chain,
        seed,
        goal,
        f"goal {d * 1e3:.3g} mm from the RCM, closer than "
        f"{MIN_GOAL_DISTANCE_FROM_RCM * 1e3:.0f} mm (dvrk.md 1.8); q is the seed",
    )


def psm_ik_closed_form(
    chain: DHChain,
    T_rcm_tip,
    q_seed,
    *,
    position_tolerance: float = POSITION_TOLERANCE,
    rotation_tolerance: float = ROTATION_TOLERANCE,
) -> IKResult:
    """Exact closed-form PSM IK (see the module docstring), with the dVRK post-processing.

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
    g = psm_geometry(chain)
    goal, seed = goal_and_seed(chain, T_rcm_tip, q_seed)
    early = _too_close(chain, seed, goal)
    if early is not None:
        return early
    raw, steps = _candidates(g, goal, seed)
    if not raw:
        return failed_result(
            chain, seed, goal, "no closed-form solution (goal out of the PSM workspace)", steps
        )
    q = _nearest(chain, [_normalise(chain, c, seed) for c in raw], seed)
    errors = pose_errors(fk_tuple(chain, q), goal)
    if errors[0] > position_tolerance or errors[1] > rotation_tolerance:
        # Near-degenerate wrist geometry: polish with the reference iteration.
        sol = dls_solve(chain, goal, q)
        steps += sol.iterations
        q = _normalise(chain, sol.q, seed)
        errors = pose_errors(fk_tuple(chain, q), goal)
    return _finish(
        chain, g, q, seed, goal, steps, None, errors, position_tolerance, rotation_tolerance
    )


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


__all__ = [
    "MIN_GOAL_DISTANCE_FROM_RCM",
    "SAFE_DISTANCE_FROM_RCM",
    "PSMGeometry",
    "psm_geometry",
    "psm_ik_closed_form",
    "psm_ik_reference",
]
