"""Stereo endoscope images over rosbridge, rendered in another process."""

import base64
import io
import math
import os
import signal

import numpy as np
import pytest
import roslibpy
from bridge_helpers import serving, wait_for
from PIL import Image

from davinci_sim.bridge.dvrk_node import DvrkNode
from davinci_sim.bridge.endoscope import EndoscopeNode, QposProbe, camera_info
from davinci_sim.bridge.rosbridge.dialect import ROS1, ROS2
from davinci_sim.sim.handle import ThreadedSimulation
from davinci_sim.sim.simulation import Simulation


@pytest.fixture
def probed_handle():
    sim = Simulation("psm1", keyframe="surgical")
    sim.add_component(QposProbe(sim))
    h = ThreadedSimulation(sim, real_time=True, snapshot_period=0.01).start()
    yield h
    h.stop()


def test_images_arrive_decode_and_do_not_stall_the_loop(probed_handle, make_server, make_ros):
    """Frames arrive, decode, have the endoscope's size and show a scene; the loop keeps
    ticking while the renderer is frozen (rendering is not in the loop's path). Image rates
    and render times are measured in benchmarks/bench_bridge.py, not here."""
    h = probed_handle
    endo = EndoscopeNode(h, "psm1", encoding="both", rate=30)
    server = make_server(nodes=[DvrkNode(h), endo])
    ros = make_ros(server)
    left, right, raw, info = [], [], [], []
    ns = "/jhu_daVinci"
    roslibpy.Topic(ros, f"{ns}/left/image_raw/compressed", "sensor_msgs/CompressedImage"
                   ).subscribe(left.append)  # fmt: skip
    roslibpy.Topic(ros, f"{ns}/right/image_raw/compressed", "sensor_msgs/CompressedImage"
                   ).subscribe(right.append)  # fmt: skip
    roslibpy.Topic(ros, f"{ns}/left/image_raw", "sensor_msgs/Image").subscribe(raw.append)
    roslibpy.Topic(ros, f"{ns}/right/camera_info", "sensor_msgs/CameraInfo").subscribe(info.append)
    assert wait_for(lambda: len(left) >= 3 and raw and right, 60), "no frames (render start-up)"
    msg = left[-1]
    assert msg["format"] == "jpeg" and msg["header"]["frame_id"] == "ECM_left"
    img = Image.open(io.BytesIO(base64.b64decode(msg["data"])))
    assert img.format == "JPEG" and img.size == (640, 480)
    pixels = np.asarray(img.convert("RGB"), dtype=float)
    assert pixels.std() > 10  # a scene, not a blank frame
    r = raw[-1]
    assert (r["width"], r["height"], r["encoding"], r["step"]) == (640, 480, "rgb8", 1920)
    assert len(base64.b64decode(r["data"])) == 640 * 480 * 3
    p = info[-1]["p"]
    assert p[3] == pytest.approx(-p[0] * 0.005)  # right camera: -fx * baseline
    # camera_info goes out with each pair, with its stamp (read an earlier, complete frame)
    assert right[-2]["header"]["stamp"] in [i["header"]["stamp"] for i in info]
    stamps = [(m["header"]["stamp"]["sec"], m["header"]["stamp"]["nanosec"]) for m in left]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)  # new frames, in order
    # The renderer runs in another process: freeze it, and the loop still ticks (200 ms of
    # simulated time), then frames resume when it runs again.
    pid = endo.render_pid()
    assert pid is not None and pid != os.getpid()
    os.kill(pid, signal.SIGSTOP)
    try:
        tick0 = h.snapshot().tick
        assert wait_for(lambda: h.snapshot().tick >= tick0 + 200, 30), "the loop stalled"
    finally:
        os.kill(pid, signal.SIGCONT)
    n = len(left)
    assert wait_for(lambda: len(left) >= n + 2, 30), "frames did not resume"
    assert endo.frames >= 5


def test_camera_info_pinhole():
    ci = camera_info(ROS2, 640, 480, 45.0, 0.005, "left", 1.5)
    f = 240 / math.tan(math.radians(22.5))
    assert ci["k"] == pytest.approx([f, 0, 320, 0, f, 240, 0, 0, 1])
    assert ci["p"][3] == 0.0 and ci["header"]["stamp"] == {"sec": 1, "nanosec": 500000000}
    assert set(camera_info(ROS1, 640, 480, 45.0, 0.005, "right", 0.0)) >= {"K", "P", "D", "R"}


