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
(simulated time since the trainee took the handle) passes. Every tick a
:class:`~davinci_sim.tasks.Sample` (the tool tip in the task frame, the guidance force the
haptic loop requests for the MTM) goes through a :class:`~davinci_sim.tasks.TaskMonitor`:
the task's state machine and its declared metrics (no trajectory is stored). A trial that does
not finish is reported as unfinished, with the metrics of the part it did. The study runs
its trials batched (:mod:`davinci_sim.study.batch`), checked against this engine.

The trial's randomness (motor noise and tremor of the trainee) is keyed by (seed, subject,
condition, repetition) only, so a trial's result does not depend on which process runs it,
when, or with which other trials.
"""

from __future__ import annotations

import json
import math
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
from davinci_sim.tasks import Phase, TaskMonitor, load_task
from davinci_sim.tasks.metrics import metric_row
from davinci_sim.tasks.session import live_sample
from davinci_sim.tasks.task import PathTask

#: Metric columns of a trial's row, in order: the study's task kind's declaration
#: (:data:`~davinci_sim.tasks.metrics.PATH_METRICS`; the synthetic trainee follows paths).
METRICS = tuple(m.name for m in PathTask.METRICS)


@dataclass(frozen=True)
class TrialSpec:
    """Everything one trial needs (picklable, sent to a worker process).

    The condition is a fixture entry of the task's kind (``fixture``, e.g. a task file's
    condition, :mod:`davinci_sim.haptics.kinds`); ``B`` and ``G_max`` alone stand for the
    seed's viscous law as printed (:func:`condition_spec`). ``B`` and ``G_max`` are the
    viscous entry's (NaN for other kinds); an adaptive entry's are the B that runs (its
    ``B``, set by the study's runner, :mod:`~davinci_sim.study.adaptive`; NaN before) and its
    G_max."""

    task: str
    """Task name or path of a task file (:func:`~davinci_sim.tasks.load_task`)."""
    subject: int
    """Subject index in the population of :attr:`seed`."""
    condition: int
    """Index of the condition in the study's list."""
    B: float | None = None
    """Viscosity of the guidance, N·s/m (viscous conditions; else NaN)."""
    G_max: float | None = None
    """Saturation of the guidance force, N (viscous conditions; else NaN)."""
    repetition: int = 1
    """Repetition in this condition, 1-based."""
    order: int = 1
    """Position of this condition in the subject's order, 1-based."""
    practice: int = 1
    """Practice count j ≥ 1 of the power law (all the trials of the subject so far, +1)."""
    seed: int = 0
    timeout: float = 60.0
    """Simulated time allowed from taking the handle, s."""
    fixture: dict | None = None
    """The condition's fixture entry as it runs (type, name, every parameter:
    :func:`~davinci_sim.haptics.kinds.resolve_fixture`)."""

    def __post_init__(self) -> None:
        from davinci_sim.haptics.kinds import resolve_fixture

        entry = self.fixture
        if entry is None:
            if self.B is None or self.G_max is None:
                raise ValueError("a trial needs a fixture entry, or B and G_max")
            entry = condition_spec(self.B, self.G_max)
        entry = resolve_fixture(entry)
        object.__setattr__(self, "fixture", entry)
        viscous = entry["type"] == "viscous"
        if entry["type"] == "adaptive":  # the B that runs (NaN until the study resolves it)
            values = {"B": entry.get("B", math.nan), "G_max": entry["G_max"]}
            for name, value in values.items():
                object.__setattr__(self, name, float(value))
            return
        for name in ("B", "G_max"):
            given, value = getattr(self, name), entry.get(name) if viscous else math.nan
            if given is not None and viscous and float(given) != value:
                raise ValueError(f"{name}={given!r} contradicts the fixture entry {entry!r}")
            object.__setattr__(self, name, float(value))

    block: str = "practice"
    """``practice`` (the condition's fixture) or ``retention`` (after the practice of
    :attr:`condition`, its fixture off: :attr:`fixture` is ``none``)."""
    own_practice: float | None = None
    """Practice count of the trainee's own correction (reliance on guidance,
    :class:`~davinci_sim.operators.params.Mechanisms`); None: :attr:`practice`."""
    condition_name: str | None = None
    """Name of :attr:`condition` when :attr:`fixture` is not its entry (a retention
    trial's practised condition); None: the fixture's name."""
    mechanisms: tuple[str, ...] = ()
    """The trainee mechanisms on (:data:`~davinci_sim.operators.params.MECHANISMS`)."""
    population: str = "trainee"
    """Synthetic population of the subject (:data:`~davinci_sim.operators.params.POPULATIONS`:
    ``trainee``, or ``expert`` for the reference of the pass marks)."""

    @property
    def key(self) -> tuple[int, ...]:
        """The seed of the trial's noise: (seed, subject, condition, repetition), and a
        fifth entry 1 for a retention trial (its noise differs from the practice's)."""
        base = (self.seed, self.subject, self.condition, self.repetition)
        return base if self.block == "practice" else (*base, 1)


def condition_spec(B: float, G_max: float, *, transition: float = 0.0) -> dict:
    """The viscous fixture entry of (B, G_max): the seed's law as printed (``transition``
    0, the default), or with an on-path ramp of ``transition`` m. (B, G_max) = (0, 0) is
    the law with no force at all (the unassisted condition)."""
    return {"type": "viscous", "B": float(B), "G_max": float(G_max),
            "transition": float(transition)}  # fmt: skip


def study_scene(task, joint_errors=()) -> SceneConfig:
    """The scene of a study trial: the task's PSM, the ECM (camera frame) and the task's MTM
    with the console; no patient (the path floats in free space, nothing to touch), which
    also spares the contact search; ``joint_errors``: the robot's inaccuracy
    (:attr:`SceneConfig.joint_errors`, none by default)."""
    return SceneConfig(arms=(task.teleop.psm, "ECM", task.teleop.mtm), include_patient=False,
                       joint_errors=joint_errors)  # fmt: skip


def trial_description(task: PathTask, *, seed: int = 0, joint_errors=()):
    """The system of a study trial: :func:`study_scene` at the task's keyframe, the console
    with a simulated MTM at the task's motion scale (no MTM alignment: the hand holds the
    handle as it is), the operator present and teleoperation enabled; no runner (the
    engines tick it), no task session (the engines measure) and no drawing."""
    from davinci_sim.console import SIMULATED_SYSTEM
    from davinci_sim.system import ConsoleDescription, SystemDescription

    console = ConsoleDescription(
        teleop=SIMULATED_SYSTEM.replace(align_mtm=False),
        scale=task.teleop.scale,
        operator_present=True,
        teleop_enabled=True,
    )
    return SystemDescription(
        scene=study_scene(task, joint_errors), keyframe=task.teleop.keyframe, seed=seed,
        console=console,
        runner="none",
    )  # fmt: skip


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
    start = np.asarray(task.start, dtype=float).tobytes()
    return (type(task).__name__, task.name, task.frame, start, repr(task.teleop), int(seed))


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


def build_setup(task: PathTask, *, seed: int = 0, joint_errors=()) -> TrialSetup:
    """Build the study scene and bring it to the start of a trial, the same for every trial:

    1. enable and home the PSM, then move its tool tip to point 1 (``move_cp``, orientation
       kept): a trial starts where the task does, instead of spending simulated time on the
       reach (which is not measured);
    2. install the console with the task's motion scale (no MTM alignment: the hand holds
       the handle as it is) and wait until the teleoperation follows.

    Raises:
        RuntimeError: if the PSM cannot reach point 1 or the teleoperation does not start.
    """
    from davinci_sim.system import install_console_of, new_simulation

    description = trial_description(task, seed=seed, joint_errors=joint_errors)
    sim = new_simulation(description)
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
    console = install_console_of(sim, description)
    teleop = console.psm_teleops[f"{mtm}_{psm_name}"]
    device = teleop.device
    if not sim.run_until(teleop.is_following, 30.0):
        raise RuntimeError("the teleoperation did not start following")
    return TrialSetup(sim, console, device, teleop, T_world_camera, T_task_camera)


def trial_inputs(specs: list[TrialSpec], task: PathTask, T_world_camera, hand_start):
    """The trainees of ``specs`` (one batch, one task and seed): ``(params, trainee)``."""
    from davinci_sim.operators import SyntheticTrainee
    from davinci_sim.operators.params import Mechanisms, sample_population
    from davinci_sim.operators.wrist import WristTurns

    seeds = {s.seed for s in specs}
    if len(seeds) != 1:
        raise ValueError(f"one batch of trials needs one seed, got {sorted(seeds)}")
    populations = {s.population for s in specs}
    if len(populations) != 1:
        raise ValueError(f"one batch of trials needs one population, got {sorted(populations)}")
    mechanisms = {tuple(sorted(s.mechanisms)) for s in specs}
    if len(mechanisms) != 1:
        raise ValueError(f"one batch of trials needs one set of mechanisms, got {mechanisms}")
    n = max(s.subject for s in specs) + 1
    subjects = sample_population(populations.pop(), n, seed=seeds.pop())
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
        own_practice=[s.practice if s.own_practice is None else s.own_practice for s in specs],
        mechanisms=Mechanisms.named(mechanisms.pop()),
        wrist=WristTurns.of(task.carry, task.T_task_camera(T_world_camera)),
    )
    return params, trainee


