"""One trial of a study: one synthetic trainee doing one repetition of a task in one fixture
condition, through the real simulator, console, teleoperation and haptic loop.

:func:`setup_trial` brings a :class:`~davinci_sim.sim.simulation.Simulation` of the study
scene (the task's PSM and MTM, the ECM; :func:`study_scene`) to the start of a trial: PSM
homed and its tool at point 1, console installed with the task's motion scale, the
teleoperation following. The start is the same for every trial: it is built once per
process and task (:func:`build_setup`) and each later trial starts from its saved state
(:meth:`Simulation.set_state <davinci_sim.sim.simulation.Simulation.set_state>`).

:func:`run_trial` is the live engine, one simulation per trial: it puts a
:class:`~davinci_sim.operators.TraineeHand` on the simulated MTM and the condition's fixture
(:class:`~davinci_sim.haptics.fixture.FixtureField`) in the haptic loop, then ticks at
1 kHz until the task is finished, the teleoperation stops (a fault) or the timeout
(simulated time since the trainee took the handle) passes. Every tick the tool tip (task
frame), its distance to the path and the guidance force the haptic loop requests for the MTM
go through the task state machine (:func:`~davinci_sim.tasks.state.task_sample`) and a
:class:`~davinci_sim.tasks.MetricsAccumulator` (no trajectory is stored). A trial that does
not finish is reported as unfinished, with the metrics of the part it did. The study runs
its trials batched (:mod:`davinci_sim.study.batch`), checked against this engine.

The trial's randomness (motor noise and tremor of the trainee) is keyed by (seed, subject,
condition, repetition) only, so a trial's result does not depend on which process runs it,
when, or with which other trials.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from davinci_sim.console.console import Console
from davinci_sim.console.teleop_psm import TeleopPSM
from davinci_sim.devices.simulated import SimulatedMTM
from davinci_sim.model.config import SceneConfig
from davinci_sim.sim.simulation import Simulation
from davinci_sim.sim.state import SimState
from davinci_sim.tasks import MetricsAccumulator, Phase, initial_state, load_task
from davinci_sim.tasks.state import task_sample
from davinci_sim.tasks.task import PathTask

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


def study_scene(task) -> SceneConfig:
    """The scene of a study trial: the task's PSM, the ECM (camera frame) and the task's MTM
    with the console; no patient (the path floats in free space, nothing to touch), which
    also spares the contact search."""
    return SceneConfig(arms=(task.teleop.psm, "ECM", task.teleop.mtm), include_patient=False)


@dataclass
class TrialSetup:
    """A simulation ready for a trial: the teleoperation follows and the tool is at point 1."""

    sim: Simulation
    console: Console
    device: SimulatedMTM
    teleop: TeleopPSM
    T_world_camera: np.ndarray
    """The camera (ECM tip) in the world (cart) frame: fixed during a trial."""
    T_task_camera: np.ndarray
    """The camera in the task's frame (:meth:`PathTask.T_task_camera`)."""


#: Set-ups built in this process, by (task, seed): (the set-up, its start state). Building
#: one compiles the model and runs ~1,200 ticks; restoring its start state takes
#: microseconds (:meth:`Simulation.set_state`).
_SETUPS: dict[tuple, tuple[TrialSetup, SimState]] = {}
#: At most this many set-ups are kept (least recently used dropped): a study has one task.
SETUP_CACHE_SIZE = 4


def setup_trial(task: PathTask, *, seed: int = 0) -> TrialSetup:
    """A simulation at the start of a trial of ``task`` (see :func:`build_setup`): built once
    per process and task, then restored to its saved start state for each later call.

    The set-up is shared: each call puts the same simulation back at the start (components
    and haptic force fields added since are removed, everything else restored), so a caller
    must be done with the set-up a previous call returned.
    """
    key = _setup_key(task, seed)
    entry = _SETUPS.pop(key, None)
    if entry is not None and not _restore(*entry):
        entry = None  # changed beyond what a restore puts back: build a new one
    if entry is None:
        setup = build_setup(task, seed=seed)
        entry = (setup, setup.sim.get_state())
    _SETUPS[key] = entry  # most recently used last
    while len(_SETUPS) > SETUP_CACHE_SIZE:
        del _SETUPS[next(iter(_SETUPS))]
    return entry[0]


def _setup_key(task: PathTask, seed: int) -> tuple:
    # What the set-up depends on: the arms and keyframe, the scale, point 1 and its frame.
    return (task.name, task.frame, task.waypoints.tobytes(), repr(task.teleop), int(seed))


def _restore(setup: TrialSetup, state: SimState) -> bool:
    """Put ``setup`` back in its start ``state``: drop components and force fields added
    since, then :meth:`Simulation.set_state`. False if that is not possible."""
    sim, haptics = setup.sim, setup.console.haptics
    saved = dict(state.components)
    for name in [n for n in sim.components if n not in saved]:
        sim.remove_component(name)
    fields = saved.get(haptics.name, {}).get("fields", {})
    for name in [f for f in haptics.field_names() if f not in fields]:
        haptics.remove_field(name)
    try:
        sim.set_state(state)
    except (TypeError, ValueError):
        return False
    return True


