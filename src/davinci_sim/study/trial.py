"""One trial of a study: one synthetic trainee doing one repetition of a task in one fixture
condition, through the real simulator, console, teleoperation and haptic loop.

:func:`run_trial` builds a :class:`~davinci_sim.sim.simulation.Simulation` (PSM1, ECM, MTMR),
installs the console with the task's motion scale, waits for the teleoperation to follow,
puts a :class:`~davinci_sim.operators.TraineeHand` on the simulated MTMR and the condition's
fixture (:class:`~davinci_sim.haptics.fixture.FixtureField`) in the haptic loop, then ticks
at 1 kHz until the task is finished or the timeout (simulated time since the trainee took the
handle) passes. Every tick the tool tip (task frame), its distance to the path and the
guidance force the haptic loop requests for the MTM go through the task state machine
(:func:`~davinci_sim.tasks.task_step`) and a :class:`~davinci_sim.tasks.MetricsAccumulator`
(no trajectory is stored). A trial that times out is reported as unfinished, with the
metrics of the part it did.

The trial's randomness (motor noise and tremor of the trainee, the simulation's seed) is
keyed by (seed, subject, condition, repetition) only, so a trial's result does not depend on
which process runs it or when.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from davinci_sim.tasks import MetricsAccumulator, Phase, initial_state, load_task, task_step

#: Metric columns of a trial's row, in order (see :mod:`davinci_sim.tasks.metrics`).
METRICS = (
    "deviation_error",
    "completion_time",
    "path_length",
    "mean_speed",
    "peak_force",
    "mean_force",
    "time_outside",
    "clutch_count",
    "samples",
)


@dataclass(frozen=True)
class TrialSpec:
    """Everything one trial needs (picklable, sent to a worker process)."""

    task: str
    """Task name or path of a task file (:func:`~davinci_sim.tasks.load_task`)."""
    subject: int
    """Subject index in the population of :attr:`seed`."""
    condition: int
    """Index of the condition in the study's list."""
    B: float
    """Viscosity of the guidance, N·s/m."""
    G_max: float
    """Saturation of the guidance force, N."""
    repetition: int
    """Repetition in this condition, 1-based."""
    order: int
    """Position of this condition in the subject's order, 1-based."""
    practice: int
    """Practice count j ≥ 1 of the power law (all the trials of the subject so far, +1)."""
    seed: int
    timeout: float = 60.0
    """Simulated time allowed from taking the handle, s."""

    @property
    def key(self) -> tuple[int, int, int, int]:
        return (self.seed, self.subject, self.condition, self.repetition)


def condition_spec(B: float, G_max: float) -> dict:
    """A task fixture entry for the viscous guidance (B, G_max); none when both are 0."""
    if B == 0 and G_max == 0:
        return {"type": "none"}
    return {"type": "viscous", "B": float(B), "G_max": float(G_max)}


def run_trial(spec: TrialSpec) -> dict:
    """Run one trial; returns its row: the spec's fields, ``finished``, the metrics, and
    ``sim_time`` / ``wall_time`` (s) of the whole trial including the set-up."""
    from davinci_sim.console import SIMULATED_SYSTEM, install_console
    from davinci_sim.devices.simulated import SimulatedMTM
    from davinci_sim.haptics.fixture import FixtureField
    from davinci_sim.operators import SyntheticTrainee, sample_subjects
    from davinci_sim.operators.console import TraineeHand, hand_impedance
    from davinci_sim.sim.simulation import Simulation

    wall0 = time.perf_counter()
    task = load_task(spec.task if not Path(spec.task).suffix else Path(spec.task))
    params = sample_subjects(spec.subject + 1, seed=spec.seed).take([spec.subject])
    sim_seed = int(np.random.SeedSequence(list(spec.key)).generate_state(1)[0])
    sim = Simulation("psm1_ecm_mtmr", keyframe=task.teleop.keyframe, seed=sim_seed)
    mtm, psm = task.teleop.mtm, task.teleop.psm
    device = SimulatedMTM(sim, mtm, hand=hand_impedance(params))
    config = SIMULATED_SYSTEM.replace(align_mtm=False, scale=task.teleop.scale)
    console = install_console(
        sim,
        devices={mtm: device},
        teleop_config=config,
        operator_present=True,
        teleop_enabled=True,
    )
    teleop = console.psm_teleops[f"{mtm}_{psm}"]
    if not sim.run_until(teleop.is_following, 10.0):
        raise RuntimeError(f"trial {spec.key}: the teleoperation did not start following")
    T_cart_camera = sim.T_cart_camera()
    trainee = SyntheticTrainee(
        params,
        repetition=[spec.practice],
        path=task.path_in_camera(T_cart_camera),
        knots=task.marker_arc_lengths,
        hand_start=np.zeros((1, 3)),
        scale=task.teleop.scale,
        start_tolerance=task.start_tolerance,
        noise_keys=[spec.key],
    )
    hand = TraineeHand(trainee, device, sim.arms[psm], when=teleop.is_following)
    sim.components = {hand.name: hand, **sim.components}
    fixture = task.fixture(condition_spec(spec.B, spec.G_max))
    console.haptics.add_field(FixtureField(fixture, frame="world"), mtm=mtm, name="guidance")

    arm = sim.arms[psm]
    state = initial_state(1)
    acc = MetricsAccumulator(1, tube_radius=task.tube_radius)
    no_force = np.zeros(6)
    t_end = sim.time + spec.timeout
    path = task.path
    while sim.time < t_end:
        sim.tick()
        t = sim.time
        tip = (T_cart_camera @ arm.measured_cp().T)[:3, 3].reshape(1, 3)
        cp = path.closest_point(tip)
        state = task_step(
            state,
            t,
            np.linalg.norm(tip - task.start, axis=1),
            np.linalg.norm(tip - task.finish, axis=1),
            cp.arc_length,
            path_length=path.length,
            start_tolerance=task.start_tolerance,
            finish_tolerance=task.finish_tolerance,
            min_progress=task.min_progress,
        )
        phase = int(state.phase[0])
        if phase in (Phase.RUNNING, Phase.FINISHED):
            force = console.haptics.snapshot().requested.get(mtm, no_force)[:3]
            acc.update(np.array([True]), t, tip, cp.distance, force.reshape(1, 3), [False])
        if phase >= Phase.FINISHED:
            break
    result = acc.result()
    row = {
        "subject": spec.subject,
        "condition": spec.condition,
        "B": spec.B,
        "G_max": spec.G_max,
        "order": spec.order,
        "repetition": spec.repetition,
        "practice": spec.practice,
        "seed": spec.seed,
        "task": task.name,
        "finished": bool(state.phase[0] >= Phase.FINISHED),
    }
    for name in METRICS:
        value = getattr(result, name)[0]
        row[name] = int(value) if name in ("clutch_count", "samples") else float(value)
    row["sim_time"] = sim.time
    row["wall_time"] = time.perf_counter() - wall0
    sim.close()
    return row