def trial_row(spec: TrialSpec, task: PathTask, result, i: int, finished: bool) -> dict:
    """The CSV row of trial ``i`` of a batch's metrics ``result`` (an (n,) array per metric
    name) without timings: the spec's fields, then ``task``'s declared metrics, then the
    attempt's ``score`` and ``passed`` (:meth:`~davinci_sim.tasks.base.Task.score`)."""
    row = spec_columns(spec, task.name, finished)
    row.update(metric_row(task.METRICS, result, i))
    row.update(task.score(row, bool(finished)))
    return row


def spec_columns(spec: TrialSpec, task_name: str, finished: bool) -> dict:
    """The columns of a trial's row before its metrics: the spec's fields, the task's name
    and whether the attempt finished."""
    from davinci_sim.haptics.kinds import describe_fixture

    params = {k: v for k, v in spec.fixture.items() if k != "name"}
    return {
        "subject": spec.subject,
        "condition": spec.condition,
        "condition_name": spec.condition_name or spec.fixture.get("name", ""),
        "B": spec.B,
        "G_max": spec.G_max,
        "fixture": json.dumps(params, sort_keys=True),
        "law": describe_fixture(spec.fixture),
        "order": spec.order,
        "block": spec.block,
        "repetition": spec.repetition,
        "practice": spec.practice,
        "own_practice": spec.practice if spec.own_practice is None else spec.own_practice,
        "mechanisms": "+".join(spec.mechanisms),
        "seed": spec.seed,
        "task": task_name,
        "finished": bool(finished),
    }


