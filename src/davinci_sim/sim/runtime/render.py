"""Stereo endoscope rendering in its own process, from the loop's shared joint positions.

Rendering a 640x480 stereo pair costs ~22 ms of CPU (llvmpipe); in the loop process it
would stall the 1 kHz tick, and in any thread of it the GIL would. The render process builds
the same model, reads the latest ``qpos`` the loop publishes every tick
(:class:`~davinci_sim.sim.runtime.shm.LatestSlot`), runs MuJoCo's kinematics and renders
both endoscope cameras at the requested rate; the frames go back through shared memory.
Nothing of this touches the loop beyond a 1 µs copy of ``qpos`` per tick.
"""

from __future__ import annotations

import struct
import time
from dataclasses import dataclass

import numpy as np

from davinci_sim.sim.runtime.shm import LatestSlot, SharedBuffer

#: Header of a qpos message: tick (int64), time (float64), nq (int64).
QPOS_HEADER = struct.Struct("<qdq")
#: Header of a frame message: tick, time, frame number, width, height, render time (s).
FRAME_HEADER = struct.Struct("<qdqqqd")
#: Render statistics block (float64): frames, sum of render times, max, first/last wall.
STATS_FIELDS = 8
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


def render_main(
    scene, qpos_path: str, frames_path: str, rate_hz: float, stop, cpu, threads
) -> None:
    """Entry point of the render process (``multiprocessing``, spawn).

    ``cpu``: pin the process to this CPU; ``threads``: rasteriser threads of Mesa's llvmpipe
    (``LP_NUM_THREADS``; one per core by default).
    """
    import os

    if cpu is not None and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {cpu})
    if threads is not None:
        os.environ["LP_NUM_THREADS"] = str(int(threads))
    import mujoco

    from davinci_sim.model import build_model
    from davinci_sim.sim.sensors import CameraRenderer

    model = build_model(scene)
    data = mujoco.MjData(model)
    renderer = CameraRenderer(model)
    width, height = scene.endoscope.width, scene.endoscope.height
    qpos_buf = SharedBuffer(path=qpos_path)
    qslot = LatestSlot(qpos_buf)
    frames_buf = SharedBuffer(path=frames_path)
    stats = np.ndarray((STATS_FIELDS,), dtype=np.float64, buffer=frames_buf.mm)
    fslot = LatestSlot(frames_buf, offset=STATS_BYTES)
    period = 1.0 / rate_hz
    frame = 0
    next_time = time.perf_counter()
    try:
        while not stop.is_set():
            now = time.perf_counter()
            if now < next_time:
                time.sleep(min(next_time - now, 0.05))
                continue
            next_time = max(next_time + period, now - period)
            msg = qslot.read()
            if msg is None:
                continue
            tick, t, nq = QPOS_HEADER.unpack_from(msg)
            data.qpos[:] = np.frombuffer(msg, dtype=np.float64, count=nq, offset=QPOS_HEADER.size)
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
