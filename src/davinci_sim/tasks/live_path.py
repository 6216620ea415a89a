"""The live session's tick of its one path trial in one compiled call (and a single
environment's, which samples its path task every tick the same way).

After every physics step the :class:`~davinci_sim.tasks.session.TaskSession` samples the
console (:func:`~davinci_sim.tasks.session.live_sample`: the tip in the task's frame, its
visibility, the guidance force, the clutch, the master, the contacts), then the
:class:`~davinci_sim.tasks.state.TaskMonitor` runs the task's state machine and metrics on
it (:func:`~davinci_sim.tasks.state.advance`). Built from numpy arrays and Python objects,
that was some 190 µs of a 1 kHz tick. For a :class:`~davinci_sim.tasks.task.PathTask` scoring
its own declaration (``seed_path`` and every path task file), :class:`LivePathTick` reads
the same inputs (:func:`~davinci_sim.tasks.session.live_inputs`) and makes the sample and
the tick one compiled call (:func:`~davinci_sim.tasks.path_row.live_path_row`: the
projection's arithmetic, then :func:`~davinci_sim.tasks.path_row.path_tick_rows`), leaving
the monitor (state, observations, metrics, previous sample, results) as the Python path
leaves it, bit for bit (``tests/tasks/test_live_path.py``). The path-following environment's
one row (``envs/problems.TaskProblem``: ``Sample.of`` then ``advance`` each tick) takes it
too, bit for bit (``tests/envs/test_env_path_tick.py``). The Python path stays the oracle
and runs whatever this does not serve.
"""

from __future__ import annotations

import numpy as np

from davinci_sim.tasks import path_row
from davinci_sim.tasks.base import Sample
from davinci_sim.tasks.metrics_one import running, update_previous
from davinci_sim.tasks.state import _FINISHED, TaskMonitor, TaskState

ENABLED = True
"""Whether sessions use :class:`LivePathTick` (off: the Python path, e.g. to compare)."""

_ACTIVE = np.ones(1, dtype=bool)  # (the kernel only reads it)
_NO_VECTOR = np.zeros(3)


