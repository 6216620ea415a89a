"""One entry point for the IK of any dVRK arm: :func:`inverse_kinematics`.

Solvers (dvrk.md 1.8): PSM exact closed form (default) or the dVRK reference DLS; ECM closed
form; MTM iterative DLS. Any other arm type (e.g. a simulated SUJ arm) gets the plain generic
DLS, verified like the others. The goal is always in the arm's **chain base frame**: the RCM for
PSM and ECM, the MTM base for MTMs. A CRTK ``move_cp`` goal given in the arm's reference
frame (``measured_cp`` frame: camera for PSMs, cart for the ECM, HRSV for MTMs) must first be
expressed in the base: ``T_base_tip = inv(T_reference_base) · T_reference_tip``.
"""

from __future__ import annotations

from typing import Literal

from davinci_sim.kinematics.arms import ArmKinematics
from davinci_sim.kinematics.dls import dls_ik
from davinci_sim.kinematics.ecm_ik import ecm_ik_closed_form
from davinci_sim.kinematics.ik_base import POSITION_TOLERANCE, ROTATION_TOLERANCE, IKResult
from davinci_sim.kinematics.mtm_ik import mtm_ik_iterative
from davinci_sim.kinematics.psm_ik import psm_ik_closed_form, psm_ik_reference

Method = Literal["default", "closed_form", "reference"]

_SOLVERS = {
    # PSM: the dVRK itself uses the DLS ("reference"); the closed form gives the same answer
    # ~10x faster and exactly.
    ("PSM", "default"): psm_ik_closed_form,
    ("PSM", "closed_form"): psm_ik_closed_form,
    ("PSM", "reference"): psm_ik_reference,
    # ECM: the dVRK's own IK is the closed form, so it is also the reference.
    ("ECM", "default"): ecm_ik_closed_form,
    ("ECM", "closed_form"): ecm_ik_closed_form,
    ("ECM", "reference"): ecm_ik_closed_form,
    # MTM: the dVRK default ITERATIVE kind; its experimental CLOSED kind is not provided.
    ("MTM", "default"): mtm_ik_iterative,
    ("MTM", "reference"): mtm_ik_iterative,
}
_ARM_TYPES = {t for t, _ in _SOLVERS}


def inverse_kinematics(
    arm_kin: ArmKinematics,
    T_base_tip,
    q_seed,
    *,
    method: Method = "default",
    position_tolerance: float = POSITION_TOLERANCE,
    rotation_tolerance: float = ROTATION_TOLERANCE,
) -> IKResult:
    """Joint values that put the tip of ``arm_kin`` at ``T_base_tip``.

    Args:
        arm_kin: the arm (from :func:`~davinci_sim.kinematics.arms.load_arm`).
        T_base_tip: goal (4, 4) in the chain base frame (RCM for PSM/ECM, MTM base), m.
        q_seed: the arm's current joints (dof,), rad / m.
        method: ``"default"``, ``"closed_form"`` or ``"reference"`` (see ``_SOLVERS``).
        position_tolerance, rotation_tolerance: acceptance of the FK check (m, rad).

    Returns:
        IKResult; unreachable goals give ``success=False`` and a message, not an exception.

    Raises:
        ValueError: bad shapes / non-finite input, or a method the arm type does not have.
    """
    solver = _SOLVERS.get((arm_kin.arm_type, method))
    if solver is None and arm_kin.arm_type not in _ARM_TYPES and method != "closed_form":
        return dls_ik(
            arm_kin.chain,
            T_base_tip,
            q_seed,
            position_tolerance=position_tolerance,
            rotation_tolerance=rotation_tolerance,
        )
    if solver is None:
        known = sorted(m for (t, m) in _SOLVERS if t == arm_kin.arm_type)
        raise ValueError(
            f"no IK method {method!r} for arm type {arm_kin.arm_type!r}; available: {known}"
        )
    return solver(
        arm_kin.chain,
        T_base_tip,
        q_seed,
        position_tolerance=position_tolerance,
        rotation_tolerance=rotation_tolerance,
    )
