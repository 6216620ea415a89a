"""Recording a running session to an MCAP file: ``davinci-sim serve --record FILE.mcap``.

:class:`SessionRecorder` attaches to a running system's handle (the thread or the process
runner alike) and writes, in its own thread, never in the loop:

* every published snapshot (the ``serve`` publish period, 10 ms by default): each arm's
  ``measured_js``, ``setpoint_js`` and jaw/gripper (``davinci_sim.JointState``), the
  Cartesian arms' ``measured_cp`` and ``setpoint_cp`` (``foxglove.PoseInFrame``) and the
  measured ones as
  ``/tf`` (``foxglove.FrameTransforms``), the whole model's joint positions (``/sim/qpos``),
  the wrench sent to each MTM (``/<MTM>/wrench``), the task session's state (phase,
  repetition, distance: ``/task/state``), the console's and every other component's state
  (``/components/<name>``);
* every event (``/events``: console buttons, teleoperation states, the task's phases;
  ``/task/results``: each finished repetition's metrics; ``/rosout``: the arms' messages as
  ``foxglove.Log``);
* optionally, the stereo endoscope's images as JPEG (``foxglove.CompressedImage`` on
  ``/endoscope/left/compressed`` and ``/endoscope/right/compressed``, ``--record-images HZ``);
* every call the handle ran, with its tick (``/inputs/calls``, from the simulation's input
  log, :mod:`davinci_sim.sim.inputs`): the commands at the arms' API (``servo_cp``,
  ``servo_jp``, ``jaw/servo_jp``, ``move_*``, ``state_command``), the MTM inputs (the web
  console's hand velocity, a client's MTM pose, the pedals), condition changes — what a
  replay runs again (:mod:`~davinci_sim.records.replay`);
* at the start, the system's description (attachments ``description.json``, readable, and
  ``description.pickle``, what a replay rebuilds from), the task file's text
  (``task.yaml``), and metadata ``davinci_sim`` (software versions, the model's signature,
  scene, seed, task, condition and its fixture's parameters): the file alone is enough to
  replay the session.

The system must be built with ``record_inputs=True`` and ``publish_qpos=True``
(:func:`recording_description` sets both); ``serve --record`` does.
"""

from __future__ import annotations

import json
import logging
import pickle
import queue
import threading
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from davinci_sim.records.jsonvalue import encode, plain
from davinci_sim.records.mcap_file import McapWriter
from davinci_sim.records.mcap_schemas import stamp, time_ns
from davinci_sim.records.messages import write_images, write_snapshot

_log = logging.getLogger("davinci_sim.records")

_LEVELS = {"debug": 1, "info": 2, "status": 2, "warning": 3, "error": 4, "fatal": 5}


def recording_description(description):
    """``description`` with what a recording needs: the input log and ``qpos`` in the
    snapshots."""
    return description.replace(record_inputs=True, publish_qpos=True)


def software_versions() -> dict[str, str]:
    """The versions of davinci-sim, MuJoCo, numpy and Python."""
    import platform
    from importlib.metadata import PackageNotFoundError, version

    import mujoco
    import numpy

    try:
        own = version("davinci-sim")
    except PackageNotFoundError:
        own = "unknown"
    return {
        "davinci_sim": own,
        "mujoco": mujoco.__version__,
        "numpy": numpy.__version__,
        "python": platform.python_version(),
    }


def task_text(task: str) -> str | None:
    """The text of the task file ``task`` names (a shipped task's name or a path)."""
    from importlib import resources

    path = Path(task)
    if path.suffix in (".yaml", ".yml", ".json") and path.is_file():
        return path.read_text()
    for suffix in (".yaml", ".yml", ".json"):
        candidate = resources.files("davinci_sim.tasks") / "data" / f"{task}{suffix}"
        if candidate.is_file():
            return candidate.read_text()
    return None


