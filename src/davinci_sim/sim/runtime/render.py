"""The stereo render pipeline: the endoscope rendered in its own process from joint positions.

Rendering a 640x480 stereo pair costs ~22 ms of CPU (llvmpipe); in the loop process it
would stall the 1 kHz tick, and in any thread of it the GIL would. :class:`StereoRenderer`
starts the render process (a plain ``python`` subprocess, not ``multiprocessing``: it
does not re-import the caller's main module, so any script can render): it builds the model (the
scene, or a picklable model factory such as :func:`davinci_sim.system.build.scene_model`
that also draws the task), reads the latest ``qpos`` from shared memory
(:class:`~davinci_sim.sim.runtime.shm.LatestSlot`), runs MuJoCo's kinematics and renders
both endoscope cameras at the requested rate, whenever the joint positions are new and
someone asked for a frame in the last second (:data:`ON_DEMAND_S`); the frames come back
through shared memory (:meth:`StereoRenderer.frame`).

The ``qpos`` comes from whoever owns the simulation: the process runner's loop writes it
every tick into the renderer's slot (1 µs), the thread runner likewise, and a renderer fed
from snapshots (the bridge's image topics on a handle that does not render) calls
:meth:`StereoRenderer.feed`. This is the one stereo render path: the runners' frames
(``handle.stereo_frame()``), the bridge's image topics and the web console's view use it.
"""

from __future__ import annotations

import logging
import os
import pickle
import struct
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from davinci_sim.sim.component import IDLE
from davinci_sim.sim.runtime.loop import frozen_heap
from davinci_sim.sim.runtime.shm import LatestSlot, SharedBuffer

_log = logging.getLogger("davinci_sim.render")

#: Header of a qpos message: tick (int64), time (float64), nq (int64).
QPOS_HEADER = struct.Struct("<qdq")
#: Header of a frame message: tick, time, frame number, width, height, render time (s).
FRAME_HEADER = struct.Struct("<qdqqqd")
#: Render statistics block (float64): frames, sum of render times, max, first/last wall,
#: (unused), when a frame was last asked for (``time.monotonic``, set by the owner's
#: :meth:`StereoRenderer.frame`); the last field is the stop request (set by the owner).
STATS_FIELDS = 8
_ASKED = 6
_STOP = STATS_FIELDS - 1
#: The render process renders only while frames are asked for: after the first frame, a
#: new state is drawn only if :meth:`StereoRenderer.frame` was called within this many s
#: (a page that draws the endoscope itself, no image subscriber: no core spent rendering).
ON_DEMAND_S = 1.0
STATS_BYTES = 8 * STATS_FIELDS


def frame_buffer_size(width: int, height: int) -> int:
    """Bytes of the shared buffer for stereo frames of this size."""
    return STATS_BYTES + LatestSlot.size_for(FRAME_HEADER.size + 2 * width * height * 3)


@dataclass(frozen=True, eq=False)
class StereoFrame:
    """One rendered stereo pair."""

    left: np.ndarray
    """RGB, (height, width, 3) uint8."""
    right: np.ndarray
    tick: int
    """Simulation tick of the joint positions it shows."""
    time: float
    """Simulation time of those, s."""
    frame: int
    """Frame number (from 1)."""
    render_time: float
    """Wall time the pair took to render, s."""


@dataclass(frozen=True)
class RenderStatistics:
    frames: int
    rate_hz: float
    """Frames per second of wall time since the first frame."""
    render_mean: float
    """Mean wall time per stereo pair, s."""
    render_max: float


def decode_frame(data: bytes) -> StereoFrame:
    tick, t, frame, width, height, render_time = FRAME_HEADER.unpack_from(data)
    n = width * height * 3
    off = FRAME_HEADER.size
    left = np.frombuffer(data, dtype=np.uint8, count=n, offset=off).reshape(height, width, 3)
    right = np.frombuffer(data, dtype=np.uint8, count=n, offset=off + n).reshape(height, width, 3)
    return StereoFrame(left, right, tick, t, frame, render_time)


