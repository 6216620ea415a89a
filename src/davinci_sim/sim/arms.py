"""The arm types of the simulation: PSM, ECM, MTM and the setup-joint arms."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from davinci_sim.kinematics import fk
from davinci_sim.kinematics.arms import ArmKinematics, SUJArmKinematics
from davinci_sim.kinematics.chain import DHChain
from davinci_sim.sim.arm import Arm
from davinci_sim.sim.jaw import Jaw
from davinci_sim.sim.types import CommandResult

if TYPE_CHECKING:
    from davinci_sim.sim.simulation import Simulation

# dvrk.md 1.7: SafeDistanceFromRCM 45 mm minus SafeDistanceFromRCMBuffer 2 mm, measured for
# the frame at the end of the shaft (link 4).
PSM_SAFE_CARTESIAN_DISTANCE = 0.045 - 0.002
# dvrk.md 2.4: the ECM allows Cartesian control once insertion > 50 mm.
ECM_SAFE_CARTESIAN_INSERTION = 0.050


class PSM(Arm):
    """Patient-side manipulator with its instrument's jaw (``psm.jaw``)."""

    def __init__(self, name: str, kin: ArmKinematics, sim: Simulation) -> None:
        super().__init__(name, kin, sim)
        assert kin.jaw is not None
        self.jaw = Jaw(self, kin.jaw, "jaw", kin.jaw_v_max, kin.jaw_a_max)
        self._shaft_chain = self.chain.truncated(4)

    def shaft_end_distance(self) -> float:
        """Distance (m) from the RCM to the end of the shaft (link-4 frame), dvrk.md 1.7."""
        q = self.measured_jp()[:4]
        return float(np.linalg.norm(fk.forward_kinematics(self._shaft_chain, q)[:3, 3]))

    def _cartesian_unsafe(self) -> str:
        d = self.shaft_end_distance()
        if d < PSM_SAFE_CARTESIAN_DISTANCE:
            return (
                f"tool needs to be inserted past the cannula for Cartesian control: shaft end is "
                f"{1000 * d:.1f} mm from the RCM, needs {1000 * PSM_SAFE_CARTESIAN_DISTANCE:.0f} mm"
            )
        return ""

    def _hold_here(self) -> None:
        super()._hold_here()
        self.jaw._hold()

    def _start_homing(self) -> None:
        super()._start_homing()
        self.jaw._start(0.0)  # the jaw is the 7th PID joint and homes with the arm

    def _pre_step(self, t: float) -> None:
        super()._pre_step(t)
        self.jaw._pre_step(t)

    def is_busy(self) -> bool:
        return super().is_busy() or self.jaw.is_busy()

    def insert_jp(self, depth: float) -> CommandResult:
        """``move_jp`` with only the insertion joint changed (dvrk_python ``insert_jp``)."""
        goal = self.setpoint_jp()
        goal[2] = depth
        return self.move_jp(goal)


class ECM(Arm):
    """Endoscope camera manipulator with a straight Classic SD scope (dvrk.md 1.4)."""

    def _cartesian_unsafe(self) -> str:
        ins = self.measured_jp()[2]
        if ins <= ECM_SAFE_CARTESIAN_INSERTION:
            return (
                f"endoscope needs to be inserted past the cannula for Cartesian control: "
                f"insertion {1000 * ins:.1f} mm, "
                f"needs > {1000 * ECM_SAFE_CARTESIAN_INSERTION:.0f} mm"
            )
        return ""

    def insert_jp(self, depth: float) -> CommandResult:
        goal = self.setpoint_jp()
        goal[2] = depth
        return self.move_jp(goal)


class MTM(Arm):
    """Master tool manipulator of the surgeon console, with its gripper (``mtm.gripper``).

    The gripper is an input: on the real console the operator's fingers set it. Here
    ``mtm.gripper.servo_jp`` stands for the fingers (simulation only); ``gripper.measured_js``
    is what the dVRK publishes.
    """

    def __init__(self, name: str, kin: ArmKinematics, sim: Simulation) -> None:
        super().__init__(name, kin, sim)
        assert kin.gripper is not None
        # The fingers are not the arm: they move whatever the arm's state.
        self.gripper = Jaw(self, kin.gripper, "gripper", 4 * np.pi, 8 * np.pi, requires_ready=False)

    def _pre_step(self, t: float) -> None:
        super()._pre_step(t)
        self.gripper._pre_step(t)


def suj_arm_kinematics(suj: SUJArmKinematics) -> ArmKinematics:
    """SUJ arm as an :class:`ArmKinematics`: the tool is ``SUJ_tip_to_tool_origin`` (dvrk.md 1.6).

    The dVRK moves simulated SUJ joints directly; here they move through dynamics, so
    ``move_jp`` needs limits: 0.1 m/s and 0.5 rad/s, accelerations the same per s (our choice).
    """
    chain = DHChain(suj.chain.name, suj.chain.convention, suj.chain.joints, suj.T_sujtip_rcm)
    n = chain.dof
    v = np.where(chain.revolute, 0.5, 0.1)
    return ArmKinematics(
        arm_type="SUJ",  # type: ignore[arg-type]
        chain=chain,
        home=suj.simulated_position,
        v_max=v,
        a_max=v,
        goal_tolerance=np.full(n, 1e-3),
    )


class SUJArm(Arm):
    """One setup-joint arm (``SUJ/PSM1`` …): ``measured_cp`` is the carried arm's RCM in the cart.

    SUJ arms start ENABLED and homed and ``home`` does not move them: they are passive,
    braked arms on the real system. ``servo_jp``/``move_jp`` move them (simulation only, as
    on the dVRK, dvrk.md 1.6).
    """

    def __init__(self, name: str, suj: SUJArmKinematics, sim: Simulation) -> None:
        super().__init__(name, suj_arm_kinematics(suj), sim)
        self.suj = suj
        self._state = "ENABLED"
        self._homed = True

    def _start_homing(self) -> None:
        # Setup joints are passive and braked: homing them is not a motion.
        self._homed = True
        self._publish_state()
