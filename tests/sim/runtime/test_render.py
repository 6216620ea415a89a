"""The one stereo render pipeline: a render process fed joint positions, frames back."""

import time

import numpy as np

from davinci_sim.sim.handle import ThreadedSimulation
from davinci_sim.sim.runtime.render import StereoFrames, StereoRenderer
from davinci_sim.sim.simulation import Simulation


def wait_for(predicate, timeout=60.0):
    end = time.monotonic() + timeout
    while not (value := predicate()):
        if time.monotonic() > end:
            return value
        time.sleep(0.01)
    return value


def test_a_renderer_draws_each_new_state_it_is_fed():
    sim = Simulation("psm1", keyframe="surgical")
    renderer = StereoRenderer(sim.config, 60.0).start()
    try:
        renderer.feed(5, 0.005, sim.data.qpos)
        first = wait_for(lambda: (f := renderer.frame()) is not None and f.tick == 5 and f)
        assert first and first.left.shape == (480, 640, 3) and first.left.std() > 10
        assert not np.array_equal(first.left, first.right)  # two cameras
        q = sim.data.qpos.copy()
        q[sim.arms["ECM"]._qposadr[0]] += 0.3  # the camera turns: the image changes
        renderer.feed(6, 0.006, q)
        second = wait_for(lambda: (f := renderer.frame()) is not None and f.tick == 6 and f)
        assert second and second.frame == first.frame + 1  # one frame per new state
        assert np.abs(second.left.astype(int) - first.left.astype(int)).mean() > 5
        assert renderer.statistics().frames == 2
    finally:
        renderer.stop()
        sim.close()
    assert not renderer.running


def test_frames_of_a_handle_without_a_probe_or_a_renderer():
    """No qpos in the snapshots and no renderer in the runner: StereoFrames starts one and
    asks the loop for qpos."""
    with ThreadedSimulation(Simulation("psm1", keyframe="surgical"), real_time=False) as h:
        frames = StereoFrames(h, "psm1", 30.0)
        assert not frames.from_handle and frames.pid is None
        got = wait_for(lambda: (f := frames.latest()) is not None and f.tick > 0 and f)
        assert got and got.left.std() > 10 and frames.pid is not None
        frames.stop()
        assert frames.renderers == []


def test_frames_of_a_rendering_runner():
    sim = Simulation("psm1", keyframe="surgical")
    with ThreadedSimulation(sim, real_time=False, render_hz=30.0) as h:
        frames = StereoFrames(h, "psm1", 30.0)
        assert frames.from_handle
        got = wait_for(lambda: (f := frames.latest()) is not None and f.frame >= 2 and f)
        assert got and got.tick <= h.snapshot().tick + 1 and frames.pid is None
        assert h.render_statistics().frames >= 2
