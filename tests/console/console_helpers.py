"""Shared set-up of the console tests: a light scene with a console, and waiting helpers."""

from __future__ import annotations

import numpy as np

from davinci_sim.console import install_console
from davinci_sim.model.config import SceneConfig
from davinci_sim.sim.simulation import Simulation

#: PSM1 + ECM + both MTMs, no patient: the ECM teleoperation needs both MTMs.
TWO_MTM_SCENE = SceneConfig(arms=("PSM1", "ECM", "MTML", "MTMR"), include_patient=False)


def teleop_sim(scene="psm1_ecm_mtmr", *, start=True, **options):
    """A simulation (surgical view) with a console; with ``start`` the operator is present,
    teleoperation is enabled and MTMR_PSM1 follows, the hand holding the handle."""
    sim = Simulation(scene, keyframe="surgical")
    console = install_console(sim, **options)
    if start:
        console.emulate_operator_present([1])
        console.teleop_enable(True)
        teleop = console.psm_teleops["MTMR_PSM1"]
        assert sim.run_until(teleop.is_following, 10), teleop.current_state()
        sim.components["MTMR/device"].grasp()
    return sim, console


def events_of(channels, *names):
    """A list collecting ``(event, payload)`` of ``channels`` for the given event names."""
    out: list = []
    channels.subscribe(lambda ev, payload: out.append((ev, payload)) if ev in names else None)
    return out


def rotation_about(axis, angle: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
