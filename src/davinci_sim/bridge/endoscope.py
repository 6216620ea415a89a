"""Stereo endoscope images over the bridge, rendered in a separate process.

Topics (the layout of the dVRK's stereo pipeline, ``/<rig>/{left,right}/…`` with
image_transport names): ``image_raw/compressed`` (``sensor_msgs/CompressedImage``, JPEG, the
default), ``image_raw`` (``sensor_msgs/Image`` rgb8, by option) and ``camera_info``
(``sensor_msgs/CameraInfo``: pinhole from the endoscope's field of view, the right camera's
projection carries the stereo baseline).

Rendering a stereo pair takes ~22 ms of CPU; done in the simulation's thread it would stall
the 1 kHz loop, and in this process it would hold the GIL. The frames come from the one
stereo render pipeline (:class:`~davinci_sim.sim.runtime.render.StereoFrames`, a render
process reading joint positions from shared memory): the handle's own (a runner created with
``render_hz``), or one of this node's, started with the server and fed the snapshots'
``qpos`` (see :class:`QposProbe`) at the image rate while images are subscribed. New frames
are JPEG-encoded in a worker thread (Pillow releases the interpreter lock); the bridge only
forwards bytes.

Time to the first image: starting a render process (interpreter, MuJoCo, the model, the GL
context) takes seconds, so the pipeline starts with the server and renders one frame at once
(:attr:`EndoscopeNode.ready` is set when it is there; ``serve`` waits for it before saying
it is ready). It then idles until images are subscribed: a subscriber's first image is the
next render of the current pose, not a process start-up, and never the warm-up frame (frames
older than the subscription are not sent).
"""

from __future__ import annotations

import asyncio
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from davinci_sim.bridge.rosbridge.publisher import PeriodicTask
from davinci_sim.model.cameras import focal_length_px
from davinci_sim.sim.runtime.render import QposProbe, StereoFrames  # noqa: F401 (re-export)

if TYPE_CHECKING:
    from davinci_sim.bridge.rosbridge.core import Bridge
    from davinci_sim.model.config import SceneConfig
    from davinci_sim.sim.handle import SimHandle

_log = logging.getLogger("davinci_sim.bridge")

NODE = "/davinci_sim/endoscope"
CAMERAS = (("left", "ECM/left"), ("right", "ECM/right"))


# =========================================================================== camera info
def camera_info(
    d: Any, width: int, height: int, fovy_deg: float, baseline: float, side: str, stamp: float
) -> dict:
    """``sensor_msgs/CameraInfo`` of an ideal pinhole (no distortion, square pixels).

    ``fy = (h / 2) / tan(fovy / 2)``; the right camera's ``P[3] = -fx · baseline`` (the ROS
    stereo convention), the left one's 0.
    """
    f = focal_length_px(height, fovy_deg)
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


# =========================================================================== encoding
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


# =========================================================================== the node
class EndoscopeNode:
    """Publishes the stereo endoscope of ``handle``'s simulation.

    Args:
        handle: the running simulation (its snapshots should carry ``extras["qpos"]``, see
            :class:`QposProbe`; otherwise ``qpos`` is asked from the loop).
        scene: the simulation's scene (name or config): the image size, and the model the
            node's renderer draws unless ``model`` is given.
        rate: images per second wanted (the renderer's speed caps it), default 30.
        encoding: ``"jpeg"`` (``image_raw/compressed``), ``"raw"`` (``image_raw``) or
            ``"both"``.
        rig: namespace of the stereo pair (``/<rig>/left/…``).
        handle_frames: take the frames the handle renders (``stereo_frame()``) instead of
            starting a renderer of this node's; None: if the handle has ``stereo_frame``.
        model: picklable callable returning the model to render (the system's, with the
            task's drawing: :attr:`davinci_sim.system.System.model_source`).
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
        model: Callable[[], Any] | None = None,
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
        self.model = model
        self.rate = rate
        self.encoding = encoding
        self.rig = rig.strip("/")
        self.quality = quality
        self.source = StereoFrames(handle, self.scene, rate, model=model, use_handle=handle_frames)
        """Where the frames come from (the one stereo render pipeline)."""
        self.frames = 0
        self.render_times: list[float] = []
        self._task: PeriodicTask | None = None
        self._last_frame_number: int | None = None
        self._encoding = False
        self._since_tick: int | None = None
        self.ready = threading.Event()
        """Set once the render pipeline has produced its first frame (started with the
        server: :meth:`attach`)."""

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
        self._warm_up()  # the render pipeline starts with the server, not at a subscription
        self._task = PeriodicTask(1.0 / self.rate, self._tick)
        self._task.start()

    async def detach(self) -> None:
        if self._task is not None:
            await self._task.stop()
        self._stop_worker()
        self.bridge.remove_node(NODE)

    @property
    def worker(self) -> list:
        """This node's render process (started with the server; empty if the handle
        renders)."""
        return self.source.renderers

    def render_pid(self) -> int | None:
        """Process id of this node's render process (None: not started, or the handle
        renders)."""
        return self.source.pid

    # ------------------------------------------------------------------ frames
    def _wanted(self) -> bool:
        return any(t.subscriptions for e in self.topics.values() for t in e.values())

    def _image_wanted(self) -> bool:
        return any(
            t.subscriptions for e in self.topics.values() for k, t in e.items() if k != "info"
        )

    def _stop_worker(self) -> None:
        self.source.stop()

    def _warm_up(self) -> None:
        """Until the first frame is there, start the pipeline and give it the current pose
        (the render process starts on the first :meth:`StereoFrames.latest`)."""
        if not self.ready.is_set() and self.source.latest() is not None:
            self.ready.set()

    def _tick(self) -> None:
        if not self._image_wanted():
            self._since_tick = None
            self._warm_up()
            if self._wanted():
                self._publish_info(self.bridge.now())
            return
        if self._since_tick is None:  # images wanted from now: no frame older than this
            self._since_tick = self.handle.snapshot().tick
        frame = self.source.latest()
        if frame is None:
            return
        self.ready.set()
        tick = getattr(frame, "tick", None)
        if tick is not None and tick < self._since_tick:
            return  # the warm-up frame, or one rendered before the subscription
        self._encode_and_publish(frame)

    def _encode_and_publish(self, frame) -> None:
        """Encode a new frame in a worker thread, then publish it (one encoding at a time:
        frames that come meanwhile are skipped)."""
        if self._encoding or frame is None or frame.frame == self._last_frame_number:
            return
        self._last_frame_number = frame.frame
        stamp = time.time() if self.bridge.config.stamp_clock == "wall" else frame.time
        self._encoding = True
        future = self.loop.run_in_executor(
            None, _encode_pair, frame.left, frame.right, self.encoding, self.quality
        )

        def done(f) -> None:
            self._encoding = False
            if f.exception() is not None:
                _log.error("endoscope: encoding failed: %s", f.exception())
                return
            jpeg, raw, seconds = f.result()
            h, w = frame.left.shape[:2]
            self._publish_frame(Frame(stamp, jpeg, raw, w, h, frame.render_time + seconds))

        future.add_done_callback(done)

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
