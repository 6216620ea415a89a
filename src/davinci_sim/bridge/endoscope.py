"""Stereo endoscope images over the bridge, rendered in a separate process.

Topics (the layout of the dVRK's stereo pipeline, ``/<rig>/{left,right}/…`` with
image_transport names): ``image_raw/compressed`` (``sensor_msgs/CompressedImage``, JPEG, the
default), ``image_raw`` (``sensor_msgs/Image`` rgb8, by option) and ``camera_info``
(``sensor_msgs/CameraInfo``: pinhole from the endoscope's field of view, the right camera's
projection carries the stereo baseline).

Rendering a stereo pair takes ~22 ms of CPU; done in the simulation's thread it would stall
the 1 kHz loop, and in this process it would hold the GIL. So a :class:`RenderWorker` process
builds the same MuJoCo model, receives joint positions (``qpos``) at the image rate, renders
both cameras and JPEG-encodes them; the bridge only forwards bytes. Frames are requested
only while someone subscribes, one at a time (the rate is capped by the worker).

A handle that renders by itself (a runner with ``stereo_frame()``, such as the process
runner of :mod:`davinci_sim.sim.runtime`) is used instead: its latest frame is taken at the
image rate and JPEG-encoded in a worker thread (Pillow releases the interpreter lock).
"""

from __future__ import annotations

import asyncio
import logging
import math
import os
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from davinci_sim.bridge.rosbridge.publisher import PeriodicTask

if TYPE_CHECKING:
    from davinci_sim.bridge.rosbridge.core import Bridge
    from davinci_sim.model.config import SceneConfig
    from davinci_sim.sim.handle import SimHandle

_log = logging.getLogger("davinci_sim.bridge")

NODE = "/davinci_sim/endoscope"
PIPELINE_DEPTH = 2
"""Requests sent ahead to the render process, so it never waits for the next one."""
CAMERAS = (("left", "ECM/left"), ("right", "ECM/right"))


class QposProbe:
    """A simulation component that publishes a copy of ``qpos`` in each snapshot's extras
    (``extras["qpos"]``), so a renderer elsewhere sees a consistent state. Register it with
    ``sim.add_component(QposProbe(sim))`` before the loop starts."""

    def __init__(self, sim: Any) -> None:
        self._sim = sim

    def pre_step(self, t: float) -> None:
        pass

    def snapshot(self) -> np.ndarray:
        q = self._sim.data.qpos.copy()
        q.setflags(write=False)
        return q

    name = "qpos"

    def get_state(self) -> None:
        """No state: the probe only copies ``qpos`` when asked."""

    def set_state(self, state: None) -> None:
        pass