def render_statistics(buffer: SharedBuffer) -> RenderStatistics:
    s = np.ndarray((STATS_FIELDS,), dtype=np.float64, buffer=buffer.mm).copy()
    frames = int(s[0])
    elapsed = s[4] - s[3]
    return RenderStatistics(
        frames=frames,
        rate_hz=(frames - 1) / elapsed if frames > 1 and elapsed > 0 else float("nan"),
        render_mean=s[1] / frames if frames else float("nan"),
        render_max=float(s[2]) if frames else float("nan"),
    )


class QposProbe:
    """A simulation component that publishes a copy of ``qpos`` in each snapshot's extras
    (``extras["qpos"]``), so a renderer fed from snapshots sees a consistent state. Register
    it with ``sim.add_component(QposProbe(sim))`` before the loop starts."""

    name = "qpos"

    def __init__(self, sim: Any) -> None:
        self._sim = sim

    def pre_step(self, t: float) -> None:
        pass

    def chunk_part(self) -> str:
        """Idle in the console's compiled ticks: the probe reads ``qpos`` only when asked."""
        return IDLE

    def snapshot(self) -> np.ndarray:
        q = self._sim.data.qpos.copy()
        q.setflags(write=False)
        return q

    def get_state(self) -> None:
        """No state: the probe only copies ``qpos`` when asked."""

    def set_state(self, state: None) -> None:
        pass


#: Capacity of a joint-position slot, bytes (8000 joints).
QPOS_CAPACITY = 64 * 1024


