"""Playing a recording back through the simulator: ``davinci-sim replay FILE.mcap``.

:func:`load_recording` reads a session's file (:mod:`.recording`), finished or cut off by a
killed process (:func:`~davinci_sim.records.mcap_file.read_mcap`), into a
:class:`Recording`: the system's description, the task file's text, the recorded calls
with their ticks and the recorded joint positions of the whole model per published tick.

Two ways to play it:

* **inputs** (mode 1, :func:`replay_inputs`, :class:`InputsPart` for ``serve``): a
  simulation built from the recorded description runs the recorded calls (the commands at
  the arms' API, the MTM inputs, the pedals) before the ticks they ran before; everything
  else is recomputed by the physics and the laws. The simulation is deterministic (its
  noise comes from its seed, it never reads the wall clock) and the calls are applied at
  the same ticks, so the replayed states are the recorded ones bit for bit
  (:func:`check_replay` measures it); a file with a call that could not be recorded (an
  argument of a type :mod:`.jsonvalue` does not write) says so in
  :attr:`Recording.unreplayable`.
* **states** (mode 2, :class:`StatePlayback`): the recorded joint positions are put into a
  simulation of the same scene every tick (after its physics step, before the other
  components read it), so viewers see the session as it was; ``speed`` recorded seconds
  per simulated second.

Either way, ``replay`` serves the simulation as ``serve`` does (web console, rosbridge
topics, images); mode 1 at real time or as fast as it computes, mode 2 at any speed.

A recording's ``description.pickle`` is read with a restricted unpickler that builds only
the simulator's own dataclasses and enums and numpy arrays: a file names no other code to run.
"""

from __future__ import annotations

import io
import pickle
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from davinci_sim.records.jsonvalue import decode
from davinci_sim.records.mcap_file import McapContents, read_mcap


class ReplayError(ValueError):
    """A recording that cannot be replayed (no description, another model)."""


_NUMPY = {
    ("numpy.core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "_reconstruct"),
    ("numpy.core.multiarray", "scalar"),
    ("numpy._core.multiarray", "scalar"),
    ("numpy", "ndarray"),
    ("numpy", "dtype"),
}
_BUILTINS = {"frozenset", "set", "tuple", "list", "dict", "complex", "float", "int", "slice"}


class _Unpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str):
        import dataclasses
        import enum

        if (module, name) in _NUMPY or (module == "builtins" and name in _BUILTINS):
            return super().find_class(module, name)
        if module.startswith("numpy.dtypes") or module == "copyreg" and name == "_reconstructor":
            return super().find_class(module, name)
        if module == "davinci_sim" or module.startswith("davinci_sim."):
            obj = super().find_class(module, name)
            if isinstance(obj, type) and (
                dataclasses.is_dataclass(obj) or issubclass(obj, enum.Enum)
            ):
                return obj
        raise pickle.UnpicklingError(f"a recording may not name {module}.{name}")


def safe_unpickle(data: bytes) -> Any:
    """Unpickle ``data`` allowing only davinci_sim's dataclasses and enums, numpy arrays and
    plain containers."""
    return _Unpickler(io.BytesIO(data)).load()


@dataclass(frozen=True)
class Call:
    """One recorded call: ``target.method(*args, **kwargs)`` right before tick ``tick``."""

    seq: int
    tick: int
    target: str
    method: str
    args: tuple
    kwargs: dict


@dataclass
class Recording:
    """A session's recording, read (see the module docstring)."""

    path: Path
    contents: McapContents
    description: Any
    """The recorded :class:`~davinci_sim.system.SystemDescription` (runner ``none``)."""
    task_text: str | None
    calls: list[Call]
    ticks: np.ndarray
    """The published ticks with recorded joint positions, increasing."""
    qpos: np.ndarray
    """(len(ticks), nq) joint positions of the whole model at those ticks."""
    meta: dict[str, str] = field(default_factory=dict)
    unreplayable: list[str] = field(default_factory=list)
    """Calls that could not be recorded (why), in order: a replay of inputs is not exact."""

    @property
    def complete(self) -> bool:
        """The file was closed (not cut off by a killed process)."""
        return self.contents.complete

    @property
    def signature(self) -> str | None:
        return self.meta.get("signature")