def load_spec_task(spec: TrialSpec) -> PathTask:
    return load_task(spec.task if not Path(spec.task).suffix else Path(spec.task))


def run_trial(spec: TrialSpec) -> dict:
    """Run one trial on the live simulator (the reference engine; the study batches trials
    with :mod:`davinci_sim.study.batch`, which must give the same results).

    Returns its row: the spec's fields, ``finished``, the metrics, ``sim_time`` (s, from
    the trainee taking the handle to the end) and ``wall_time`` (s, set-up included). A
    needle exercise's trial is :func:`~davinci_sim.study.console_trial.run_console_trial`'s."""
    from davinci_sim.haptics.fixture import FixtureField
    from davinci_sim.operators.console import TraineeHand, hand_impedance

    wall0 = time.perf_counter()
    task = load_spec_task(spec)
    if task.kind != "path":  # (a needle exercise: its trainee works both MTMs)
        from davinci_sim.study.console_trial import run_console_trial

        return run_console_trial(spec)
    setup = setup_trial(task)
    sim, device, teleop = setup.sim, setup.device, setup.teleop
    mtm, psm = task.teleop.mtm, task.teleop.psm
    T_world_camera = setup.T_world_camera
    params, trainee = trial_inputs([spec], task, T_world_camera, np.zeros(3))
    device.hand = hand_impedance(params)
    hand = TraineeHand(trainee, device, sim.arms[psm])
    sim.add_component(hand, before=next(iter(sim.components)))  # the hand acts first
    fixture = task.fixture(spec.fixture)
    setup.console.haptics.add_field(
        FixtureField(fixture, frame=task.frame), mtm=mtm, name="guidance"
    )

    monitor = TaskMonitor(task)
    t_start = sim.time
    t_end = t_start + spec.timeout
    while sim.time < t_end and teleop.is_following():
        sim.tick()
        sample = live_sample(task, setup.T_task_camera, teleop, setup.console, sim.time)
        if monitor.observe(sample)[0] >= Phase.FINISHED:
            break
    finished = monitor.phase >= Phase.FINISHED
    row = trial_row(spec, task, monitor.metrics.result(), 0, finished)
    row["sim_time"] = sim.time - t_start
    row["wall_time"] = time.perf_counter() - wall0
    sim.close()
    return row