class LivePathTick:
    """One path trial's sample and tick (see the module docstring) for ``trial``, whose
    task is ``task`` (the constants are built once; :meth:`build` says whether it applies).

    Args:
        task: the :class:`~davinci_sim.tasks.task.PathTask`.
        trial: what holds the trial's ``state`` and ``metrics`` (updated): the session's
            :class:`~davinci_sim.tasks.state.TaskMonitor` of one trial (its observations and
            results too), or a single environment's task problem.
        camera: the endoscope's :class:`~davinci_sim.model.cameras.CameraConfig`.
        constants: ``path_row``'s constants of the task.
    """

    def __init__(self, task, trial, camera, constants: tuple) -> None:
        self.task, self.trial = task, trial
        self._constants = constants
        self._camera = (camera.focal_px, camera.baseline_m / 2.0, float(camera.width),
                        float(camera.height))  # fmt: skip
        self._own_prev: Sample | None = None
        """The trial's previous sample when it has live_sample's fields (:func:`_live_fields`):
        the next one then takes its place, or it stays, without the general rules."""

    @classmethod
    def build(cls, task, trial, camera) -> LivePathTick | None:
        """The tick for ``trial`` (its ``n``, ``state``, ``metrics``) of ``task``, or None
        where it does not apply: another kind or declaration, more than one trial, a path
        the brute force does not serve, no numba."""
        from davinci_sim.tasks.task import PathTask

        if not path_row.COMPILED or type(task) is not PathTask or trial.n != 1:
            return None
        if not trial.metrics.floats:
            return None
        constants = path_row._constants(task)
        return None if constants is None else cls(task, trial, camera, constants)

    def tick(self, T_task_camera, inputs: tuple, t: float, T_task_tip=None) -> bool:
        """One sample at the simulated time ``t`` (s) of the console's ``inputs``
        (:func:`~davinci_sim.tasks.session.live_inputs`), the camera in the task's frame
        ``T_task_camera`` (4x4), the tip in it ``T_task_tip`` (None: ``T_task_camera`` times
        the tip's pose in the camera frame, numpy's product, as ``live_sample`` has it): the
        monitor's :meth:`~TaskMonitor.observe` of
        :func:`~davinci_sim.tasks.session.live_sample`, or an environment's ``advance`` of
        its sample. False (nothing done) where the previous sample has no contacts (the
        reducers' path decides then)."""
        if not ENABLED:
            return False
        trial = self.trial
        metrics = trial.metrics
        prev = metrics._prev
        if prev is not None and prev.contacts is None:
            return False
        p_camera, force, clutch, master, (count, contact_force) = inputs
        if master is not None:  # (a column of the device's pose: the kernel's one signature)
            master = np.ascontiguousarray(master, dtype=float)
        if p_camera.flags.writeable:  # (read-only as Arm._measured_T's: one signature)
            p_camera = p_camera.view()
            p_camera.setflags(write=False)
        if T_task_tip is None:
            T_task_tip = np.asarray(T_task_camera) @ p_camera  # (numpy's: live_sample's)
        arrays = _sample_arrays(1)
        s_time, s_tip, s_force, s_clutch, s_visible, s_master, s_contacts, s_tool_force = arrays
        new = path_row.next_state(trial.state)
        closest, measured = np.empty((1, 8)), np.empty(1, dtype=bool)
        if prev is None:  # (the first sample is its own previous one)
            previous = (s_time, s_tip, s_clutch, s_contacts)
        else:
            previous = (_c(prev.time, float), _c(prev.tip, float), _c(prev.clutch, bool),
                        _c(prev.contacts, np.int64))  # fmt: skip
        has_master = master is not None
        args = (
            *self._constants, _ACTIVE, T_task_tip, p_camera, *self._camera, force is not None,
            _NO_VECTOR if force is None else force, has_master,
            _NO_VECTOR if master is None else master, float(t), clutch, count,
            float(contact_force), *new, *arrays, *previous, *running(metrics),
            metrics._prev_in, closest, measured,
        )  # fmt: skip
        path_row.live_path_row(*args)
        if not has_master:  # (metrics_one.mark_missing: the one optional field it can lack)
            metrics._missing.add("master_workspace")
        sample = (s_time, s_tip, s_force, s_clutch, s_visible, s_master if has_master else None,
                  s_contacts, s_tool_force, T_task_camera, T_task_tip)  # fmt: skip
        if prev is not None and prev is self._own_prev and (prev.master is not None) == has_master:
            if measured[0]:  # (update_previous: where() of every row, copies of new arrays)
                metrics._prev = self._own_prev = self._sample(*sample)
            # (else kept(): the same sample, every field of the same kind)
            metrics._prev_in = measured
        else:
            update_previous(metrics, measured, self._sample(*sample))
            self._own_prev = metrics._prev if _live_fields(metrics._prev) else None
        return self._done(new, closest)

    def ticks(self, T_task_camera, T_task_tip, p_camera, t, contacts, tool_force) -> bool:
        """m samples in turn, as m :meth:`tick` calls with no guidance force, clutch or
        master would take them (an environment's samples after a compiled period's ticks):
        the camera and the tip in the task's frame and the tip in the camera frame (m, 4, 4),
        the times (m,) s, the instrument's contacts and their force (m,). False (nothing
        done) where the samples must go one by one: the trial's previous sample is not
        :meth:`tick`'s own kind (the first after a reset or a restored state), numba off."""
        prev = self.trial.metrics._prev
        if not ENABLED or prev is None or prev is not self._own_prev or prev.master is not None:
            return False
        self._samples(T_task_camera, T_task_tip, p_camera, t, contacts, tool_force, None, None,
                      stop=False)  # fmt: skip
        return True

    def takes(self, T_task_camera, T_task_tip, p_camera, t, force, master) -> int:
        """Samples in turn, as :meth:`tick` takes them with the guidance force ``force``
        (m, 3) N (None: none), the master's position ``master`` (m, 3) m, no clutch and no
        contact (the console's compiled ticks, :mod:`davinci_sim.console.chunk`), up to and
        including the first that changes the trial's phase; the camera and the tip in the
        task's frame and the tip in the camera frame (m, 4, 4), the times (m,) s. Returns how
        many it took: 0 where they must go one by one (as :meth:`ticks`)."""
        prev = self.trial.metrics._prev
        if not ENABLED or prev is None or prev is not self._own_prev or prev.master is None:
            return 0
        m = len(t)
        return self._samples(T_task_camera, T_task_tip, p_camera, t, np.zeros(m, np.int64),
                             np.zeros(m), force, master, stop=True)  # fmt: skip

    def _samples(self, T_task_camera, T_task_tip, p_camera, t, contacts, tool_force, force,
                 master, *, stop: bool) -> int:  # fmt: skip
        """:func:`~davinci_sim.tasks.path_row.live_path_rows` on the samples (arguments as
        :meth:`ticks` and :meth:`takes`); the trial and its previous sample as the ticks
        leave them. Returns the samples taken."""
        trial = self.trial
        metrics = trial.metrics
        prev = metrics._prev
        m = len(t)
        arrays = _sample_arrays(m)
        new = path_row.next_state(trial.state)
        closest, measured = np.empty((1, 8)), np.empty(1, dtype=bool)
        done = np.zeros(1, dtype=np.int64)
        previous = (np.array(prev.time, dtype=float), np.array(prev.tip, dtype=float),
                    np.array(prev.clutch, dtype=bool),
                    np.array(prev.contacts, dtype=np.int64))  # fmt: skip
        has_force, has_master = force is not None, master is not None
        args = (
            *self._constants, _ACTIVE, _c(T_task_tip, float), _c(p_camera, float),
            *self._camera, has_force, _c(force, float) if has_force else np.zeros((m, 3)),
            has_master, _c(master, float) if has_master else np.zeros((m, 3)), _c(t, float),
            _c(contacts, np.int64), _c(tool_force, float), stop, *new, *arrays, *previous,
            *running(metrics), metrics._prev_in.copy(), closest, measured, done,
        )  # fmt: skip
        last = path_row.live_path_rows(*args)
        if not has_master:
            metrics._missing.add("master_workspace")  # (no master: mark_missing)
        metrics._prev_in = measured
        if last >= 0:  # (the last measured sample: the metrics' previous one; views of
            # this call's own new arrays, which nothing writes again)
            row = tuple(a[last : last + 1] for a in arrays)
            time, tip, force_row, clutch, visible, master_row, count, tool = row
            metrics._prev = self._own_prev = self._sample(
                time, tip, force_row, clutch, visible, master_row if has_master else None,
                count, tool, T_task_camera[last], T_task_tip[last],
            )  # fmt: skip
        self._done(new, closest)
        return int(done[0])

    def _done(self, new: TaskState, closest: np.ndarray) -> bool:
        """The trial's new state; a monitor's observations (the last sample's distance and
        arc length) and its results once the trial is finished, as ``observe`` leaves them."""
        trial = self.trial
        trial.state = new
        if isinstance(trial, TaskMonitor):
            trial.observations = {"distance": closest[:, 6], "arc_length": closest[:, 7]}
            if trial.results is None and new.phase[0] >= _FINISHED:
                trial.results = trial.metrics.result()
        return True

    @staticmethod
    def _sample(time, tip, force, clutch, visible, master, contacts, tool_force, T_task_camera,
                T_task_tip) -> Sample:  # fmt: skip
        """The sample :func:`~davinci_sim.tasks.session.live_sample` builds, from the
        kernel's arrays (new ones each tick: nothing refills them)."""
        return Sample(
            time, tip, force, clutch, visible=visible, master=master, contacts=contacts,
            tool_force=tool_force, T_task_camera=np.array(T_task_camera, dtype=float)[None],
            R_task_tip=T_task_tip[None, :3, :3].copy(),
        )  # fmt: skip


