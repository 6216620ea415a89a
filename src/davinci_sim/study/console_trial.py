"""A study trial of a needle exercise: a synthetic trainee does it with its hands on the MTMs.

The study's path trainees (:mod:`davinci_sim.operators`) follow a path; the needle
exercises need grasps, hand-offs and turns of the wrist. Their trainee is the scripted
expert's plan (:mod:`davinci_sim.study.experts`: the same reaches, grasps and turns, each
reach ending off its aim by the subject's own motor noise and corrected by what it sees)
made by one subject of the study's population (:class:`~davinci_sim.study.experts.Motor`
of the subject's parameters at its practice count), through the console as a person does:

* :class:`ConsoleStreamer` turns each setpoint of a PSM into the target of the simulated
  hand on the MTM that teleoperates it (the inverse of the following law,
  :func:`~davinci_sim.console.teleop_math.lead_pose`, with the teleoperation's anchors), and
  each jaw angle into a squeeze of the MTM's gripper (the inverse of the jaw mapping);
* the hands hold the handles with the subject's limb impedance
  (:func:`~davinci_sim.operators.console.hand_impedance`); the MTMs' dynamics, the
  teleoperations (scale, alignment offset, jaw following) and the haptic loop's fields act
  between the hand and the tool; the condition's fixture pushes on the task's MTM
  (the driving instrument's: :meth:`NeedleDriveTask.guidance
  <davinci_sim.tasks.needle_drive.NeedleDriveTask.guidance>` along its drive);
* the trainee looks at the tool after each reach, once the visuomotor delay has passed
  (the tool lags the hand), and corrects by the offset it sees;
* the task's own session (:class:`~davinci_sim.tasks.session.TaskSession`) scores the
  attempt: the row has the exercise's metrics.

This is the live engine only (one simulation in Python, ~4x real time on one core): the
study's batch engine steps the path trainees.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from davinci_sim.console import teleop_math as tm
from davinci_sim.geometry.so3 import rotation_vector
from davinci_sim.study.experts import Motor, Streamer

#: The exercise kinds a study can run with these trainees, and the scripts they follow.
CONSOLE_KINDS = ("needle_pickup", "needle_drive")
#: Simulated time a trial may take beyond the task's time limit, s: the limit counts from
#: the first grasp, the reach for it comes before.
START_ALLOWANCE = 30.0


class ConsoleStreamer(Streamer):
    """The :class:`~davinci_sim.study.experts.Streamer` of a trainee's hands on the MTMs.

    Args:
        sim: the simulation, every teleoperation in ``teleops`` following.
        motor: the trainee's motion style in this attempt.
        T_camera_task: the task's frame in the camera frame, 4x4.
        teleops: PSM name → its :class:`~davinci_sim.console.teleop_psm.TeleopPSM`, whose
            device is a :class:`~davinci_sim.devices.simulated.SimulatedMTM`.
    """

    LOOKS_AFTER_DELAY = True

    def __init__(self, sim, motor: Motor, T_camera_task: np.ndarray, teleops) -> None:
        super().__init__(sim, motor, T_camera_task, tuple(teleops), sees_tips=True)
        self.teleops = dict(teleops)
        self._last: dict[str, np.ndarray] = {}
        """PSM name → the hand target last sent (HRSV)."""

    def set_jaw(self, arm: str, angle: float) -> None:
        """The fingers squeeze ``arm``'s MTM gripper to the opening whose jaw angle the
        teleoperation maps to ``angle`` (rad; the gripper's own limits apply)."""
        teleop = self.teleops[arm]
        a = teleop.following_anchors()
        teleop.device.squeeze(tm.gripper_for_jaw(angle, a.jaw_scale, a.jaw_offset))

    def _send(self) -> None:
        t, dt = self.sim.time, self.sim.dt
        for n, G in self.goal.items():
            H = G.copy()
            H[:3, 3] += self.motor.tremor_at(t) - self.bias[n]
            teleop = self.teleops[n]
            a = teleop.following_anchors()
            T = tm.lead_pose(a.T_camera_psm0, a.T_hrsv_mtm0, self.T @ H, a.R_offset, a.scale)
            last = self._last.get(n)
            velocity = None
            if last is not None:  # (the hand's own motion: its impedance acts about it)
                velocity = np.concatenate(
                    [
                        (T[:3, 3] - last[:3, 3]) / dt,
                        rotation_vector(T[:3, :3] @ last[:3, :3].T) / dt,
                    ]
                )
            teleop.device.move_hand(T, velocity)
            self._last[n] = T


@dataclass
class ConsoleStage:
    """A simulation of a needle exercise with both teleoperations following and the hands
    on the handles, its session, teleoperations and start state (built once per process
    and task)."""

    sim: object
    session: object
    teleops: dict
    state: object
    T_camera_task: np.ndarray


_STAGES: dict[tuple, ConsoleStage] = {}


def build_console_stage(task, seed: int = 0) -> ConsoleStage:
    """The stage of ``task``: PSM1, PSM2, the ECM and both MTMs at the task's motion scale
    (the MTMs aligned with their PSMs, as the dVRK's console starts), every arm homed, both
    teleoperations following, a hand on each handle, the task's session installed.

    Raises:
        RuntimeError: the arms do not home or the teleoperations do not follow.
    """
    from davinci_sim.model import SceneConfig
    from davinci_sim.system import ConsoleDescription, SystemDescription
    from davinci_sim.system.build import install, new_simulation
    from davinci_sim.system.description import TaskDescription

    scene = SceneConfig(arms=("PSM1", "PSM2", "ECM", "MTMR", "MTML"), include_patient=False)
    console = ConsoleDescription(operator_present=True, teleop_enabled=True,
                                 scale=task.teleop.scale)  # fmt: skip
    description = SystemDescription(scene, console=console, runner="none", seed=seed,
                                    task=TaskDescription(task.name))  # fmt: skip
    sim = new_simulation(description, task)
    install(sim, description, task)
    session = sim.components["task"]
    arms = ("PSM1", "PSM2", "ECM")
    for n in arms:
        sim.arms[n].state_command("enable")
        sim.arms[n].state_command("home")
    teleops = {t.psm.name: t for t in sim.components["console"].psm_teleops.values()}
    ready = lambda: all(t.is_following() for t in teleops.values())  # noqa: E731
    if not sim.run_until(ready, 30.0):
        raise RuntimeError(f"{task.name}: the teleoperations did not start following")
    for t in teleops.values():
        t.device.grasp()
    sim.run_for(0.3)  # (objects at rest: READY)
    T_camera_task = np.linalg.inv(task.T_task_camera(sim.T_cart_camera()))
    return ConsoleStage(sim, session, teleops, sim.get_state(), T_camera_task)


def console_stage(task, seed: int = 0) -> ConsoleStage:
    """:func:`build_console_stage` of ``task``, built once per process (its start state
    restored for each trial)."""
    key = (task.name, repr(task), int(seed))
    stage = _STAGES.get(key)
    if stage is None:
        _STAGES.clear()  # (a study has one task: keep one simulation)
        stage = _STAGES[key] = build_console_stage(task, seed)
    return stage


def run_console_trial(spec) -> dict:
    """Run one study trial (:class:`~davinci_sim.study.trial.TrialSpec`) of a needle
    exercise: its row (the spec's fields, the task's metrics, ``score``, ``passed``,
    ``sim_time`` from the start to the end, ``wall_time``)."""
    from davinci_sim.operators.console import hand_impedance
    from davinci_sim.operators.params import sample_population
    from davinci_sim.study.experts import do_needle_drive, do_needle_pickup
    from davinci_sim.study.trial import load_spec_task, spec_columns
    from davinci_sim.tasks.metrics import metric_row

    wall0 = time.perf_counter()
    task = load_spec_task(spec)
    if task.kind not in CONSOLE_KINDS:
        raise ValueError(f"no console trainee for a {task.kind} task; kinds: {CONSOLE_KINDS}")
    stage = console_stage(task, spec.seed)
    sim, session = stage.sim, stage.session
    sim.set_state(stage.state)
    result = session.set_condition(spec.fixture)
    if not result:
        raise ValueError(result.message)
    params = sample_population(spec.population, spec.subject + 1, seed=spec.seed)
    for t in stage.teleops.values():
        t.device.hand = hand_impedance(params, spec.subject)
    rng = np.random.default_rng([*spec.key, 0xC0])
    motor = Motor.of(params, spec.subject, spec.practice, task.teleop.scale, rng)
    before = len(session.results)
    t_start = sim.time
    # (the exercise's own time limit ends it, from the first grasp: the budget leaves room)
    end = t_start + task.time_limit + START_ALLOWANCE

    def done() -> bool:
        return (len(session.results) > before or sim.time > end
                or not all(t.is_following() for t in stage.teleops.values()))  # fmt: skip

    stream = ConsoleStreamer(sim, motor, stage.T_camera_task, stage.teleops)
    script = {"needle_pickup": do_needle_pickup, "needle_drive": do_needle_drive}[task.kind]
    script(stream, session, task, done)
    sim.run_until(done, 2.0)
    finished = len(session.results) > before
    row = spec_columns(spec, task.name, finished)
    if finished:
        row.update({m.name: session.results[-1][m.name] for m in task.METRICS})
    else:
        row.update(metric_row(task.METRICS, session.monitor.metrics.result(), 0))
    row.update(task.score(row, finished))
    row["sim_time"] = sim.time - t_start
    row["wall_time"] = time.perf_counter() - wall0
    return row