def write_header(
    writer: McapWriter,
    kind: str,
    *,
    description=None,
    info: dict | None = None,
    extra: dict | None = None,
) -> None:
    """The self-describing start of a recording: metadata ``davinci_sim`` (kind, versions,
    start time, the model's signature and sizes from ``info``, ``extra``) and, with a
    ``description``, its attachments and the task's file and fixture."""
    meta: dict[str, Any] = {
        "kind": kind,
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        **software_versions(),
        **(info or {}),
        **(extra or {}),
    }
    if description is not None:
        meta.update(
            scene=plain(description.scene),
            keyframe=description.keyframe,
            seed=description.seed,
            home=description.home,
        )
        writer.attach(
            "description.json",
            "application/json",
            json.dumps(plain(description), indent=1).encode(),
        )
        writer.attach(
            "description.pickle",
            "application/x-python-pickle",
            pickle.dumps(
                description.replace(
                    runner="none",
                    start_paused=False,
                    render_hz=None,
                    realtime_priority=None,
                    loop_cpu=None,
                )
            ),
        )
        if description.task is not None:
            t = description.task
            meta.update(task=t.task, condition=plain(t.condition))
            text = task_text(t.task)
            if text is not None:
                writer.attach("task.yaml", "text/yaml", text.encode())
            try:
                from davinci_sim.records.console import condition_settings
                from davinci_sim.tasks import load_task

                meta["fixture"] = plain(condition_settings(load_task(t.task), t.condition))
            except Exception as e:  # (the file is still worth writing)
                meta["fixture"] = f"unknown ({e})"
    writer.metadata("davinci_sim", meta)
    writer.flush()


class SessionRecorder:
    """Records a running system to ``path``; see the module docstring.

    Args:
        path: the MCAP file (created; its folder must exist).
        description: the system's description (attached; what a replay rebuilds).
        poll: how often, s of wall time, the recorder looks for a new snapshot.
        period: simulated time, s, between two recorded snapshots at least (0: every
            snapshot the runner publishes, 10 ms by default; the recorder's cost is per
            snapshot, ~27 messages for the task scene).
        on_error: told, once, if writing fails (the simulation goes on; default: logged).
        frames: the stereo endoscope's frames to record (``System.frames(rate)``: a
            :class:`~davinci_sim.sim.runtime.render.StereoFrames`), each new pair as two
            ``foxglove.CompressedImage`` (JPEG) on ``/endoscope/{left,right}/compressed``;
            None: no images. The recorder stops it.
        jpeg_quality: JPEG quality of the images (1-95).
    """

    def __init__(
        self,
        path: str | Path,
        description,
        *,
        poll: float = 0.002,
        period: float = 0.0,
        on_error: Callable[[str], None] | None = None,
        frames=None,
        jpeg_quality: int = 80,
    ) -> None:
        self.path = Path(path)
        self.frames = frames
        self.jpeg_quality = int(jpeg_quality)
        self.images = 0
        """Stereo pairs written so far."""
        self._frame = 0
        self.description = description
        self.poll = poll
        if not (period >= 0):
            raise ValueError(f"the recording period must be >= 0 s, got {period!r}")
        self.period = float(period)
        self.on_error = on_error
        self._events: queue.SimpleQueue = queue.SimpleQueue()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._unsubscribe: Callable[[], None] | None = None
        self._writer: McapWriter | None = None
        self._last_tick = -1
        self._last_time = 0.0
        self._seen_seq = 0
        self.snapshots = 0
        """Snapshots written so far."""
        self.calls = 0
        """Calls written so far."""
        self.error: str | None = None

    def attach(self, handle) -> SessionRecorder:
        """Subscribe to ``handle``'s events, write the header, start the writer thread.

        Raises:
            RuntimeError: the system has no input log (built without ``record_inputs``).
            OSError: the file cannot be created.
        """
        self._writer = McapWriter(self.path)
        self._unsubscribe = handle.subscribe(self._on_event)
        try:
            info = handle.call("inputs", "info").result(30)
            earlier = handle.call("inputs", "drain").result(30)
        except (KeyError, AttributeError) as e:
            self._unsubscribe()
            self._writer.close()
            raise RuntimeError(
                "the system has no input log: build it with record_inputs=True "
                f"(records.recording_description) ({e})"
            ) from None
        self._dt = info["dt"]
        write_header(self._writer, "session", description=self.description, info=info)
        for entry in earlier:
            self._events.put(("inputs", "call", entry))
        self._handle = handle
        self._thread = threading.Thread(target=self._run, name="recording", daemon=True)
        self._thread.start()
        return self

    def _on_event(self, source: str, event: str, payload: object) -> None:
        self._events.put((source, event, payload))  # (the loop's thread: only hand it over)

    def stop(self, timeout: float | None = 10.0) -> None:
        """Write what is pending, the last snapshot, the summary; close the file."""
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None
        if self.frames is not None:
            self.frames.stop()

    # ------------------------------------------------------------ the writer thread
    def _run(self) -> None:
        try:
            while not self._stop.wait(self.poll):
                self._step()
            self._step()
        except Exception as e:  # a full disk: say so once, stop recording, go on serving
            self.error = f"recording to {self.path} stopped: {type(e).__name__}: {e}"
            _log.error("%s", self.error)
            if self.on_error is not None:
                self.on_error(self.error)
        finally:
            try:
                self._writer.close()
            except Exception:
                _log.exception("closing the recording failed")

    def _step(self) -> None:
        while True:
            try:
                source, event, payload = self._events.get_nowait()
            except queue.Empty:
                break
            self._write_event(source, event, payload)
        snap = self._handle.snapshot()
        if snap.tick != self._last_tick and (
            self._last_tick < 0 or snap.time - self._last_time >= self.period - 1e-9
        ):
            self._last_tick = snap.tick
            write_snapshot(self._writer, snap)
            self._last_time = snap.time
            self.snapshots += 1
        if self.frames is not None:
            frame = self.frames.latest()
            if frame is not None and frame.frame != self._frame:
                self._frame = frame.frame
                write_images(self._writer, frame, self.jpeg_quality)
                self.images += 1

    def _write_event(self, source: str, event: str, payload: object) -> None:
        w = self._writer
        if source == "inputs" and event == "call":
            seq, tick, target, method, args, kwargs = payload
            if seq <= self._seen_seq:  # (drained and received as an event)
                return
            self._seen_seq = seq
            t = tick * self._dt
            try:
                message = {
                    "seq": seq,
                    "tick": tick,
                    "target": target,
                    "method": method,
                    "args": encode(list(args)),
                    "kwargs": encode(dict(kwargs)),
                }
            except TypeError as e:  # kept as text: a replay says it cannot run it
                message = {
                    "seq": seq,
                    "tick": tick,
                    "target": target,
                    "method": method,
                    "args": [],
                    "kwargs": {},
                    "unrecordable": str(e),
                }
            w.write(
                "/inputs/calls", "davinci_sim.Call", time_ns(t), {"timestamp": stamp(t), **message}
            )
            self.calls += 1
            return
        t = float(getattr(payload, "timestamp", None) or self._last_time)
        ns, ts = time_ns(t), stamp(t)
        if source == "task" and event == "results":
            w.write(
                "/task/results",
                "davinci_sim.Event",
                ns,
                {"timestamp": ts, "source": source, "event": event, "payload": plain(payload)},
            )
            return
        if event in _LEVELS and hasattr(payload, "text"):
            w.write(
                "/rosout",
                "foxglove.Log",
                ns,
                {
                    "timestamp": ts,
                    "level": _LEVELS[event],
                    "message": str(payload.text),
                    "name": source,
                    "file": "",
                    "line": 0,
                },
            )
        w.write(
            "/events",
            "davinci_sim.Event",
            ns,
            {"timestamp": ts, "source": source, "event": event, "payload": plain(payload)},
        )