#: The fields of live_sample's sample of a path task: (name, dtype, shape); None: absent.
_LIVE_FIELDS = (("time", np.float64, (1,)), ("tip", np.float64, (1, 3)),
                ("force", np.float64, (1, 3)), ("clutch", np.bool_, (1,)),
                ("visible", np.bool_, (1,)), ("contacts", np.int64, (1,)),
                ("tool_force", np.float64, (1,)), ("objects", None, None),
                ("grasp", None, None), ("T_task_camera", np.float64, (1, 4, 4)),
                ("R_task_tip", np.float64, (1, 3, 3)), ("tools", None, None))  # fmt: skip


def _live_fields(sample: Sample | None) -> bool:
    """Whether ``sample``'s fields are those of
    :func:`~davinci_sim.tasks.session.live_sample`'s samples of a path task (the master's
    position optional), of their dtypes and shapes. For such a previous sample,
    ``update_previous`` keeps it (an unmeasured sample with the same master field) or
    replaces it with the new one (a measured one): ``Sample.kept``'s and ``Sample.where``'s
    rules when every field agrees."""
    if sample is None:
        return False
    for name, dtype, shape in (*_LIVE_FIELDS, ("master", np.float64, (1, 3))):
        a = getattr(sample, name)
        if dtype is None or (name == "master" and a is None):
            if a is not None:
                return False
        elif a is None or a.dtype != dtype or a.shape != shape:
            return False
    return True


def _sample_arrays(m: int) -> tuple:
    """New arrays for m samples' time, tip, force, clutch, visibility, master, contacts and
    tool force, as the kernels fill them (new each time: a sample kept holds its own)."""
    return (np.empty(m), np.empty((m, 3)), np.empty((m, 3)), np.empty(m, dtype=bool),
            np.empty(m, dtype=bool), np.empty((m, 3)), np.empty(m, dtype=np.int64),
            np.empty(m))  # fmt: skip


def _c(a, dtype) -> np.ndarray:
    """``a`` as a C-ordered array of ``dtype`` (a copy only where it is not one)."""
    return np.ascontiguousarray(a, dtype=dtype)


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import with the session's one signature."""
    from davinci_sim.model.cameras import CameraConfig
    from davinci_sim.tasks import load_task

    task = load_task("seed_path")
    tick = LivePathTick.build(task, TaskMonitor(task), CameraConfig())
    if tick is not None:
        p = np.eye(4)
        p[2, 3] = 0.1
        p.setflags(write=False)  # (Arm._measured_T's)
        for master in (None, np.zeros(3)):
            tick.tick(np.eye(4), (p, np.zeros(3), False, master, (0, 0.0)), 0.0)
            tick.tick(np.eye(4), (p, None, False, master, (0, 0.0)), 0.001)
        tick.tick(np.eye(4), (p, None, False, None, (0, 0.0)), 0.002)
        T = np.tile(np.eye(4), (2, 1, 1))
        assert tick.ticks(T, T.copy(), T.copy(), np.array([0.003, 0.004]), np.zeros(2, int),
                          np.zeros(2))  # fmt: skip


if path_row.COMPILED:
    from davinci_sim.kinematics import jit

    if not jit.warmed_up(_warm_up, "the live path tick cannot be compiled: Python runs"):
        ENABLED = False
