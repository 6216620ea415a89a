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
    write(
        "render",
        {
            "stereo_pairs_per_s": frames / elapsed,
            "width_px": 640,
            "height_px": 480,
            "frames": frames,
        },
    )
    sim.close()


if __name__ == "__main__":
    main()
