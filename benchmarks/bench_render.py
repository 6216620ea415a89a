"""Stereo endoscope rendering rate: two 640x480 images per frame, on the CPU."""

from __future__ import annotations

import time

from common import write
from davinci_sim.sim.simulation import Simulation


def main(seconds: float = 5.0) -> None:
    sim = Simulation("full")
    sim.render_stereo()  # create the GL contexts outside the timed part
    frames = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        sim.tick()
        sim.render_stereo()
        frames += 1
    elapsed = time.perf_counter() - t0
    shadows = {size: _pairs_with_shadows(size, seconds) for size in (4096, 1024)}
    write(
        "render",
        {
            "stereo_pairs_per_s": frames / elapsed,
            "width_px": 640,
            "height_px": 480,
            "frames": frames,
            # The depth cue the web console could not afford on this CPU (llvmpipe): the
            # room light's shadow map, without multisampling, by its size in texels.
            "stereo_pairs_per_s_with_shadows": {str(k): v for k, v in shadows.items()},
        },
    )
    sim.close()


def _pairs_with_shadows(shadowsize: int, seconds: float) -> float:
    import mujoco

    sim = Simulation("full", keyframe="surgical")
    sim.model.vis.quality.shadowsize = shadowsize
    sim.model.vis.quality.offsamples = 0
    renderer = mujoco.Renderer(sim.model, 480, 640)

    def pair() -> None:
        for camera in ("ECM/left", "ECM/right"):
            renderer.update_scene(sim.data, camera=camera)
            renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = True
            renderer.render()

    pair()
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        sim.tick()
        pair()
        n += 1
    rate = n / (time.perf_counter() - t0)
    renderer.close()
    sim.close()
    return rate


if __name__ == "__main__":
    main()