def load_recording(path: str | Path) -> Recording:
    """Read the session recording at ``path`` (see the module docstring).

    Raises:
        ReplayError: no description attached (not a session recording).
        McapReadError, OSError: not an MCAP file, not readable.
    """
    contents = read_mcap(path)
    raw = contents.attachments.get("description.pickle")
    if raw is None:
        raise ReplayError(f"{path} has no system description: not a session recording")
    description = safe_unpickle(raw)
    text = contents.attachments.get("task.yaml")
    calls, unreplayable = [], []
    for _, m in contents.topic("/inputs/calls"):
        if "unrecordable" in m:
            unreplayable.append(
                f"{m['target']}.{m['method']} at tick {m['tick']}: {m['unrecordable']}"
            )
            continue
        calls.append(
            Call(
                m["seq"],
                m["tick"],
                m["target"],
                m["method"],
                tuple(decode(m["args"])),
                decode(m["kwargs"]),
            )
        )
    calls.sort(key=lambda c: c.seq)
    q = contents.topic("/sim/qpos")
    ticks = np.array([m["tick"] for _, m in q], dtype=np.int64)
    qpos = np.array([[np.nan if v is None else v for v in m["qpos"]] for _, m in q], dtype=float)
    if len(ticks) and np.any(np.diff(ticks) <= 0):  # (keep the first of a repeated tick)
        keep = np.r_[True, np.diff(ticks) > 0]
        ticks, qpos = ticks[keep], qpos[keep]
    return Recording(
        Path(path),
        contents,
        description,
        None if text is None else text.decode(),
        calls,
        ticks,
        qpos.reshape(len(ticks), -1),
        dict(contents.metadata.get("davinci_sim", {})),
        unreplayable,
    )


def replay_description(recording: Recording, **changes):
    """The recorded description made ready to run here: the task from the recorded file's
    text (a file in the temporary folder named by the text's hash: the replay needs neither
    the original file nor the shipped task's current version), no CSV log (the replay
    appends nothing to the session's log), no input log; ``changes`` on top (runner …)."""
    d = recording.description
    task = d.task
    if task is not None:
        import dataclasses

        source = task.task
        if recording.task_text is not None:  # (one file per task text, reused)
            import hashlib

            digest = hashlib.sha1(recording.task_text.encode()).hexdigest()[:16]
            path = Path(tempfile.gettempdir()) / f"davinci-sim-replay-task-{digest}.yaml"
            if not path.is_file() or path.read_text() != recording.task_text:
                path.write_text(recording.task_text)
            source = str(path)
        task = dataclasses.replace(task, task=source, log=None)
    return d.replace(task=task, record_inputs=False, **changes)


def _check_signature(recording: Recording, sim) -> None:
    expected = recording.signature
    if expected is not None and sim.signature != expected:
        raise ReplayError(
            f"{recording.path} was recorded on another model (signature {expected[:12]}, "
            f"this simulator builds {sim.signature[:12]}): another scene or version"
        )


@dataclass
class ReplayCheck:
    """How far a replay's joint positions are from the recorded ones at the recorded ticks."""

    ticks: int
    """Recorded ticks compared."""
    max_abs_diff: float
    """Largest |replayed - recorded| over all joints and ticks (m or rad; 0: bit-equal)."""
    bit_equal: bool
    first_diff_tick: int | None
    calls: int
    failed_calls: int
    """Calls that raised when replayed (as they may have live: a refused command)."""


