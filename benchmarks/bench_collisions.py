"""The cost of instrument-on-instrument collisions (:mod:`davinci_sim.model.contact`): the
physics step (``mj_step``) of the full scene and of the peg-transfer scene with the
instruments of different arms colliding (the model as built) against the same model with
the bits that kept them apart before (each tool geom's conaffinity without the other arms'
bits), measured interleaved, block by block, in one process (the load of the machine hits
both alike). Also: how many geom pairs the filter now lets through to MuJoCo's bounding
checks.

``python benchmarks/bench_collisions.py`` writes ``results/collisions.json``.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import mujoco  # noqa: E402

import davinci_sim  # noqa: E402, F401  (sets MUJOCO_GL)
from common import write  # noqa: E402
from davinci_sim.model import SceneConfig, build_model, build_spec  # noqa: E402
from davinci_sim.model.contact import ALL_INSTRUMENTS, TOOL_BIT  # noqa: E402
from davinci_sim.tasks import load_task  # noqa: E402


def _pairs(m) -> int:
    """Geom pairs whose contype/conaffinity let them collide (the filter's pass count)."""
    n = 0
    for a in range(m.ngeom):
        for b in range(a + 1, m.ngeom):
            if (m.geom_contype[a] & m.geom_conaffinity[b]) or (
                m.geom_contype[b] & m.geom_conaffinity[a]
            ):
                n += 1
    return n


def _ab(m, blocks: int, steps: int) -> dict:
    """Median µs per mj_step, interleaved blocks: as built (A) and tools apart (B)."""
    d = mujoco.MjData(m)
    tools = (m.geom_contype & TOOL_BIT) > 0
    new = m.geom_conaffinity.copy()
    old = new.copy()
    old[tools] &= ~ALL_INSTRUMENTS
    key = m.key("surgical").id
    out = {"together": [], "apart": []}
    for i in range(2 * blocks):
        which = "together" if i % 2 == 0 else "apart"
        m.geom_conaffinity[:] = new if which == "together" else old
        mujoco.mj_resetDataKeyframe(m, d, key)
        for _ in range(50):
            mujoco.mj_step(m, d)
        t0 = time.perf_counter_ns()
        for _ in range(steps):
            mujoco.mj_step(m, d)
        out[which].append((time.perf_counter_ns() - t0) / 1000.0 / steps)
    m.geom_conaffinity[:] = new
    figures = {f"step_{k}_median_us": statistics.median(v) for k, v in out.items()}
    figures["pairs_together"] = _pairs(m)
    m.geom_conaffinity[:] = old
    figures["pairs_apart"] = _pairs(m)
    m.geom_conaffinity[:] = new
    return figures


def main(blocks: int = 20, steps: int = 500) -> None:
    figures = {"load_average_1min": os.getloadavg()[0], "blocks": blocks, "steps": steps}
    for k, v in _ab(build_model("full"), blocks, steps).items():
        figures[f"full_{k}"] = v
    task = load_task("peg_transfer_icra")
    spec = build_spec(SceneConfig(arms=("PSM1", "PSM2", "ECM"), include_console=False))
    task.draw(spec)
    for k, v in _ab(spec.compile(), blocks, steps).items():
        figures[f"peg_{k}"] = v
    write("collisions", figures)


if __name__ == "__main__":
    main()
