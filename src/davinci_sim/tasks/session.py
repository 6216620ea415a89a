"""A training session: a person (or a program) doing a task at the simulated console.

:class:`TaskSession` is a simulation component for the interactive use of a task, the
trainee's side of what the study automates, for any kind of task
(:class:`~davinci_sim.tasks.base.Task`): it sets the task's teleoperation scale, puts the
condition's fixture in the console's haptic loop (a
:class:`~davinci_sim.haptics.fixture.FixtureField` in the task's frame), and after every
physics step feeds a :class:`~davinci_sim.tasks.base.Sample` (the tool tip in the task's
frame, the guidance force the haptic loop requested, the clutch) to a
:class:`~davinci_sim.tasks.state.TaskMonitor`. Each finished repetition becomes a row (task,
condition, repetition, then the task's declared metrics, :func:`session_columns`), kept in
:attr:`TaskSession.results`, emitted on the ``results`` channel and appended to a CSV file
if one is given.

An adaptive condition (fixture entry ``type: adaptive``, :mod:`davinci_sim.haptics.adaptive`)
changes the guidance's B after each finished repetition, never inside one: the error the
rule declares (``metric``, e.g. ``deviation_error``) of the repetitions so far in the
condition goes through :func:`~davinci_sim.haptics.adaptive.next_B`, and the fixture of the
haptic loop's field becomes the seed's viscous law with the new B. The B that ran is the
row's ``guidance_B`` column (adaptive conditions only, after ``repetition``); the B now is
the state's :attr:`TaskSessionState.guidance_B`.

Repetitions follow one another by themselves: once a repetition's results are in, bringing
the tool back to point 1 starts the next one; :meth:`TaskSession.reset` abandons the
current repetition at any time and puts the task's objects (peg rings) back at their start
(dvrk-style command, callable over the bridge as ``/task/reset``).

Size: just over 500 lines because the session is one component whose parts share its state
(the repetition cycle, the adaptive B, framing the view before an attempt's clock starts, the
objects published for the page); splitting them would pass that state between modules.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from davinci_sim.sim.channels import Channels
from davinci_sim.sim.state import capture, restore
from davinci_sim.sim.types import ACCEPTED, CommandResult
from davinci_sim.tasks.base import Sample, Task
from davinci_sim.tasks.live_path import LivePathTick
from davinci_sim.tasks.metrics import MetricValues
from davinci_sim.tasks.objects_probe import ObjectsReading
from davinci_sim.tasks.scoring import SCORE_COLUMNS
from davinci_sim.tasks.state import Phase, TaskMonitor

if TYPE_CHECKING:
    from davinci_sim.console.console import Console
    from davinci_sim.console.teleop_psm import TeleopPSM
    from davinci_sim.sim.simulation import Simulation

#: How far the endoscope looks at a task it frames (:meth:`TaskSession.frame_view`), m: the
#: seed's 6 x 3 x 2.5 cm path then spans about half the 57° x 45° view.
VIEW_DISTANCE = 0.13

BRING_ABOVE = 0.03
"""How far above the task's start and its view points the session's tool crosses to the
start, m (the joints' interpolation dips the tool ~12 mm below the straight line over the
~12 cm to a peg board's far side; the jaws are 10.5 mm long)."""

#: The columns of a session's row before the task's metrics.
SESSION_COLUMNS = ("task", "condition", "repetition")


def session_columns(task: Task) -> tuple[str, ...]:
    """The columns of ``task``'s session rows (CSV log, ``/task/results``): the session's,
    the task's metrics, then the score (:data:`~davinci_sim.tasks.scoring.SCORE_COLUMNS`)."""
    return (*SESSION_COLUMNS, *(m.name for m in task.METRICS), *SCORE_COLUMNS)


@dataclass(frozen=True)
class TaskSessionState:
    """What a session publishes (``/task/state`` over the bridge)."""

    task: str
    condition: str
    phase: str
    """:class:`~davinci_sim.tasks.state.Phase` name of the current repetition."""
    repetition: int
    """Number of the current repetition, 1-based."""
    completed: int
    """Repetitions with results so far."""
    distance_to_path: float
    """Tool tip to the path, m (nan before the first tick)."""
    last: dict = field(default_factory=dict)
    """The last repetition's row (empty before the first)."""
    progress: str = ""
    """Where the repetition is, in the task's words (:meth:`Task.progress`)."""
    guidance_B: float | None = None
    """The B (N·s/m) the guidance runs with now, in an adaptive condition (None in
    another)."""
    objects: tuple = ()
    """A kind with objects (peg transfer's rings): their centres at the last sample, task
    frame, m, one (x, y, z) each (empty for the other kinds)."""
    object_frame: tuple = ()
    """A kind whose object's orientation is sampled (the needle): its frame at the last
    sample, task frame (m), the 4×4 matrix's rows (empty for the other kinds)."""


def _rows(a: np.ndarray | None) -> tuple:
    """A sampled array's rows as tuples of floats (a snapshot's plain values; () for none)."""
    return () if a is None else tuple(tuple(float(x) for x in row) for row in a.reshape(len(a), -1))


class TaskSession:
    """``task`` at ``console``'s teleoperation of the task's PSM; see the module docstring.

    Args:
        sim: the simulation (with the task's PSM, its MTM and the ECM).
        console: the installed console (:func:`~davinci_sim.console.install_console`).
        task: the task.
        condition: fixture entry or condition name of ``task`` (None: the task's own
            ``fixture``).
        log: CSV file the rows are appended to (None: none).
        name: component name.
        frame_view: bring the endoscope to the task (:meth:`frame_view`) from this distance
            (m) as soon as the ECM is homed and idle, then the tool to the task's start;
            None: the camera and the tool stay where they are.

    Raises:
        KeyError: if the console has no teleoperation of the task's MTM and PSM.
    """

    def __init__(
        self,
        sim: Simulation,
        console: Console,
        task: Task,
        *,
        condition: dict | str | None = None,
        log: str | Path | None = None,
        name: str = "task",
        frame_view: float | None = None,
    ) -> None:
        key = f"{task.teleop.mtm}_{task.teleop.psm}"
        teleop = console.psm_teleops.get(key)
        if teleop is None:
            raise KeyError(
                f"task {task.name!r} is done with {key}; the console's teleoperations: "
                f"{sorted(console.psm_teleops)}"
            )
        self.sim, self.console, self.task, self.teleop = sim, console, task, teleop
        self.name = name
        self.channels = Channels(name)
        self.field_name = f"{name}/guidance"
        self.condition = ""
        self._adaptive: dict | None = None
        """An adaptive condition's entry, errors so far and B (None: not adaptive)."""
        self._install_condition(condition)
        teleop.set_scale(task.teleop.scale)
        self.log = None if log is None else Path(log)
        self.monitor = TaskMonitor(task)
        self._live_tick = LivePathTick.build(task, self.monitor, sim.endoscope)
        """The path kind's one compiled call a tick (None: the Python path for this task)."""
        self.results: list[dict] = []
        self.repetition = 1
        self._distance = math.nan
        self._objects: np.ndarray | None = None  # (the last sample's: tuples at a snapshot)
        self._object_frame: np.ndarray | None = None
        self._bringing = False
        """The session's move of the tool to the start is under way."""
        self._recorded = False
        self._frame_at = frame_view
        self._framed = False

    def _install_condition(self, condition: dict | str | None) -> None:
        """Put ``condition``'s fixture in the haptic loop in place of the current one
        (raises TaskError or KeyError for a condition the task does not have)."""
        from davinci_sim.haptics.fixture import FixtureField

        task = self.task
        spec = condition if isinstance(condition, dict) else None
        if isinstance(condition, str):
            spec = task.condition(condition)
        fixture = task.fixture(spec)  # checks the entry before anything changes
        adaptive = _adaptive_start(task, spec if spec is not None else task.fixture_spec)
        haptics = self.console.haptics
        if self.field_name in haptics.field_names():
            haptics.remove_field(self.field_name)
        self._field = FixtureField(fixture, frame=task.frame)
        haptics.add_field(self._field, mtm=task.teleop.mtm, name=self.field_name)
        self.condition = _condition_label(spec if spec is not None else task.fixture_spec)
        self._adaptive = adaptive

    # ------------------------------------------------------------ commands
    def frame_view(self, distance: float = VIEW_DISTANCE) -> CommandResult:
        """Bring the endoscope to the task: the ECM moves (``move_cp``) so that the camera
        looks at the centre of the task's :attr:`~davinci_sim.tasks.base.Task.view_points`
        from ``distance`` m along its shaft (the ECM's closed-form IK keeps the shaft
        through the RCM and projects the orientation onto it). A world-frame task only (a
        camera-frame task moves with the camera)."""
        if self.task.frame != "world":
            return CommandResult(False, f"{self.name}: a {self.task.frame}-frame task "
                                        "moves with the camera; nothing to frame")  # fmt: skip
        if not (isinstance(distance, int | float) and 0.03 <= distance <= 0.5):
            return CommandResult(False, f"{self.name}: distance must be in [0.03, 0.5] m")
        ecm = self.sim.arms.get("ECM")
        if ecm is None:
            return CommandResult(False, f"{self.name}: no ECM in this simulation")
        centre = np.asarray(self.task.view_points, dtype=float).mean(axis=0)
        T_cart_rcm = ecm.base_frame()[0]
        shaft = centre - T_cart_rcm[:3, 3]
        goal = ecm.measured_cp().T.copy()  # (cart frame, dvrk.md 1.6)
        goal[:3, 3] = centre - float(distance) * shaft / np.linalg.norm(shaft)
        return ecm.move_cp(goal)

    def set_condition(self, condition: dict | str | None) -> CommandResult:
        """Change the condition now: a condition name of the task, a fixture entry
        (``{"type": "viscous", "B": 40, "G_max": 5}``, ``{"type": "spring", ...}``,
        ``{"type": "none"}``), or None for the task's own fixture. The current repetition
        starts over (its rows would mix two conditions); a refused condition changes
        nothing."""
        from davinci_sim.tasks.base import TaskError

        try:
            self._install_condition(condition)
        except (TaskError, KeyError, TypeError, ValueError) as e:
            message = e.args[0] if isinstance(e, KeyError) and e.args else str(e)
            return CommandResult(False, f"{self.name}: {message}")
        self.reset()
        self.channels.message("status", f"condition: {self.condition}", self.sim.time)
        return ACCEPTED

    def reset(self) -> CommandResult:
        """Abandon the current repetition and set the task's objects up for the next: the
        task's scene back at its start (:meth:`~davinci_sim.tasks.base.Task.reset_scene`:
        peg rings on their start pegs, at rest; nothing rebuilt), then back to IDLE (the
        tool at point 1 starts it). The command behind the console's and the web
        console's Reset and ``/task/reset``."""
        try:
            self.task.reset_scene(self.sim.model, self.sim.data)
        except ValueError as e:  # (a scene drawn without the task's objects)
            self.channels.message("warning", f"{self.name}: {e}", self.sim.time)
        self._restart(self.sim.time)
        return ACCEPTED

    def _restart(self, t: float) -> None:
        """Back to IDLE for the next repetition (the objects left where they are); ``t``: the
        simulated time it happens at (s)."""
        self.monitor.reset()
        self._recorded = False
        self.channels.message("status", f"repetition {self.repetition}: reset", t)

    def report(self, level: str, text: str) -> CommandResult:
        """Put ``text`` on the session's message channel at ``level`` (``error``,
        ``warning`` or ``status``): how a part outside the loop tells about the session (the
        trainee records, when an attempt cannot be written)."""
        if level not in ("error", "warning", "status"):
            return CommandResult(False, f"{self.name}: level must be error, warning or status")
        self.channels.message(level, str(text), self.sim.time)
        return ACCEPTED

    # ------------------------------------------------------------ component
    def pre_step(self, t: float) -> None:
        """Nothing before the physics step: the session samples in :meth:`post_step`."""

    def post_step(self, t: float) -> None:
        if self._frame_at is not None or self._bringing:
            if self._frame_at is not None:
                self._frame_when_ready()
            if self._framing():  # no repetition starts while the session moves the arms
                self.monitor.reset()
                return
        task = self.task
        T_task_camera = task.T_task_camera(self.sim.T_cart_camera())
        if self._recorded:
            self._after_result(T_task_camera, self.teleop.psm.measured_cp().T, t)
            return
        ticked = self._live_tick is not None and self._live_tick.tick(
            T_task_camera, live_inputs(task, self.teleop, self.console), t
        )
        self._sampled(ticked, T_task_camera, t)

    def _after_result(self, T_task_camera: np.ndarray, T_camera_tip: np.ndarray,
                      t: float) -> None:  # fmt: skip
        """A tick once the repetition's result is in (its time ``t``, s): the tool's distance
        to the path; back to the start, the next repetition."""
        task = self.task
        tip = (T_task_camera @ T_camera_tip)[:3, 3]
        self._distance = float(task.distance(tip)[0])
        if task.at_start(tip)[0]:
            self.repetition += 1
            self._restart(t)  # (the objects stay: a Reset puts them back)

    def _sampled(self, ticked: bool, T_task_camera: np.ndarray, t: float,
                 sample: Sample | None = None) -> None:  # fmt: skip
        """The rest of :meth:`post_step` once the compiled tick has (``ticked``) or has not
        taken the tick's sample: then the monitor observes ``sample`` (None: the console's
        now, :func:`live_sample`)."""
        if not ticked:
            if sample is None:
                sample = live_sample(self.task, T_task_camera, self.teleop, self.console, t)
            self.monitor.observe(sample)
            if sample.objects is not None:  # (what the console's page shows of them)
                self._objects = np.array(sample.objects[0], dtype=float)
            if sample.T_task_object is not None:  # (the needle: the page shows where it is)
                self._object_frame = np.array(sample.T_task_object[0], dtype=float)
        self._distance = self.monitor.distance
        if self.monitor.phase == Phase.FINISHED and self.monitor.results is not None:
            self._record(self.monitor.results, t)

    def chunk_part(self):
        """What the console's compiled ticks (:mod:`davinci_sim.console.chunk`) sample for
        the session after each step, or None where its tick needs Python: framing the view,
        an adaptive condition (a repetition's end changes the fixture for the next tick), a
        sample the compiled tick does not take."""
        from davinci_sim.console.chunk import SampleRequest

        if self._frame_at is not None or self._bringing or self._adaptive is not None:
            return None
        live, task = self._live_tick, self.task
        if not self._recorded and live is not None:
            prev = live.trial.metrics._prev
            if prev is not None and prev.contacts is None:
                return None
        try:  # (the kind's objects, recorded after each step)
            objects = None if live is not None else task.objects_probe(self.sim.model,
                                                                       _SCENE_CACHE)  # fmt: skip
        except ValueError:  # (a scene drawn without them: the Python tick says so)
            return None
        contacts = _contacts(self.sim, task)
        return SampleRequest(self.teleop.name, self._take, contacts.tool_geom,
                             contacts.other_geom, objects,
                             contacts if live is None else None)  # fmt: skip

    def _take(self, t, T_cart_camera, T_camera_tip, requested, master,
              readings: tuple | None = None, contacts: tuple | None = None,
              clutch: bool = False) -> None:  # fmt: skip
        """:meth:`post_step` of m compiled ticks, in order: their times ``t`` (m,) s, the
        camera in the cart and the tip in the camera (m, 4, 4), the guidance force requested
        ((m, 3) N, or None) and the master's position ((m, 3) m) as each tick left them, the
        kind's objects' readings (the
        :class:`~davinci_sim.tasks.objects_probe.ObjectsReading` fields, each with the m
        ticks first; None: a kind without objects), the instruments' contacts (their
        number and force, N, each (m,); None: not measured, the ticks had none) and the
        clutch (the same for all m). The path kind's samples go in compiled calls up to each
        change of phase (``LivePathTick.takes``; one at a time while clutched); another
        kind's through its Python step, one at a time (its contacts measured)."""
        task, live = self.task, self._live_tick
        T_task_camera = task.T_task_cameras(T_cart_camera)
        if live is None:
            assert contacts is not None  # (chunk_part asks for them)
            self._take_each(T_task_camera, t, T_camera_tip, requested, master, readings,
                            contacts, clutch)  # fmt: skip
            return
        T_task_tip = T_task_camera @ T_camera_tip  # (each product as the tick's own @)
        j, m = 0, len(t)
        while j < m:
            if self._recorded:
                self._after_result(T_task_camera[j], T_camera_tip[j], float(t[j]))
                j += 1
                continue
            force = None if requested is None else requested[j:]
            n = 0 if clutch else live.takes(T_task_camera[j:], T_task_tip[j:],
                                            T_camera_tip[j:], t[j:], force,
                                            master[j:])  # fmt: skip
            if n == 0:  # (the first sample of a trial, or clutched: one tick)
                tip = T_camera_tip[j].copy()
                tip.setflags(write=False)
                inputs = (tip, None if force is None else force[0], clutch, master[j], (0, 0.0))
                live.tick(T_task_camera[j], inputs, float(t[j]))
                n = 1
            j += n
            self._sampled(True, T_task_camera[j - 1], float(t[j - 1]))

    def _take_each(self, T_task_camera, t, T_camera_tip, requested, master, readings,
                   contacts, clutch: bool) -> None:  # fmt: skip
        """:meth:`_take`'s samples one at a time, each as :func:`live_sample` has it."""
        sim, task = self.sim, self.task
        count, force = contacts
        for j in range(len(t)):
            if self._recorded:
                self._after_result(T_task_camera[j], T_camera_tip[j], float(t[j]))
                continue
            tip = T_camera_tip[j].copy()
            tip.setflags(write=False)
            inputs = (tip, None if requested is None else requested[j], clutch, master[j],
                      (int(count[j]), float(force[j])))  # fmt: skip
            extra = {}
            if readings is not None:
                reading = ObjectsReading(*(a[j] for a in readings))
                extra = task.objects_fields(reading, sim.model, None, _SCENE_CACHE)
            sample = sample_of(T_task_camera[j], inputs, sim.endoscope, float(t[j]), extra)
            self._sampled(False, T_task_camera[j], float(t[j]), sample)

    def _framing(self) -> bool:
        """The session is framing the view: the ECM moves (homing, then to the task) or the
        tool has still to be brought to the start. (A camera exercise is ready as soon as
        the camera is still: its clock must not start with these motions.)"""
        if self._bringing:  # the tool on its way to the start (the session's move_cp)
            if not self.teleop.psm.is_busy():
                self._bringing = self._bring()
            return self._bringing
        ecm = self.sim.arms.get("ECM")
        return self._frame_at is not None and (self._framed or (ecm is not None and ecm.is_busy()))

    def _frame_when_ready(self) -> None:
        """The one-shot start of a framed session: once the ECM is homed and idle, frame the
        task; once it has got there and the PSM is homed and idle, bring the tool to the
        task's start (``move_cp``, orientation kept, as the study's set-up does) unless the
        teleoperation already follows (the operator has it)."""
        ecm = self.sim.arms.get("ECM")
        if ecm is None or not (ecm.is_homed() and not ecm.is_busy()):
            return
        if not self._framed:
            result = self.frame_view(self._frame_at)
            self._framed = True
            if not result:
                self._frame_at = None
                self.channels.message("warning", result.message, self.sim.time)
            return
        psm = self.teleop.psm
        if not (psm.is_homed() and not psm.is_busy()):
            return
        self._frame_at = None
        if self.teleop.is_following():
            return
        self._bringing = self._bring()

    def _bring(self) -> bool:
        """The next of the moves that bring the tool to the task's start (``move_cp``,
        orientation kept), from where its setpoint is; whether one is under way. Up to the
        height of :data:`BRING_ABOVE` over the start and over every view point of the
        task (its pegs' tops, a wall's), across to above the start, down to it: ``move_cp``
        interpolates the joints, and the tool's way straight to the start swept through
        peg transfer's pegs and its wall (measured: PSM1 then faulted on its tracking
        error). Straight to the start if a move above is refused."""
        psm = self.teleop.psm
        task = self.task
        T_task_camera = task.T_task_camera(self.sim.T_cart_camera())
        T_camera_task = np.linalg.inv(T_task_camera)
        goal = psm.setpoint_cp().T.copy()  # (its orientation kept)
        p_task = (T_task_camera @ np.append(goal[:3, 3], 1.0))[:3]
        start = np.asarray(task.start, dtype=float)
        top = float(np.max(np.asarray(task.view_points, dtype=float)[:, 2]))
        height = max(p_task[2], start[2] + BRING_ABOVE, top + BRING_ABOVE)
        above = np.array([start[0], start[1], height])
        if np.linalg.norm(p_task - start) < 1e-4:
            return False  # (there)
        if np.linalg.norm(p_task - above) < 1e-4:
            plan = [start]  # down
        elif abs(p_task[2] - height) < 1e-4:
            plan = [above, start]  # across, else straight
        else:
            plan = [np.array([p_task[0], p_task[1], height]), start]  # up, else straight
        for i, p in enumerate(plan):
            goal[:3, 3] = (T_camera_task @ np.append(p, 1.0))[:3]
            result = psm.move_cp(goal)
            if result:
                return True
            if i == len(plan) - 1:
                self.channels.message("warning", result.message, self.sim.time)
        return False

    def _record(self, metrics: MetricValues, t: float) -> None:
        row = {"task": self.task.name, "condition": self.condition, "repetition": self.repetition}
        if self._adaptive is not None:
            row["guidance_B"] = self._adaptive["B"]
        row.update(metrics.row(0))
        row.update(self.task.score(row))
        self.results.append(row)
        self._recorded = True
        self.channels.emit("results", dict(row))
        verdict = {True: "passed", False: "not passed", None: "no pass mark"}[row["passed"]]
        score = "" if row["score"] is None else f"score {row['score']:.0f} % ({verdict}); "
        self.channels.message(
            "status",
            f"repetition {self.repetition} done: {score}{self.task.summary(row)}",
            t,
        )
        if self.log is not None:
            self._append(row)
        if self._adaptive is not None:
            self._adapt(row, t)

    def _adapt(self, row: dict, t: float) -> None:
        """After a finished repetition of an adaptive condition: the rule's next B from the
        errors so far, put in the guidance field (between repetitions only)."""
        from davinci_sim.haptics.adaptive import AdaptiveRule, next_B
        from davinci_sim.haptics.kinds import fixture_params

        state = self._adaptive
        rule = AdaptiveRule.of(fixture_params(state["entry"]))
        value = row.get(rule.metric)
        state["errors"].append(math.nan if value is None else float(value))
        state["B"] = next_B(state["B"], state["errors"], rule)
        self._apply_B()
        self.channels.message("status", f"guidance B for the next repetition: "
                                        f"{state['B']:.3g} N·s/m", t)  # fmt: skip

    def _apply_B(self) -> None:
        """The guidance field's fixture: the adaptive entry with the current B."""
        state = self._adaptive
        self._field.fixture = self.task.fixture({**state["entry"], "B": state["B"]})

    def _append(self, row: dict) -> None:
        """Append ``row`` to the log under the file's header (a new file: the row's keys;
        a column the header lacks, e.g. ``guidance_B`` after a change of condition, is left
        out, a column the row lacks is empty)."""
        try:
            new = not self.log.exists() or self.log.stat().st_size == 0
            names = list(row)
            if not new:
                with open(self.log, newline="") as f:
                    names = next(csv.reader(f), names)
            with open(self.log, "a", newline="") as f:
                writer = csv.DictWriter(f, fieldnames=names, extrasaction="ignore", restval="")
                if new:
                    writer.writeheader()
                writer.writerow(row)
        except OSError as e:  # the session goes on; the row stays in .results
            self.channels.message("error", f"cannot write {self.log}: {e}", self.sim.time)

    def snapshot(self) -> TaskSessionState:
        return TaskSessionState(
            task=self.task.name,
            condition=self.condition,
            phase=self.monitor.phase.name,
            repetition=self.repetition,
            completed=len(self.results),
            distance_to_path=self._distance,
            last=dict(self.results[-1]) if self.results else {},
            progress=self.task.progress(self.monitor.state),
            guidance_B=None if self._adaptive is None else self._adaptive["B"],
            objects=_rows(self._objects),
            object_frame=_rows(self._object_frame),
        )

    # ------------------------------------------------------------ state
    _STATE = ("results", "repetition", "_distance", "_recorded", "condition", "_frame_at",
              "_framed", "_bringing", "_adaptive")  # fmt: skip

    def get_state(self) -> dict:
        """The monitor's state, the rows so far, the repetition number, the last distance,
        whether this repetition's row is in, the condition's label and, in an adaptive
        condition, its errors so far and B. (The guidance field and its filter are the
        haptic loop's; :meth:`set_state` gives its fixture the restored B.)"""
        return {"monitor": self.monitor.get_state(), **capture(self, self._STATE)}

    def set_state(self, state: dict) -> None:
        state = dict(state)
        self.monitor.set_state(state.pop("monitor"))
        restore(self, state, self._STATE)
        if self._adaptive is not None:
            self._apply_B()


def live_sample(task: Task, T_task_camera, teleop: TeleopPSM, console: Console, t: float) -> Sample:
    """The :class:`~davinci_sim.tasks.base.Sample` of ``task`` at the simulated console now:
    the tool tip of ``teleop``'s PSM in the task's frame (``T_task_camera``: the camera in
    the task's frame), the guidance force the haptic loop requested for the task's MTM (0
    before it has run), the clutch; ``t`` the simulated time, s. The trainer metrics'
    fields: whether the tip is in the left endoscope image, the master handle's position
    (HRSV: the device's input of this tick, read before the step, so one tick behind the
    study batch's, which reads the MTM after it; None before the first input), and the
    instrument's contacts and their force (MuJoCo's contacts of the last step,
    :class:`~davinci_sim.tasks.trainer.InstrumentContacts`); the camera's pose and the tool's
    orientation in the task's frame (for the exercises that score them)."""
    sim = console.sim
    extra = task.scene_fields(sim.model, sim.data, _SCENE_CACHE)  # (a kind's objects)
    return sample_of(T_task_camera, live_inputs(task, teleop, console), sim.endoscope, t, extra)


def sample_of(T_task_camera, inputs: tuple, camera, t: float, extra: dict) -> Sample:
    """:func:`live_sample`'s sample of the console's ``inputs`` (:func:`live_inputs`), the
    camera in the task's frame ``T_task_camera`` (4x4), the endoscope's ``camera``
    (:class:`~davinci_sim.model.cameras.CameraConfig`), the time ``t`` (s) and the kind's
    ``extra`` fields (:meth:`~davinci_sim.tasks.base.Task.scene_fields`)."""
    from davinci_sim.model.cameras import project_left

    p_camera, force, clutch, master, (count, contact_force) = inputs
    T_task_tip = np.asarray(T_task_camera) @ p_camera
    tip = T_task_tip[:3, 3]
    uv = project_left(p_camera[:3, 3], camera)  # (one point: the scalar form is cheaper)
    visible = uv is not None and 0 <= uv[0] < camera.width and 0 <= uv[1] < camera.height
    master = None if master is None else master.reshape(1, 3)
    # One trial: the arrays built directly (Sample.of's conversions cost more, every tick).
    f = np.zeros((1, 3)) if force is None else np.asarray(force, dtype=float).reshape(1, 3)
    objects, grasp, tools = extra.get("objects"), extra.get("grasp"), extra.get("tools")
    return Sample(
        np.array([float(t)]), tip.reshape(1, 3), f, np.array([clutch]),
        visible=np.array([visible]), master=master, contacts=np.array([count], dtype=np.int64),
        tool_force=np.array([contact_force]),
        objects=None if objects is None else np.asarray(objects, dtype=float).reshape(1, -1, 3),
        grasp=None if grasp is None else np.asarray(grasp, dtype=np.int64).reshape(1, -1),
        T_task_camera=np.asarray(T_task_camera, dtype=float).reshape(1, 4, 4),
        R_task_tip=T_task_tip[:3, :3].reshape(1, 3, 3),
        tools=None if tools is None else np.asarray(tools, dtype=float).reshape(1, -1, 3),
        T_task_object=None if (obj := extra.get("T_task_object")) is None
        else np.asarray(obj, dtype=float).reshape(1, 4, 4),
        tissue_force=None if (tf := extra.get("tissue_force")) is None
        else np.asarray(tf, dtype=float).reshape(1),
    )  # fmt: skip


def live_inputs(task: Task, teleop: TeleopPSM, console: Console) -> tuple:
    """What :func:`live_sample` reads from the console now: the tip of ``teleop``'s PSM in
    the camera frame (4x4, m, read-only), the guidance force the haptic loop requested for
    the task's MTM ((3,) N, or None before it has run), the clutch, the master handle's
    position ((3,) m, HRSV, or None before the device's first input) and the instrument's
    contacts (their number and total normal force, N)."""
    requested = console.haptics.requested(task.teleop.mtm)
    reading = teleop.device.input()
    sim = console.sim
    return (
        teleop.psm._measured_T(),  # (measured_cp().T)
        None if requested is None else requested[:3],
        bool(teleop.is_clutched()),
        None if reading is None else reading.T_hrsv_tip[:3, 3],
        _contacts(sim, task).measure(sim.model, sim.data),
    )


#: What kinds keep between ticks to read the scene (:meth:`Task.scene_fields`).
_SCENE_CACHE: dict = {}


#: InstrumentContacts by (model id, PSMs, ignored prefixes): (model, contacts), the few
#: most recent (building one reads every body's name).
_CONTACTS: dict[tuple, tuple] = {}


def _contacts(sim: Simulation, task: Task):
    """The :class:`~davinci_sim.tasks.trainer.InstrumentContacts` of ``task``'s instruments in
    ``sim``'s model (built once per model)."""
    from davinci_sim.tasks.trainer import InstrumentContacts, task_instruments

    key = (id(sim.model), task_instruments(task), task.CONTACT_IGNORE)
    entry = _CONTACTS.get(key)
    if entry is None or entry[0] is not sim.model:  # (an id reused by a new model)
        entry = (sim.model, InstrumentContacts(sim.model, *key[1:]))
        _CONTACTS[key] = entry
        while len(_CONTACTS) > 4:
            del _CONTACTS[next(iter(_CONTACTS))]
    return entry[1]


def _adaptive_start(task: Task, spec: dict) -> dict | None:
    """An adaptive entry's starting state in a session (its entry, no errors, the B of
    the first repetition: the entry's ``B`` if it sets one, else the rule's), or None for
    another kind. ValueError if the task has no column of the rule's error metric."""
    if spec.get("type") != "adaptive":
        return None
    from davinci_sim.haptics.adaptive import AdaptiveRule, B_at
    from davinci_sim.haptics.kinds import fixture_params

    rule = AdaptiveRule.of(fixture_params(spec))
    names = [m.name for m in task.METRICS]
    if rule.metric not in names:
        raise ValueError(f"the adaptive rule's metric {rule.metric!r} is not one of task "
                         f"{task.name!r}'s: {names}")  # fmt: skip
    B = spec.get("B")
    B = B_at(1, [], rule) if B is None else float(B)
    return {"entry": {k: v for k, v in spec.items() if k != "B"}, "errors": [], "B": B}


def _condition_label(spec: dict) -> str:
    if spec.get("name"):
        return str(spec["name"])
    kind = spec.get("type", "none")
    params = ", ".join(
        f"{k}={v:g}" if isinstance(v, int | float) else f"{k}={v}"
        for k, v in spec.items()
        if k not in ("type", "name")
    )
    return f"{kind}({params})" if params else kind


def install_task(
    sim: Simulation,
    task: Task,
    *,
    condition: dict | str | None = None,
    log: str | Path | None = None,
    frame_view: float | None = None,
) -> TaskSession:
    """Add a :class:`TaskSession` of ``task`` to ``sim``'s installed console (component
    ``task``, after the console's components so that it samples after the haptic loop)."""
    console = sim.components.get("console")
    if console is None:
        raise KeyError("install the console first (console.install_console)")
    session = TaskSession(sim, console, task, condition=condition, log=log, frame_view=frame_view)
    if session.name in sim.components:
        raise ValueError(f"a component named {session.name!r} is already registered")
    sim.add_component(session)
    return session