class RecordingPart:
    """``serve --record FILE``: a ``serve`` part that records the served system (built with
    :func:`recording_description`) to ``path``; adds ``recording`` to the ready info."""

    def __init__(self, path: str | Path, images_hz: float | None = None,
                 rate_hz: float | None = None) -> None:  # fmt: skip
        self.path = Path(path)
        self.images_hz = images_hz
        self.period = 0.0 if rate_hz is None else 1.0 / rate_hz
        self.recorder: SessionRecorder | None = None

    def __call__(self, system, info: dict) -> SessionRecorder:
        handle = system.handle
        frames = None if self.images_hz is None else system.frames(self.images_hz)

        def on_error(text: str) -> None:
            try:
                handle.call("task", "report", "error", text)
            except Exception:
                pass

        self.recorder = SessionRecorder(self.path, system.description, on_error=on_error,
                                        frames=frames, period=self.period)  # fmt: skip
        info["recording"] = str(self.path)
        return self.recorder.attach(handle)


def recording_part(path: str | Path, images_hz: float | None = None,
                   rate_hz: float | None = None) -> RecordingPart:  # fmt: skip
    """A ``serve`` part recording the session to ``path`` (see :class:`RecordingPart`),
    with the stereo endoscope's images at ``images_hz`` (None: none), the states at
    ``rate_hz`` at most (None: every published snapshot).

    Raises:
        ValueError: a rate that is not > 0.
    """
    for name, rate in (("image", images_hz), ("state", rate_hz)):
        if rate is not None and not (rate > 0 and rate < float("inf")):
            raise ValueError(f"the {name} rate must be > 0 Hz, got {rate!r}")
    return RecordingPart(path, images_hz, rate_hz)
