"""MTM inverse kinematics, the dVRK default ``ITERATIVE`` kind (dvrk.md 1.8).

The goal ``T_base_tip`` is in the MTM chain base frame (not HRSV: remove the arm's
``T_reference_base`` first, dvrk.md 1.5). The MTM has 7 joints for 6 pose DOF; the platform
(joint 4) is redundant with the wrist, so the seed decides which of the infinitely many
solutions the DLS settles on. The dVRK nudges it first: the platform is pre-adjusted by
q₆·cos(q₅) (wrist yaw projected on the platform axis), clamped to its limits.
"""

from __future__ import annotations

import math

from davinci_sim.kinematics.chain import DHChain
from davinci_sim.kinematics.dls import dls_solve
from davinci_sim.kinematics.ik_base import (
    POSITION_TOLERANCE,
    ROTATION_TOLERANCE,
    IKResult,
    goal_and_seed,
    make_result,
    nearest_turn,
)

#: Joint indices (dvrk.md 1.5).
PLATFORM, WRIST_PITCH, WRIST_YAW, WRIST_ROLL = 3, 4, 5, 6


def mtm_ik_iterative(
    chain: DHChain,
    T_base_tip,
    q_seed,
    *,
    position_tolerance: float = POSITION_TOLERANCE,
    rotation_tolerance: float = ROTATION_TOLERANCE,
) -> IKResult:
    """MTM IK: platform pre-adjust, generic DLS, wrist roll nearest the current one.

    The wrist roll takes the turn (mod 2π) nearest the current roll, preferring one within
    its limits.

    Args:
        chain: an MTM chain (7 revolute joints, standard DH).
        T_base_tip: goal pose of the gimbal tip in the MTM base frame, (4, 4), m.
        q_seed: current joints (7,), rad.
        position_tolerance, rotation_tolerance: acceptance of the FK check (m, rad).

    Returns:
        IKResult; ``iterations`` counts DLS steps.

    Raises:
        ValueError: on a badly shaped or non-finite goal or seed, or a chain without 7 joints.
    """
    if chain.dof != 7:
        raise ValueError(f"{chain.name}: an MTM chain has 7 joints, got {chain.dof}")
    goal, seed = goal_and_seed(chain, T_base_tip, q_seed)
    start = list(seed)
    platform = chain.joints[PLATFORM]
    start[PLATFORM] = min(
        max(seed[PLATFORM] + seed[WRIST_YAW] * math.cos(seed[WRIST_PITCH]), platform.qmin),
        platform.qmax,
    )
    sol = dls_solve(chain, goal, start)
    q = list(sol.q)
    # (dvrk.md 1.8: nearest the current roll mod 2π, within its limits or not, as the PSM's)
    q[WRIST_ROLL] = nearest_turn(q[WRIST_ROLL], seed[WRIST_ROLL])
    failure = None if sol.converged else f"DLS did not converge in {sol.iterations} iterations"
    return make_result(
        chain,
        q,
        goal,
        iterations=sol.iterations,
        failure=failure,
        position_tolerance=position_tolerance,
        rotation_tolerance=rotation_tolerance,
    )
