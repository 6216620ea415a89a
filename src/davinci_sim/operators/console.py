"""A synthetic trainee at the simulated console: its hand on a simulated MTM.

:class:`TraineeHand` is a simulation component (like :class:`~davinci_sim.devices.HandScript`)
that, every tick before the MTM device reads its input, shows one trainee (a
:class:`~davinci_sim.operators.SyntheticTrainee` of one trial) the PSM's tool tip as the
endoscope sees it (``measured_cp``, camera frame) and applies the trainee's hand to the
MTM handle through the device's simulated hand: the hand's target is the trainee's
equilibrium point and the device's hand impedance is the subject's
(:func:`hand_impedance`: the limb's mass rides on the handle, its stiffness and damping
pull it), plus a push of the rest of the trainee's force (D·ẋ_eq, the inertia
feed-forward and the tremor). The MTM's own dynamics integrate the motion, the console's
teleoperation moves the PSM, and the haptic loop's force fields (e.g. a
:class:`~davinci_sim.haptics.fixture.FixtureField`) push back on the handle: the same code
path as a person's hand. One trial per simulation; for many trials at once see the study.
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np

from davinci_sim.devices.hand import HandImpedance
from davinci_sim.devices.simulated import SimulatedMTM
from davinci_sim.operators.params import SubjectParams
from davinci_sim.operators.trainee import SyntheticTrainee


def hand_impedance(params: SubjectParams, index: int = 0) -> HandImpedance:
    """The simulated hand of subject ``index``: its limb mass, stiffness and damping (the
    wrist's rotational values stay the device's defaults)."""
    return HandImpedance(
        stiffness=float(params.stiffness[index]),
        damping=float(params.damping[index]),
        mass=float(params.mass[index]),
    )


class TraineeHand:
    """Component driving ``device`` with ``trainee`` (n = 1), watching ``psm``'s tool tip.

    Args:
        trainee: one trial, not stepped yet, its path in the camera frame; its hand starts
            where the handle is when this component starts.
        device: the simulated MTM (create it with ``hand=hand_impedance(params)``).
        psm: the PSM arm the MTM teleoperates.
        when: start condition checked every tick (e.g. the teleoperation follows).
        name: component name (default ``"<device>/trainee"``).
    """

    def __init__(
        self, trainee: SyntheticTrainee, device: SimulatedMTM, psm, *, when=None, name=None
    ):
        if trainee.n != 1:
            raise ValueError(
                f"a TraineeHand drives one MTM: the trainee must have n = 1, got {trainee.n}"
            )
        K, D = float(trainee.params.stiffness[0]), float(trainee.params.damping[0])
        if not (np.isclose(device.hand.stiffness, K) and np.isclose(device.hand.damping, D)):
            raise ValueError(
                f"the device's hand ({device.hand.stiffness} N/m, {device.hand.damping} N·s/m) "
                f"is not the trainee's ({K} N/m, {D} N·s/m): use hand=hand_impedance(params)"
            )
        self.trainee = trainee
        self.device = device
        self.psm = psm
        self.when = when
        self.name = name or f"{device.name}/trainee"
        self.started = False
        self.R_hand0 = np.eye(3)[None]
        """The handle's orientation when the hand took it (1, 3, 3), HRSV."""

    def pre_step(self, t: float) -> None:
        if not self.started:
            if self.when is not None and not self.when():
                return
            self.started = True
            handle = self.device.input().position
            self.trainee.set_hand_start(handle[None])
            self.device.grasp(handle)
            self.R_hand0 = self.device.hand_target()[None, :3, :3]  # (what the grasp holds)
        tr = self.trainee
        tip = self.psm.measured_cp().T[:3, 3]
        t = tr.time  # (the step's: command moves it on)
        x_eq = tr.command(tr.dt, tip[None], self.device.wrench()[None, :3])
        K, D = float(tr.stiffness[0]), float(tr.damping[0])
        hand = self.device.hand
        if K != hand.stiffness or D != hand.damping:  # co-contraction (Mechanisms)
            self.device.hand = dataclasses.replace(hand, stiffness=K, damping=D)
        if tr.wrist is None:
            self.device.move_hand(x_eq[0])
        else:  # the hand turns the handle along the path (operators.wrist)
            T = np.eye(4)
            T[:3, :3] = tr.hand_rotations(t, self.R_hand0)[0]
            T[:3, 3] = x_eq[0]
            self.device.move_hand(T)
        self.device.push(tr.push_force()[0])

    def snapshot(self) -> dict:
        return {"started": self.started, "phase": int(self.trainee.phase[0])}

    def get_state(self) -> dict:
        """Whether the hand has started, and the trainee (deep-copied whole: a pure-numpy
        object with no reference to the simulation, whose state is its plan, delays,
        filters and noise generators)."""
        return {"started": self.started, "trainee": copy.deepcopy(self.trainee),
                "R_hand0": self.R_hand0.copy()}  # fmt: skip

    def set_state(self, state: dict) -> None:
        self.started = bool(state["started"])
        self.trainee = copy.deepcopy(state["trainee"])
        self.R_hand0 = np.array(state.get("R_hand0", np.eye(3)[None]), dtype=float)
