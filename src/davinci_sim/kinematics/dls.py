"""The generic damped-least-squares IK of cisst ``robManipulator`` (dvrk.md 1.8).

This is the solver the dVRK uses for the PSM and (by default) the MTM. It is kept literal,
slow convergence included: with the fixed damping λ = 0.001 the wrist directions of a PSM
(lever 9.1 mm, so σ² ≈ 1e-4 < λ) shrink by only ~10 % per step, and a solve takes a few
hundred steps.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from davinci_sim.kinematics.chain import DHChain
from davinci_sim.kinematics.fk import forward_kinematics_and_jacobian
from davinci_sim.kinematics.ik_base import (
    POSITION_TOLERANCE,
    ROTATION_TOLERANCE,
    IKResult,
    goal_and_seed,
    goal_tuple,
    make_result,
    wrap_revolute,
)

#: cisst defaults (dvrk.md 1.8).
DLS_TOLERANCE = 1e-12
DLS_MAX_ITERATIONS = 1000
DLS_DAMPING = 1e-3


class DLSSolution(NamedTuple):
    """Raw output of :func:`dls_solve`, before any arm-specific post-processing."""

    q: list[float]
    """Joint values after wrapping revolute joints (rad / m)."""
    converged: bool
    """‖Δq‖ fell to the tolerance before the iteration cap."""
    iterations: int


def dls_solve(
    chain: DHChain,
    goal: Sequence[float],
    q_seed: Sequence[float],
    *,
    tolerance: float = DLS_TOLERANCE,
    max_iterations: int = DLS_MAX_ITERATIONS,
    damping: float = DLS_DAMPING,
) -> DLSSolution:
    """Iterate Δq = Jsᵀ (Js Jsᵀ + λI)⁻¹ [e_p; e_r] from ``q_seed`` (dvrk.md 1.8).

    ``goal`` is the flat pose tuple of :func:`~davinci_sim.kinematics.ik_base.goal_tuple`
    (rotation row-major, then position in m). e_p is the tip position error in the base
    frame; e_r = ½ (n×n_g + o×o_g + a×a_g) with n, o, a the columns of the current rotation
    and n_g, o_g, a_g those of the goal. Stops when ‖Δq‖ ≤ ``tolerance`` (converged) or after
    ``max_iterations`` steps; revolute joints are then wrapped to (−π, π].
    """
    q = [float(x) for x in q_seed]
    gx, gy, gz = goal[9], goal[10], goal[11]
    # Goal columns n_g, o_g, a_g.
    g_cols = [(goal[c], goal[3 + c], goal[6 + c]) for c in range(3)]
    lam = damping * np.eye(6)
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):  # noqa: B007 - 'it' is reported after the loop
        T, Jn = forward_kinematics_and_jacobian(chain, np.array(q))
        f = goal_tuple(T)
        erx = ery = erz = 0.0
        for c in range(3):
            ux, uy, uz = f[c], f[3 + c], f[6 + c]
            vx, vy, vz = g_cols[c]
            erx += uy * vz - uz * vy
            ery += uz * vx - ux * vz
            erz += ux * vy - uy * vx
        e = np.array([gx - f[9], gy - f[10], gz - f[11], 0.5 * erx, 0.5 * ery, 0.5 * erz])
        dq = Jn.T @ np.linalg.solve(Jn @ Jn.T + lam, e)
        dql = dq.tolist()
        q = [a + b for a, b in zip(q, dql, strict=True)]
        if math.sqrt(sum(x * x for x in dql)) <= tolerance:
            converged = True
            break
    return DLSSolution(q=wrap_revolute(chain, q), converged=converged, iterations=it)


def dls_ik(
    chain: DHChain,
    T_base_tip,
    q_seed,
    *,
    tolerance: float = DLS_TOLERANCE,
    max_iterations: int = DLS_MAX_ITERATIONS,
    damping: float = DLS_DAMPING,
    position_tolerance: float = POSITION_TOLERANCE,
    rotation_tolerance: float = ROTATION_TOLERANCE,
) -> IKResult:
    """Generic DLS IK of any chain, verified: pose error and joint limits are checked.

    Args:
        chain: the DH chain (its base frame is the goal's frame).
        T_base_tip: goal pose (4, 4), m.
        q_seed: starting joints (dof,), rad / m; normally the current joints.
        tolerance, max_iterations, damping: the cisst parameters (dvrk.md 1.8).
        position_tolerance, rotation_tolerance: acceptance of the FK check (m, rad).

    Returns:
        An :class:`~davinci_sim.kinematics.ik_base.IKResult`; ``success=False`` if the
        iteration did not converge, missed the goal or left the joint limits.

    Raises:
        ValueError: if the goal or seed has the wrong shape or is not finite.
    """
    goal, seed = goal_and_seed(chain, T_base_tip, q_seed)
    sol = dls_solve(
        chain, goal, seed, tolerance=tolerance, max_iterations=max_iterations, damping=damping
    )
    failure = None if sol.converged else f"DLS did not converge in {sol.iterations} iterations"
    return make_result(
        chain,
        sol.q,
        goal,
        iterations=sol.iterations,
        failure=failure,
        position_tolerance=position_tolerance,
        rotation_tolerance=rotation_tolerance,
    )
