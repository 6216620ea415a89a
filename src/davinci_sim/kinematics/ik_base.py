"""What every IK solver shares: the result type, input checks, pose errors, joint wrapping.

All solvers take the goal ``T_base_tip`` in the chain's base frame (the RCM for PSM/ECM,
dvrk.md 1.2 and 1.4; the MTM base, not HRSV) and a seed ``q_seed``, which is the arm's
current joint vector (rad / m): the dVRK seeds its IK with the measured joints and several
post-processing rules (roll nearest current, PSM insertion safety) refer to it (dvrk.md 1.8).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from davinci_sim.kinematics.chain import DHChain
from davinci_sim.kinematics.fk import fk_tuple
from davinci_sim.kinematics.jit import helper

TWO_PI = 2.0 * math.pi

#: Default acceptance tolerances of an IK answer (m, rad): far below anything physical, far
#: above the ~1e-15 that converged solvers reach.
POSITION_TOLERANCE = 1e-9
ROTATION_TOLERANCE = 1e-9

#: Slack when testing joint limits, so that a goal computed by FK at a limit is still accepted.
LIMIT_SLACK = 1e-9


class IKResult(NamedTuple):
    """The answer of an IK solver.

    ``success`` means ``q`` is a command the dVRK would accept: within joint limits and, unless
    ``adjusted``, reaching the goal within tolerance. An unreachable goal gives
    ``success=False`` and a ``message`` saying why; ``q`` is then the solver's best attempt
    (never to be sent blindly).
    """

    q: np.ndarray
    """Joint values, rad (revolute) / m (prismatic), shape ``(dof,)``."""
    success: bool
    message: str
    iterations: int
    """DLS steps (iterative solvers) or fixed-point steps of the PSM wrist equation."""
    position_error: float
    """‖p(q) − p_goal‖, m."""
    rotation_error: float
    """Angle of R(q)ᵀ·R_goal, rad."""
    adjusted: bool = False
    """A dVRK rule moved ``q`` off the exact solution on purpose: PSM 45 mm insertion rule,
    ECM 40 mm insertion clamp, ECM orientation projection. The errors above then measure it."""
    reached: bool = False
    """``q`` reaches the goal (within the tolerances, or as ``adjusted``) and the solver did
    not fail: only joint limits can make such a result unsuccessful. The dVRK's generic IK
    does not test limits; its arm clips the solution to them (``clip_jp``, dvrk.md 1.8)."""


# --- input checks ---------------------------------------------------------------------------


def check_goal(T_base_tip) -> np.ndarray:
    """The goal as a float (4, 4) array; ValueError if its shape is wrong or it is not finite."""
    T = np.asarray(T_base_tip, dtype=float)
    if T.shape != (4, 4):
        raise ValueError(f"goal T_base_tip must have shape (4, 4), got {T.shape}")
    if not np.isfinite(T).all():
        raise ValueError(f"goal T_base_tip must be finite, got {T_base_tip!r}")
    return T


def check_seed(chain: DHChain, q_seed) -> np.ndarray:
    """The seed as a float (dof,) array; ValueError if its shape is wrong or it is not finite."""
    q = np.asarray(q_seed, dtype=float)
    if q.shape != (chain.dof,):
        raise ValueError(f"{chain.name}: q_seed must have shape ({chain.dof},), got {q.shape}")
    if not np.isfinite(q).all():
        raise ValueError(f"{chain.name}: q_seed must be finite, got {q_seed!r}")
    return q


def goal_and_seed(chain: DHChain, T_base_tip, q_seed) -> tuple[tuple[float, ...], list[float]]:
    """Every solver's inputs, checked (:func:`check_goal`, :func:`check_seed`), as floats: the
    goal as a :func:`goal_tuple` and the seed as a list."""
    return goal_tuple(check_goal(T_base_tip)), check_seed(chain, q_seed).tolist()


def goal_tuple(T: np.ndarray) -> tuple[float, ...]:
    """A (4, 4) pose as the flat float tuple of :func:`~davinci_sim.kinematics.fk.fk_tuple`."""
    (r00, r01, r02, px), (r10, r11, r12, py), (r20, r21, r22, pz) = T[:3].tolist()
    return (r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz)


# --- pose errors ----------------------------------------------------------------------------


@helper
def pose_errors(f: Sequence[float], g: Sequence[float]) -> tuple[float, float]:
    """Position (m) and rotation (rad) distance between two flat pose tuples.

    The angle uses atan2(sin, cos) of RᵀR_g: ``acos`` of the trace alone loses all precision
    below ~1e-8 rad, which is exactly the range the IK acceptance test needs. (Plain float
    arithmetic: compiled into the PSM IK kernel too, :func:`~davinci_sim.kinematics.jit.helper`.)
    """
    dp = math.sqrt((f[9] - g[9]) ** 2 + (f[10] - g[10]) ** 2 + (f[11] - g[11]) ** 2)
    # E = Rᵀ R_g via column dot products: E_ij = col_i(R) · col_j(R_g).
    e00 = f[0] * g[0] + f[3] * g[3] + f[6] * g[6]
    e11 = f[1] * g[1] + f[4] * g[4] + f[7] * g[7]
    e22 = f[2] * g[2] + f[5] * g[5] + f[8] * g[8]
    e01 = f[0] * g[1] + f[3] * g[4] + f[6] * g[7]
    e02 = f[0] * g[2] + f[3] * g[5] + f[6] * g[8]
    e10 = f[1] * g[0] + f[4] * g[3] + f[7] * g[6]
    e12 = f[1] * g[2] + f[4] * g[5] + f[7] * g[8]
    e20 = f[2] * g[0] + f[5] * g[3] + f[8] * g[6]
    e21 = f[2] * g[1] + f[5] * g[4] + f[8] * g[7]
    s = 0.5 * math.sqrt((e21 - e12) ** 2 + (e02 - e20) ** 2 + (e10 - e01) ** 2)
    c = 0.5 * (e00 + e11 + e22 - 1.0)
    return dp, math.atan2(s, c)


def fk_errors(chain: DHChain, q: Sequence[float], goal: Sequence[float]) -> tuple[float, float]:
    """Position and rotation error of FK(q) against a flat goal tuple (m, rad)."""
    return pose_errors(fk_tuple(chain, q), goal)


# --- joint post-processing ------------------------------------------------------------------


@helper
def wrap_angle(x: float) -> float:
    """``x`` wrapped to (−π, π]."""
    return math.pi - (math.pi - x) % TWO_PI


@helper
def nearest_turn(x: float, reference: float) -> float:
    """``x`` shifted by the multiple of 2π that brings it nearest ``reference``."""
    return x + TWO_PI * round((reference - x) / TWO_PI)


_LIMITS: weakref.WeakKeyDictionary[DHChain, tuple[tuple[bool, float, float], ...]] = (
    weakref.WeakKeyDictionary()
)


def _limits(chain: DHChain) -> tuple[tuple[bool, float, float], ...]:
    """(revolute, qmin − slack, qmax + slack) per joint, cached: attribute access is slow."""
    lim = _LIMITS.get(chain)
    if lim is None:
        lim = tuple(
            (j.is_revolute, j.qmin - LIMIT_SLACK, j.qmax + LIMIT_SLACK) for j in chain.joints
        )
        _LIMITS[chain] = lim
    return lim


@helper
def wrap_within(x: float, lo: float, hi: float) -> float:
    """A revolute joint value wrapped to (−π, π], then moved by ±2π into [lo, hi] when it
    is outside and that is possible (the rule of :func:`wrap_revolute`)."""
    x = math.pi - (math.pi - x) % TWO_PI
    if not lo <= x <= hi:
        if lo <= x - TWO_PI <= hi:
            x -= TWO_PI
        elif lo <= x + TWO_PI <= hi:
            x += TWO_PI
    return x


def wrap_revolute(chain: DHChain, q: Sequence[float]) -> list[float]:
    """Wrap revolute joints to (−π, π] as cisst does after its IK (dvrk.md 1.8).

    Some joints have ranges wider than (−π, π] (MTM platform and wrist pitch); a wrapped value
    outside its limits is moved by ±2π into them when that is possible. This only changes the
    representation of the same pose, never the pose.
    """
    return [
        wrap_within(x, lo, hi) if rev else x
        for (rev, lo, hi), x in zip(_limits(chain), q, strict=True)
    ]


def within_limits(chain: DHChain, q: Sequence[float]) -> bool:
    """True if every joint is within its limits (± LIMIT_SLACK)."""
    return all(lo <= x <= hi for (_, lo, hi), x in zip(_limits(chain), q, strict=True))


def limit_violations(chain: DHChain, q: Sequence[float]) -> list[str]:
    """Human-readable list of joints outside their limits (empty if none)."""
    if within_limits(chain, q):
        return []
    return [
        f"{j.name}={x:.6g} not in [{j.qmin:.6g}, {j.qmax:.6g}]"
        for j, x in zip(chain.joints, q, strict=True)
        if not j.qmin - LIMIT_SLACK <= x <= j.qmax + LIMIT_SLACK
    ]


def make_result(
    chain: DHChain,
    q: Sequence[float],
    goal: Sequence[float],
    *,
    iterations: int,
    failure: str | None = None,
    adjusted: str | None = None,
    errors: tuple[float, float] | None = None,
    position_tolerance: float = POSITION_TOLERANCE,
    rotation_tolerance: float = ROTATION_TOLERANCE,
) -> IKResult:
    """Check ``q`` (pose error against ``goal`` and joint limits) and build the result.

    ``failure`` forces ``success=False`` with that reason. ``adjusted`` names a deliberate
    dVRK adjustment: the pose errors are then reported but not held against ``q``.
    ``errors`` are the already known (position, rotation) errors of ``q``, to skip an FK.
    """
    dp, dr = fk_errors(chain, q, goal) if errors is None else errors
    reasons = [failure] if failure else []
    if adjusted is None and (dp > position_tolerance or dr > rotation_tolerance):
        reasons.append(f"pose not reached: position error {dp:.3g} m, rotation error {dr:.3g} rad")
    reached = not reasons
    bad = limit_violations(chain, q)
    if bad:
        reasons.append("joint limits: " + ", ".join(bad))
    success = not reasons
    if success:
        message = "ok" if adjusted is None else f"ok, adjusted: {adjusted}"
    else:
        message = "; ".join(reasons) + (f" (adjusted: {adjusted})" if adjusted else "")
    return IKResult(
        q=np.array(q, dtype=float),
        success=success,
        message=message,
        iterations=iterations,
        position_error=dp,
        rotation_error=dr,
        adjusted=adjusted is not None,
        reached=reached,
    )


def failed_result(
    chain: DHChain, q: Sequence[float], goal: Sequence[float], message: str, iterations: int = 0
) -> IKResult:
    """A ``success=False`` result carrying ``q`` (often the seed) and ``message``."""
    dp, dr = fk_errors(chain, q, goal)
    return IKResult(
        q=np.array(q, dtype=float),
        success=False,
        message=message,
        iterations=iterations,
        position_error=dp,
        rotation_error=dr,
    )