def build_setup(task: PathTask, *, seed: int = 0) -> TrialSetup:
    """Build the study scene and bring it to the start of a trial, the same for every trial:

    1. enable and home the PSM, then move its tool tip to point 1 (``move_cp``, orientation
       kept): a trial starts where the task does, instead of spending simulated time on the
       reach (which is not measured);
    2. install the console with the task's motion scale (no MTM alignment: the hand holds
       the handle as it is) and wait until the teleoperation follows.

    Raises:
        RuntimeError: if the PSM cannot reach point 1 or the teleoperation does not start.
    """
    from davinci_sim.console import SIMULATED_SYSTEM, install_console

    sim = Simulation(study_scene(task), keyframe=task.teleop.keyframe, seed=seed)
    mtm, psm_name = task.teleop.mtm, task.teleop.psm
    psm = sim.arms[psm_name]
    psm.state_command("enable")
    psm.state_command("home")
    if not sim.run_until(lambda: psm.is_homed() and not psm.is_busy(), 30.0):
        raise RuntimeError(f"{psm_name} did not home")
    T_world_camera = sim.T_cart_camera().copy()
    T_task_camera = task.T_task_camera(T_world_camera)
    goal = psm.setpoint_cp().T.copy()
    goal[:3, 3] = (np.linalg.inv(T_task_camera) @ np.append(task.start, 1.0))[:3]
    result = psm.move_cp(goal)
    if not result or not sim.run_until(lambda: not psm.is_busy(), 30.0):
        raise RuntimeError(f"{psm_name} cannot reach point 1 of {task.name}: {result.message}")
    device = SimulatedMTM(sim, mtm)
    config = SIMULATED_SYSTEM.replace(align_mtm=False, scale=task.teleop.scale)
    console = install_console(
        sim,
        devices={mtm: device},
        teleop_config=config,
        operator_present=True,
        teleop_enabled=True,
    )
    teleop = console.psm_teleops[f"{mtm}_{psm_name}"]
    if not sim.run_until(teleop.is_following, 30.0):
        raise RuntimeError("the teleoperation did not start following")
    return TrialSetup(sim, console, device, teleop, T_world_camera, T_task_camera)


def trial_inputs(specs: list[TrialSpec], task: PathTask, T_world_camera, hand_start):
    """The trainees of ``specs`` (one batch, one task and seed): ``(params, trainee)``."""
    from davinci_sim.operators import SyntheticTrainee, sample_subjects

    seeds = {s.seed for s in specs}
    if len(seeds) != 1:
        raise ValueError(f"one batch of trials needs one seed, got {sorted(seeds)}")
    subjects = sample_subjects(max(s.subject for s in specs) + 1, seed=seeds.pop())
    params = subjects.take([s.subject for s in specs])
    trainee = SyntheticTrainee(
        params,
        repetition=[s.practice for s in specs],
        path=task.path_in_camera(T_world_camera),
        knots=task.marker_arc_lengths,
        hand_start=np.broadcast_to(np.asarray(hand_start, dtype=float), (len(specs), 3)),
        scale=task.teleop.scale,
        start_tolerance=task.start_tolerance,
        noise_keys=[s.key for s in specs],
    )
    return params, trainee


def trial_row(spec: TrialSpec, task: PathTask, result, i: int, finished: bool) -> dict:
    """The CSV row of trial ``i`` of a batch's metrics ``result`` (without timings)."""
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
        "finished": bool(finished),
    }
    for name in METRICS:
        value = getattr(result, name)[i]
        row[name] = int(value) if name in ("clutch_count", "samples") else float(value)
    return row


def load_spec_task(spec: TrialSpec) -> PathTask:
    return load_task(spec.task if not Path(spec.task).suffix else Path(spec.task))


def run_trial(spec: TrialSpec) -> dict:
    """Run one trial on the live simulator (the reference engine; the study batches trials
    with :mod:`davinci_sim.study.batch`, which must give the same results).

    Returns its row: the spec's fields, ``finished``, the metrics, ``sim_time`` (s, from
    the trainee taking the handle to the end) and ``wall_time`` (s, set-up included)."""
    from davinci_sim.haptics.fixture import FixtureField
    from davinci_sim.operators.console import TraineeHand, hand_impedance

    wall0 = time.perf_counter()
    task = load_spec_task(spec)
    setup = setup_trial(task)
    sim, device, teleop = setup.sim, setup.device, setup.teleop
    mtm, psm = task.teleop.mtm, task.teleop.psm
    T_world_camera = setup.T_world_camera
    params, trainee = trial_inputs([spec], task, T_world_camera, np.zeros(3))
    device.hand = hand_impedance(params)
    hand = TraineeHand(trainee, device, sim.arms[psm])
    sim.add_component(hand, before=next(iter(sim.components)))  # the hand acts first
    fixture = task.fixture(condition_spec(spec.B, spec.G_max))
    setup.console.haptics.add_field(
        FixtureField(fixture, frame=task.frame), mtm=mtm, name="guidance"
    )

    arm = sim.arms[psm]
    state = initial_state(1)
    acc = MetricsAccumulator(1, tube_radius=task.tube_radius)
    no_force = np.zeros(6)
    t_start = sim.time
    t_end = t_start + spec.timeout
    while sim.time < t_end and teleop.is_following():
        sim.tick()
        t = sim.time
        tip = (setup.T_task_camera @ arm.measured_cp().T)[:3, 3].reshape(1, 3)
        state, cp = task_sample(state, task, t, tip)
        phase = int(state.phase[0])
        if phase in (Phase.RUNNING, Phase.FINISHED):
            force = setup.console.haptics.snapshot().requested.get(mtm, no_force)[:3]
            acc.update(np.array([True]), t, tip, cp.distance, force.reshape(1, 3), [False])
        if phase >= Phase.FINISHED:
            break
    row = trial_row(spec, task, acc.result(), 0, state.phase[0] >= Phase.FINISHED)
    row["sim_time"] = sim.time - t_start
    row["wall_time"] = time.perf_counter() - wall0
    sim.close()
    return row