def replay_inputs(
    recording: Recording, *, on_tick=None, until_tick: int | None = None
) -> ReplayCheck:
    """Mode 1 without a viewer: run the recorded calls through a simulation built from the
    recording and compare its joint positions with the recorded ones at every recorded tick.
    ``on_tick(sim)`` is called after every tick.

    Raises:
        ReplayError: another model.
    """
    from davinci_sim.sim.handle import execute
    from davinci_sim.system.build import build_simulation

    sim = build_simulation(replay_description(recording, runner="none", publish_qpos=False))
    try:
        _check_signature(recording, sim)
        last = (
            until_tick
            if until_tick is not None
            else int(max([*recording.ticks.tolist(), *(c.tick for c in recording.calls), 0]))
        )
        calls = recording.calls
        ticks = recording.ticks
        k = i = failed = 0
        worst, first, compared = 0.0, None, 0
        while True:
            now = sim.tick_count
            while k < len(ticks) and ticks[k] < now:
                k += 1
            if k < len(ticks) and ticks[k] == now:  # (published after the tick, before calls)
                d = float(np.max(np.abs(sim.data.qpos - recording.qpos[k]), initial=0.0))
                compared += 1
                if d > 0 and first is None:
                    first = now
                worst = max(worst, d)
            while i < len(calls) and calls[i].tick <= now:
                c = calls[i]
                i += 1
                if c.tick < now:
                    continue
                try:
                    execute(sim, c.target, c.method, c.args, c.kwargs)
                except Exception:  # (refused live too)
                    failed += 1
            if now >= last:
                break
            sim.tick()
            if on_tick is not None:
                on_tick(sim)
        return ReplayCheck(compared, worst, worst == 0.0 and compared > 0, first, i, failed)
    finally:
        sim.close()


class StatePlayback:
    """Mode 2: a component that puts the recorded joint positions into the simulation after
    every physics step (velocities zero), so the snapshots, the images and the task session
    show the recording as it was. Add it first (``before=`` the first component) so the
    other components' ``post_step`` read the recorded state: a task session recomputes its
    phase and deviation from the recorded tool (the recorded ones are the file's
    ``/task/state``).

    Args:
        sim: the simulation (same model as the recording).
        ticks, qpos: the recording's ticks and joint positions.
        speed: recorded seconds per simulated second (> 0).
        loop: start again at the end (else hold the last state).
    """

    name = "playback"

    def __init__(
        self, sim, ticks: np.ndarray, qpos: np.ndarray, *, speed: float = 1.0, loop: bool = False
    ) -> None:
        import mujoco

        if not (np.isfinite(speed) and speed > 0):
            raise ValueError(f"speed must be > 0, got {speed!r}")
        if len(ticks) == 0:
            raise ValueError("the recording has no joint positions (/sim/qpos)")
        if qpos.shape[1] != sim.model.nq:
            raise ReplayError(f"recorded qpos has {qpos.shape[1]} joints, the model {sim.model.nq}")
        self._sim, self._mj = sim, mujoco
        self.ticks = np.asarray(ticks, dtype=float) - float(ticks[0])
        self.qpos = qpos
        self.speed = float(speed)
        self.loop = loop
        self._start = sim.tick_count
        self.index = 0
        """Index of the recorded state shown now."""

    def pre_step(self, t: float) -> None:
        pass

    def post_step(self, t: float) -> None:
        sim = self._sim
        at = (sim.tick_count - self._start) * self.speed
        span = self.ticks[-1]
        if self.loop and span > 0:
            at = at % (span + 1)
        self.index = int(np.searchsorted(self.ticks, at, side="right") - 1)
        q = self.qpos[max(self.index, 0)]
        ok = np.isfinite(q)
        sim.data.qpos[ok] = q[ok]
        sim.data.qvel[:] = 0.0
        self._mj.mj_forward(sim.model, sim.data)

    @property
    def finished(self) -> bool:
        return not self.loop and self.index >= len(self.ticks) - 1

    def snapshot(self) -> dict:
        return {"index": self.index, "of": len(self.ticks), "speed": self.speed}

    def get_state(self) -> dict:
        return {"start": self._start}

    def set_state(self, state: dict) -> None:
        self._start = state["start"]