# =========================================================================== camera info
def camera_info(
    d: Any, width: int, height: int, fovy_deg: float, baseline: float, side: str, stamp: float
) -> dict:
    """``sensor_msgs/CameraInfo`` of an ideal pinhole (no distortion, square pixels).

    ``fy = (h / 2) / tan(fovy / 2)``; the right camera's ``P[3] = -fx · baseline`` (the ROS
    stereo convention), the left one's 0.
    """
    f = 0.5 * height / math.tan(math.radians(fovy_deg) / 2)
    cx, cy = 0.5 * width, 0.5 * height
    K = [f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0]
    R = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    tx = -f * baseline if side == "right" else 0.0
    P = [f, 0.0, cx, tx, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    names = ("D", "K", "R", "P") if d.ros_version == 1 else ("d", "k", "r", "p")
    return {
        "header": d.header(stamp, f"ECM_{side}"),
        "height": height,
        "width": width,
        "distortion_model": "plumb_bob",
        names[0]: [0.0, 0.0, 0.0, 0.0, 0.0],
        names[1]: K,
        names[2]: R,
        names[3]: P,
        "binning_x": 0,
        "binning_y": 0,
        "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0, "do_rectify": False},
    }


# =========================================================================== the worker
def _encode_pair(left, right, encoding: str, quality: int):
    """``(jpeg pair | None, raw pair | None, seconds)`` of two RGB arrays."""
    import io

    from PIL import Image

    t0 = time.perf_counter()
    jpeg = raw = None
    if encoding in ("jpeg", "both"):
        out = []
        for rgb in (left, right):
            buf = io.BytesIO()
            Image.fromarray(np.ascontiguousarray(rgb)).save(buf, format="JPEG", quality=quality)
            out.append(buf.getvalue())
        jpeg = (out[0], out[1])
    if encoding in ("raw", "both"):
        raw = (np.ascontiguousarray(left).tobytes(), np.ascontiguousarray(right).tobytes())
    return jpeg, raw, time.perf_counter() - t0


@dataclass(frozen=True)
class Frame:
    """One rendered stereo pair: JPEG and/or raw RGB bytes (left, right), with its timing."""

    stamp: float
    jpeg: tuple[bytes, bytes] | None
    raw: tuple[bytes, bytes] | None
    width: int
    height: int
    render_s: float


class RenderWorker:
    """The render process (``python -m davinci_sim.bridge.render_worker``) and its socket.

    A plain subprocess rather than ``multiprocessing``: it does not re-import the caller's
    main module, so any script can serve images.
    """

    def __init__(self, scene: SceneConfig, encoding: str = "jpeg", quality: int = 85) -> None:
        parent, child = socket.socketpair()
        env = dict(os.environ)
        env.setdefault("MUJOCO_GL", "egl")
        self.process = subprocess.Popen(
            [sys.executable, "-m", "davinci_sim.bridge.render_worker", str(child.fileno())],
            pass_fds=(child.fileno(),),
            env=env,
        )
        child.close()
        self._conn = Connection(parent.detach())
        self._conn.send((scene, encoding, quality))
        self.ready = False
        self.in_flight = 0

    def fileno(self) -> int:
        return self._conn.fileno()

    def request(self, stamp: float, qpos: np.ndarray) -> None:
        self.in_flight += 1
        self._conn.send((stamp, np.asarray(qpos, dtype=float)))

    def receive(self) -> tuple[str, Any]:
        return self._conn.recv()

    def close(self) -> None:
        try:
            self._conn.send(None)
        except OSError:
            pass
        try:
            self.process.wait(3)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(1)
        self._conn.close()


# =========================================================================== the node
class EndoscopeNode:
    """Publishes the stereo endoscope of ``handle``'s simulation.

    Args:
        handle: the running simulation (its snapshots should carry ``extras["qpos"]``, see
            :class:`QposProbe`; otherwise ``qpos`` is asked from the loop).
        scene: the simulation's scene (name or config): the worker builds the same model.
        rate: images per second wanted (the worker's speed caps it), default 30.
        encoding: ``"jpeg"`` (``image_raw/compressed``), ``"raw"`` (``image_raw``) or
            ``"both"``.
        rig: namespace of the stereo pair (``/<rig>/left/…``).
        handle_frames: take the frames the handle renders (``stereo_frame()``) instead of
            rendering in a worker process; None: if the handle has ``stereo_frame``.
    """

    def __init__(
        self,
        handle: SimHandle,
        scene: str | SceneConfig = "full",
        *,
        rate: float = 30.0,
        encoding: Literal["jpeg", "raw", "both"] = "jpeg",
        rig: str = "jhu_daVinci",
        quality: int = 85,
        handle_frames: bool | None = None,
    ) -> None:
        from davinci_sim.model import resolve_scene

        if encoding not in ("jpeg", "raw", "both"):
            raise ValueError(f"encoding must be 'jpeg', 'raw' or 'both', got {encoding!r}")
        if not 0 < rate <= 120:
            raise ValueError(f"rate must be in ]0, 120] Hz, got {rate!r}")
        if not 1 <= quality <= 100:
            raise ValueError(f"quality must be in [1, 100], got {quality!r}")
        self.handle = handle
        self.scene = resolve_scene(scene)
        self.rate = rate
        self.encoding = encoding
        self.rig = rig.strip("/")
        self.quality = quality
        self.worker: list[RenderWorker] = []
        self.frames = 0
        self.render_times: list[float] = []
        self._task: PeriodicTask | None = None
        self._pending_qpos = False
        self._started = 0.0
        self._retry_at = 0.0
        self._last_request = 0.0
        has_frames = callable(getattr(handle, "stereo_frame", None))
        self._external = has_frames if handle_frames is None else handle_frames and has_frames
        self._last_frame_number: int | None = None
        self._encoding_external = False

    def attach(self, bridge: Bridge) -> None:
        self.bridge = bridge
        self.loop = asyncio.get_running_loop()
        self.topics: dict[str, dict] = {}
        for side, _ in CAMERAS:
            ns = f"/{self.rig}/{side}"
            entry = {"info": bridge.advertise(f"{ns}/camera_info", "sensor_msgs/CameraInfo",
                                              node=NODE)}  # fmt: skip
            if self.encoding in ("jpeg", "both"):
                entry["jpeg"] = bridge.advertise(
                    f"{ns}/image_raw/compressed", "sensor_msgs/CompressedImage", node=NODE
                )
            if self.encoding in ("raw", "both"):
                entry["raw"] = bridge.advertise(f"{ns}/image_raw", "sensor_msgs/Image", node=NODE)
            self.topics[side] = entry
        self._task = PeriodicTask(1.0 / self.rate, self._tick)
        self._task.start()

    async def detach(self) -> None:
        if self._task is not None:
            await self._task.stop()
        self._stop_worker()
        self.bridge.remove_node(NODE)

    # ------------------------------------------------------------------ worker
    def _wanted(self) -> bool:
        return any(t.subscriptions for e in self.topics.values() for t in e.values())

    def _image_wanted(self) -> bool:
        return any(
            t.subscriptions for e in self.topics.values() for k, t in e.items() if k != "info"
        )

    def _worker(self) -> RenderWorker:
        if not self.worker:
            w = RenderWorker(self.scene, self.encoding, self.quality)
            self.loop.add_reader(w.fileno(), self._on_readable, w)
            self.worker.append(w)
            self._started = time.perf_counter()
        return self.worker[0]

    def _stop_worker(self) -> None:
        for w in self.worker:
            try:
                self.loop.remove_reader(w.fileno())
            except Exception:
                pass
            w.close()
        self.worker.clear()

    def _tick(self) -> None:
        if not self._wanted():
            return
        if not self._image_wanted():
            self._publish_info(self.bridge.now())
            return
        if self._external:
            self._tick_external()
            return
        if time.monotonic() < self._retry_at:
            return
        try:
            w = self._worker()
        except Exception:
            _log.exception("endoscope: cannot start the render process; retrying in 10 s")
            self._retry_at = time.monotonic() + 10.0
            return
        # Two requests in flight: the worker starts the next pair as soon as it has sent one.
        if not w.ready or w.in_flight >= PIPELINE_DEPTH or self._pending_qpos:
            return
        if time.monotonic() < self._last_request + 1.0 / self.rate - 0.002:
            return
        self._request(w)

    def _tick_external(self) -> None:
        """Frames rendered by the handle's own renderer: encode and publish new ones."""
        if self._encoding_external:
            return
        try:
            frame = self.handle.stereo_frame()
        except Exception as e:  # e.g. a runner started without a renderer: use ours
            _log.warning("endoscope: the handle does not render (%s); rendering here", e)
            self._external = False
            return
        number = getattr(frame, "frame", None)
        if frame is None or number == self._last_frame_number:
            return
        self._last_frame_number = number
        stamp = time.time() if self.bridge.config.stamp_clock == "wall" else frame.time
        self._encoding_external = True
        future = self.loop.run_in_executor(
            None, _encode_pair, frame.left, frame.right, self.encoding, self.quality
        )

        def done(f) -> None:
            self._encoding_external = False
            if f.exception() is not None:
                _log.error("endoscope: encoding failed: %s", f.exception())
                return
            jpeg, raw, seconds = f.result()
            h, w = frame.left.shape[:2]
            self._publish_frame(Frame(stamp, jpeg, raw, w, h, frame.render_time + seconds))

        future.add_done_callback(done)

    def _request(self, w: RenderWorker) -> None:
        self._last_request = time.monotonic()
        snap = self.handle.snapshot()
        qpos = snap.extras.get("qpos") if snap.extras else None
        stamp = time.time() if self.bridge.config.stamp_clock == "wall" else snap.time
        if qpos is not None:
            w.request(stamp, qpos)
            return
        # No probe: ask the loop for qpos and copy it at once, between two ticks.
        self._pending_qpos = True
        future = self.handle.call("sim", "measured_qpos")

        def got(f) -> None:
            self._pending_qpos = False
            if f.exception() is None and self.worker:
                self.worker[0].request(stamp, np.array(f.result(), dtype=float))

        future.add_done_callback(lambda f: self.loop.call_soon_threadsafe(got, f))

    def _on_readable(self, w: RenderWorker) -> None:
        try:
            kind, payload = w.receive()
        except (EOFError, OSError):
            _log.error("endoscope: the render process exited; restarting in 10 s")
            self.loop.remove_reader(w.fileno())
            self.worker.remove(w)
            w.close()
            self._retry_at = time.monotonic() + 10.0
            return
        if kind == "ready":
            w.ready = True
            _log.info("endoscope: render process ready in %.2f s",
                      time.perf_counter() - self._started)  # fmt: skip
        else:
            w.in_flight = max(0, w.in_flight - 1)
            if kind == "error":
                _log.error("endoscope: %s", payload)
            elif kind == "frame":
                self._publish_frame(Frame(*payload))
        if self._image_wanted():
            self._tick()  # the next request now if it is due

    # ------------------------------------------------------------------ publishing
    def _publish_info(self, stamp: float) -> None:
        b, e = self.bridge, self.scene.endoscope
        for side, entry in self.topics.items():
            topic = entry["info"]
            if topic.subscriptions:
                b.publish(topic, camera_info(b.dialect, e.width, e.height, e.fovy_deg,
                                             e.baseline_m, side, stamp))  # fmt: skip

    def _publish_frame(self, frame: Frame) -> None:
        b, d = self.bridge, self.bridge.dialect
        self.frames += 1
        self.render_times.append(frame.render_s)
        del self.render_times[:-200]
        self._publish_info(frame.stamp)
        for i, (side, entry) in enumerate(self.topics.items()):
            header = d.header(frame.stamp, f"ECM_{side}")
            topic = entry.get("jpeg")
            if topic is not None and topic.subscriptions and frame.jpeg:
                b.publish(topic, {"header": header, "format": "jpeg", "data": frame.jpeg[i]})
            topic = entry.get("raw")
            if topic is not None and topic.subscriptions and frame.raw:
                b.publish(topic, {"header": header, "height": frame.height, "width": frame.width,
                                  "encoding": "rgb8", "is_bigendian": 0, "step": 3 * frame.width,
                                  "data": frame.raw[i]})  # fmt: skip
