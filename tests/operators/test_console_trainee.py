"""A synthetic trainee at the simulated console does the seed task through the real
teleoperation and haptic loop, with the viscous fixture as a force field."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from davinci_sim.console import SIMULATED_SYSTEM, install_console
from davinci_sim.devices.simulated import SimulatedMTM
from davinci_sim.haptics.fixture import FixtureField
from davinci_sim.operators import SyntheticTrainee, sample_subjects
from davinci_sim.operators.console import TraineeHand, hand_impedance
from davinci_sim.sim.simulation import Simulation
from davinci_sim.tasks import Phase, TaskMonitor, load_task


def test_trainee_completes_the_seed_task_through_the_console():
    task = load_task("seed_path")
    sim = Simulation("psm1_ecm_mtmr", keyframe=task.teleop.keyframe)
    n = 1
    p = dataclasses.replace(sample_subjects(n, seed=2), speed=np.full(n, 0.05))
    device = SimulatedMTM(sim, "MTMR", hand=hand_impedance(p))
    config = SIMULATED_SYSTEM.replace(align_mtm=False, scale=task.teleop.scale)
    console = install_console(
        sim,
        devices={"MTMR": device},
        teleop_config=config,
        operator_present=True,
        teleop_enabled=True,
    )
    teleop = console.psm_teleops["MTMR_PSM1"]
    assert sim.run_until(teleop.is_following, 10)
    T_cart_camera = sim.T_cart_camera()
    trainee = SyntheticTrainee(
        p,
        repetition=[10],
        path=task.path_in_camera(T_cart_camera),
        knots=task.marker_arc_lengths,
        hand_start=np.zeros((1, 3)),
        scale=task.teleop.scale,
        start_tolerance=task.start_tolerance,
        noise_keys=[(3, 0)],
    )
    hand = TraineeHand(trainee, device, sim.arms["PSM1"], when=teleop.is_following)
    sim.add_component(hand, before=next(iter(sim.components)))
    field = FixtureField(task.fixture("B=40"), frame="world")
    console.haptics.add_field(field, mtm="MTMR", name="guidance")
    monitor = TaskMonitor(task)
    peak = 0.0
    while sim.time < 12.0 and monitor.phase < Phase.FINISHED:
        sim.step()
        tip = (T_cart_camera @ sim.arms["PSM1"].measured_cp().T)[:3, 3]
        force = console.haptics.snapshot().requested.get("MTMR", np.zeros(6))[:3]
        peak = max(peak, float(np.linalg.norm(device.wrench()[:3])))
        monitor.update(sim.time, tip, force)
    assert monitor.phase == Phase.FINISHED, (monitor.phase, trainee.phase)
    r = monitor.results
    # Within the task's tolerance tube: a fast trainee (50 mm/s, 3x the median) with the
    # calibrated signal-dependent noise, which grows with the command (operators.params).
    assert r.deviation_error[0] < task.tube_radius
    assert r.path_length[0] > 0.9 * task.path.length - 2 * task.start_tolerance
    assert 0.0 < r.peak_force[0] <= 5.0 + 1e-9  # the guidance acted, capped at G_max
    assert peak > 0.0  # and reached the MTM
    with pytest.raises(ValueError, match="hand"):
        TraineeHand(trainee, SimulatedMTM(sim, "MTMR", name="other"), sim.arms["PSM1"])