def replay_system(
    recording: Recording,
    mode: str = "inputs",
    *,
    speed: float = 1.0,
    loop: bool = False,
    render_hz: float | None = None,
    snapshot_period: float = 0.01,
):
    """The recording as a running system to serve (not started): the simulation built here
    behind a thread runner (:class:`~davinci_sim.sim.handle.ThreadedSimulation`).

    ``mode="inputs"``: built from the recorded description, the recorded calls queued for
    their ticks; paced at ``speed`` times real time (0: as fast as it computes).
    ``mode="states"``: the recorded scene (and task drawing) with a :class:`StatePlayback`
    first in the tick at ``speed`` recorded seconds per second (``loop``: start again at
    the end), paced at real time.

    Raises:
        ReplayError: another model, no recorded states for mode ``states``.
        ValueError: a bad mode or speed.
    """
    from davinci_sim.sim.handle import ThreadedSimulation
    from davinci_sim.system.build import System

    description, sim = _build(recording, mode, speed, loop)
    try:
        real_time = mode == "states" or speed > 0
        handle = ThreadedSimulation(
            sim,
            real_time=real_time,
            snapshot_period=snapshot_period,
            render_hz=render_hz,
            render_model=_model_of(description),
            speed=speed if mode == "inputs" and speed > 0 else 1.0,
        )
        if mode == "inputs":
            for c in recording.calls:
                handle.call_at(c.tick, c.target, c.method, *c.args, **c.kwargs)
    except BaseException:
        sim.close()
        raise
    return System(description.replace(runner="thread", render_hz=render_hz), sim, handle)


def _model_of(description):
    import functools

    from davinci_sim.system.build import scene_model

    return functools.partial(scene_model, description)


def _build(recording: Recording, mode: str, speed: float, loop: bool = False):
    """The description and the simulation of a replay (see :func:`replay_system`)."""
    from davinci_sim.system.build import build_simulation

    if mode not in ("inputs", "states"):
        raise ValueError(f"mode must be inputs or states, not {mode!r}")
    if not (np.isfinite(speed) and speed >= 0) or (mode == "states" and speed == 0):
        raise ValueError(
            f"speed must be > 0 (or 0 for inputs: as fast as it computes), got {speed!r}"
        )
    changes: dict = {"runner": "none", "publish_qpos": True, "render_hz": None}
    if mode == "states":  # nothing drives the arms: no homing
        changes["home"] = False
    description = replay_description(recording, **changes)
    sim = build_simulation(description)
    try:
        _check_signature(recording, sim)
        if mode == "states":
            if len(recording.ticks) == 0:
                raise ReplayError(f"{recording.path} has no recorded joint positions")
            first = next(iter(sim.components), None)
            playback = StatePlayback(sim, recording.ticks, recording.qpos, speed=speed, loop=loop)
            sim.add_component(playback, before=first)
    except BaseException:
        sim.close()
        raise
    return description, sim


def replay_states(recording: Recording, *, speed: float = 1.0, on_tick=None) -> ReplayCheck:
    """Mode 2 without a viewer: play the recorded states into a simulation of the recorded
    scene (:class:`StatePlayback`) and compare its joint positions, after each tick, with
    the recorded state it shows. ``on_tick(sim)`` is called after every tick."""
    _, sim = _build(recording, "states", speed)
    try:
        playback = sim.components["playback"]
        worst, first, compared = 0.0, None, 0
        while True:
            sim.tick()
            if on_tick is not None:
                on_tick(sim)
            q = recording.qpos[playback.index]
            ok = np.isfinite(q)
            d = float(np.max(np.abs(sim.data.qpos[ok] - q[ok]), initial=0.0))
            compared += 1
            if d > 0 and first is None:
                first = sim.tick_count
            worst = max(worst, d)
            if playback.finished:
                break
        return ReplayCheck(compared, worst, worst == 0.0, first, 0, 0)
    finally:
        sim.close()