class StereoRenderer:
    """The render process and its shared buffers; see the module docstring.

    Args:
        scene: the scene (name or config): its endoscope gives the image size, and without
            ``model`` the process builds the scene's model.
        rate_hz: frames per second at most.
        model: picklable callable returning the compiled ``MjModel`` to render (e.g. the
            scene with a task's drawing); it must have the scene's joints.
        qpos_path: the shared buffer the owner writes ``qpos`` messages to (the process
            runner's); None: a buffer of this renderer's own, written with :meth:`feed`.
        cpu: pin the render process to this CPU; threads: rasteriser threads of Mesa's
            llvmpipe (``LP_NUM_THREADS``; None: one per core).
    """

    def __init__(
        self,
        scene,
        rate_hz: float,
        *,
        model: Callable[[], Any] | None = None,
        qpos_path: str | None = None,
        cpu: int | None = None,
        threads: int | None = None,
    ) -> None:
        from davinci_sim.model import resolve_scene

        if not (rate_hz > 0 and np.isfinite(rate_hz)):
            raise ValueError(f"rate_hz must be > 0, got {rate_hz!r}")
        self.scene = resolve_scene(scene)
        self.rate_hz = float(rate_hz)
        self.width, self.height = self.scene.endoscope.width, self.scene.endoscope.height
        self._model = model
        self._cpu, self._threads = cpu, threads
        own = qpos_path is None
        self._qpos_buffer = SharedBuffer(LatestSlot.size_for(QPOS_CAPACITY)) if own else None
        self.qpos_path = self._qpos_buffer.path if self._qpos_buffer else qpos_path
        self._qslot = LatestSlot(self._qpos_buffer) if self._qpos_buffer else None
        self._frames = SharedBuffer(frame_buffer_size(self.width, self.height))
        self._fslot = LatestSlot(self._frames, offset=STATS_BYTES)
        self._stats = np.ndarray((STATS_FIELDS,), dtype=np.float64, buffer=self._frames.mm)
        self.process: subprocess.Popen | None = None

    @property
    def pid(self) -> int | None:
        return None if self.process is None else self.process.pid

    def start(self) -> StereoRenderer:
        if self.process is not None:
            return self
        env = dict(os.environ)
        env.setdefault("MUJOCO_GL", "egl")
        if self._threads is not None:
            env["LP_NUM_THREADS"] = str(int(self._threads))
        self.process = subprocess.Popen(
            [sys.executable, "-c", _CHILD],
            stdin=subprocess.PIPE,
            env=env,
        )
        config = (self._model or self.scene, self.qpos_path, self._frames.path, self.rate_hz,
                  self._cpu, os.getpid(), self.width, self.height)  # fmt: skip
        self.process.stdin.write(pickle.dumps(config))
        self.process.stdin.close()
        return self

    def feed(self, tick: int, t: float, qpos: np.ndarray) -> None:
        """Give the joint positions of simulation tick ``tick`` (time ``t``, s) to render."""
        if self._qslot is None:
            raise RuntimeError("this renderer reads the joint positions its owner publishes")
        q = np.ascontiguousarray(qpos, dtype=np.float64)
        self._qslot.write(QPOS_HEADER.pack(tick, t, q.size), q)

    def frame(self) -> StereoFrame | None:
        """The latest rendered pair, or None yet; asking keeps the process rendering
        (:data:`ON_DEMAND_S`)."""
        self._stats[_ASKED] = time.monotonic()
        data = self._fslot.read()
        return None if data is None else decode_frame(data)

    def statistics(self) -> RenderStatistics:
        return render_statistics(self._frames)

    @property
    def running(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the render process and release the buffers (idempotent)."""
        if self.process is not None:
            self._stats[_STOP] = 1.0
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(timeout)
            self.process = None
        del self._stats
        self._stats = np.zeros(STATS_FIELDS)
        self._fslot = None
        self._frames.close()
        if self._qpos_buffer is not None:
            self._qslot = None
            self._qpos_buffer.close()


class StereoFrames:
    """Stereo frames of a running simulation for a viewer (the bridge's image topics, the
    web console's view): the handle's own renderer if it has one (a runner created with
    ``render_hz``: ``handle.stereo_frame()``), else a :class:`StereoRenderer` of this
    object's, started on the first :meth:`latest` and fed the snapshots' ``qpos`` (see
    :class:`QposProbe`; without it, ``qpos`` is asked from the loop between two ticks).

    Args:
        handle: the running simulation (a ``SimHandle``).
        scene: its scene (name or config).
        rate_hz: frames per second wanted (the renderer's speed caps it).
        model: picklable callable returning the model to render (the system's, with the
            task's drawing: :attr:`davinci_sim.system.System.model_source`).
        use_handle: take the handle's frames; None: if it has ``stereo_frame``.
        retry_after: s before starting a renderer again after it failed or exited.
    """

    def __init__(
        self,
        handle: Any,
        scene,
        rate_hz: float,
        *,
        model: Callable[[], Any] | None = None,
        use_handle: bool | None = None,
        retry_after: float = 10.0,
    ) -> None:
        from davinci_sim.model import resolve_scene

        self.handle = handle
        self.scene = resolve_scene(scene)
        self.rate_hz = rate_hz
        self.model = model
        self.retry_after = retry_after
        # (a runner says whether it was created with a renderer: ``renders``)
        has_frames = callable(getattr(handle, "stereo_frame", None))
        has_frames = has_frames and getattr(handle, "renders", True)
        self.from_handle = has_frames if use_handle is None else use_handle and has_frames
        self.renderers: list[StereoRenderer] = []
        """The renderer of this object (empty until used, or when the handle renders)."""
        self._retry_at = 0.0
        self._pending_qpos = False

    @property
    def pid(self) -> int | None:
        """Process id of this object's render process (None: none)."""
        return self.renderers[0].pid if self.renderers else None

    def latest(self) -> StereoFrame | None:
        """The latest frame (None yet); with a renderer of ours, first give it the latest
        joint positions. Call it at the viewer's rate, from one thread."""
        if self.from_handle:
            try:
                return self.handle.stereo_frame()
            except Exception as e:  # e.g. a runner started without a renderer: use ours
                _log.warning("the handle does not render (%s); rendering here", e)
                self.from_handle = False
                return None
        renderer = self._renderer()
        if renderer is None:
            return None
        self._feed(renderer)
        return renderer.frame()

    def stop(self) -> None:
        """Stop our render process (if any); :meth:`latest` starts a new one."""
        for r in self.renderers:
            r.stop()
        self.renderers.clear()

    def _renderer(self) -> StereoRenderer | None:
        if self.renderers and not self.renderers[0].running:
            _log.error("the render process exited; restarting in %g s", self.retry_after)
            self.stop()
            self._retry_at = time.monotonic() + self.retry_after
        if not self.renderers:
            if time.monotonic() < self._retry_at:
                return None
            try:
                r = StereoRenderer(self.scene, self.rate_hz, model=self.model).start()
            except Exception:
                _log.exception("cannot start the render process; retrying later")
                self._retry_at = time.monotonic() + self.retry_after
                return None
            self.renderers.append(r)
        return self.renderers[0]

    def _feed(self, renderer: StereoRenderer) -> None:
        snap = self.handle.snapshot()
        qpos = snap.extras.get("qpos") if snap.extras else None
        if qpos is not None:
            renderer.feed(snap.tick, snap.time, qpos)
            return
        if self._pending_qpos:
            return
        self._pending_qpos = True  # one request at a time: the slot has one writer
        future = self.handle.call("sim", "measured_qpos")

        def got(f) -> None:
            if f.exception() is None and self.renderers and self.renderers[0] is renderer:
                snap = self.handle.snapshot()
                renderer.feed(snap.tick, snap.time, np.asarray(f.result(), dtype=float))
            self._pending_qpos = False

        future.add_done_callback(got)


def render_main(model_source, qpos_path: str, frames_path: str, rate_hz: float, cpu,
                parent: int | None, width: int, height: int) -> None:  # fmt: skip
    """The render process's loop (see :class:`StereoRenderer`): until the stop flag is set or
    the parent process exits."""
    if cpu is not None and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {cpu})
    import mujoco

    from davinci_sim.model import build_model, resolve_scene
    from davinci_sim.model.config import SceneConfig
    from davinci_sim.sim.sensors import CameraRenderer

    if isinstance(model_source, str | SceneConfig):
        scene = resolve_scene(model_source)
        model = build_model(scene)
    else:
        model = model_source()
    data = mujoco.MjData(model)
    renderer = CameraRenderer(model)
    qpos_buf = SharedBuffer(path=qpos_path)
    qslot = LatestSlot(qpos_buf)
    frames_buf = SharedBuffer(path=frames_path)
    stats = np.ndarray((STATS_FIELDS,), dtype=np.float64, buffer=frames_buf.mm)
    fslot = LatestSlot(frames_buf, offset=STATS_BYTES)
    period = 1.0 / rate_hz
    frame = 0
    last_tick = None
    next_time = time.perf_counter()
    try:
        with frozen_heap():  # no full collection over the model mid-run
            while not stats[_STOP] and (parent is None or os.getppid() == parent):
                now = time.perf_counter()
                if now < next_time:
                    time.sleep(min(next_time - now, 0.05))
                    continue
                msg = qslot.read()
                if msg is None or QPOS_HEADER.unpack_from(msg)[0] == last_tick:
                    next_time = now + min(period, 0.005)  # nothing new: look again soon
                    continue
                if frame > 0 and time.monotonic() - stats[_ASKED] > ON_DEMAND_S:
                    next_time = now + min(period, 0.02)  # nobody looks: draw nothing
                    continue
                next_time = max(next_time + period, now - period)
                tick, t, nq = QPOS_HEADER.unpack_from(msg)
                last_tick = tick
                data.qpos[:] = np.frombuffer(msg, np.float64, nq, QPOS_HEADER.size)
                start = time.perf_counter()
                mujoco.mj_kinematics(model, data)
                mujoco.mj_camlight(model, data)
                left = renderer.render(data, "ECM/left", width, height, fast=True)
                right = renderer.render(data, "ECM/right", width, height, fast=True)
                elapsed = time.perf_counter() - start
                frame += 1
                header = FRAME_HEADER.pack(tick, t, frame, width, height, elapsed)
                fslot.write(header, left, right)
                stats[0] = frame
                stats[1] += elapsed
                stats[2] = max(stats[2], elapsed)
                if frame == 1:
                    stats[3] = start
                stats[4] = start
    finally:
        renderer.close()


def _child_main() -> None:
    render_main(*pickle.loads(sys.stdin.buffer.read()))


_CHILD = "from davinci_sim.sim.runtime.render import _child_main; _child_main()"