def test_the_render_pipeline_starts_with_the_server_and_idles_without_image_subscribers(
    probed_handle, make_server, make_ros
):
    """The render process starts with the server and has a frame before anyone subscribes
    (the first image is not a process start-up away); camera_info alone does not make it
    render at the image rate; an image subscriber's first image shows the pose of its
    subscription or later (never the warm-up frame), from the same process."""
    h = probed_handle
    endo = EndoscopeNode(h, "psm1")
    server = make_server(nodes=[endo], stamp_clock="sim")
    assert wait_for(endo.ready.is_set, 120), "no first frame (render start-up)"
    pid = endo.render_pid()
    assert pid is not None  # started before any subscription
    ros = make_ros(server)
    info, left = [], []
    roslibpy.Topic(ros, "/jhu_daVinci/left/camera_info", "sensor_msgs/CameraInfo").subscribe(
        info.append
    )
    assert wait_for(lambda: len(info) > 30, 30)
    assert endo.worker[0].statistics().frames <= 3  # the warm-up only, not 30 Hz
    t_subscribed = h.snapshot().time
    roslibpy.Topic(ros, "/jhu_daVinci/left/image_raw/compressed",
                   "sensor_msgs/CompressedImage").subscribe(left.append)  # fmt: skip
    assert wait_for(lambda: left, 60), "no image"
    stamp = left[0]["header"]["stamp"]
    assert stamp["sec"] + 1e-9 * stamp["nanosec"] >= t_subscribed - 1e-6
    assert endo.render_pid() == pid
    with pytest.raises(ValueError, match="encoding"):
        EndoscopeNode(probed_handle, "psm1", encoding="png")


class RenderingHandle:
    """A handle whose runner renders by itself (the ``stereo_frame()`` of a process runner)."""

    def __init__(self, inner):
        self.inner = inner
        self.number = 0

    def snapshot(self):
        return self.inner.snapshot()

    def subscribe(self, cb):
        return self.inner.subscribe(cb)

    def call(self, *a, **k):
        return self.inner.call(*a, **k)

    def stereo_frame(self):
        from types import SimpleNamespace

        self.number += 1
        left = np.full((48, 64, 3), 200, np.uint8)
        left[:, :32] = 20
        return SimpleNamespace(left=left, right=left[:, ::-1].copy(), time=1.0,
                               frame=self.number // 2, render_time=0.01)  # fmt: skip


def test_frames_from_a_rendering_runner(handle, make_server, make_ros):
    h = RenderingHandle(handle)
    endo = EndoscopeNode(h, "psm1", encoding="both")
    server = make_server(nodes=[endo])
    ros = make_ros(server)
    left, raw = [], []
    roslibpy.Topic(ros, "/jhu_daVinci/left/image_raw/compressed",
                   "sensor_msgs/CompressedImage").subscribe(left.append)  # fmt: skip
    roslibpy.Topic(ros, "/jhu_daVinci/right/image_raw", "sensor_msgs/Image").subscribe(raw.append)
    assert wait_for(lambda: len(left) >= 3 and raw, 10)
    assert endo.worker == []  # no render process of ours
    img = np.asarray(Image.open(io.BytesIO(base64.b64decode(left[-1]["data"]))))
    assert img.shape == (48, 64, 3) and img[:, :20].mean() < 60 and img[:, 44:].mean() > 150
    r = raw[-1]
    right = np.frombuffer(base64.b64decode(r["data"]), np.uint8).reshape(48, 64, 3)
    assert right[:, :32].mean() == 200 and right[:, 32:].mean() == 20  # mirrored, exact


@pytest.mark.parametrize("runner", ["thread", "process"])
def test_serve_images_show_the_task_path(make_ros, runner):
    """issue 11: ``serve --task`` renders the scene the simulation has, path included, with
    either runner (the renderer builds its model from the system's description)."""
    from davinci_sim.bridge.app import ServeOptions
    from davinci_sim.bridge.rosbridge.config import BridgeConfig

    options = ServeOptions(scene="psm1_ecm_mtmr", task="seed_path", runner=runner,
                           images="raw", bridge=BridgeConfig(port=0))  # fmt: skip
    with serving(options) as server:
        ros = make_ros(server)
        raw = []
        roslibpy.Topic(ros, "/jhu_daVinci/left/image_raw", "sensor_msgs/Image").subscribe(
            raw.append
        )
        assert wait_for(lambda: raw, 60), "no image"
        rgb = np.frombuffer(base64.b64decode(raw[-1]["data"]), np.uint8).reshape(480, 640, 3)
        rgb = rgb.astype(int)
        magenta = (rgb[..., 0] > 200) & (rgb[..., 1] < 120) & (rgb[..., 2] > 180)
        assert magenta.sum() > 20  # the path, in the task's colour
