"""The suture pad's cost against the tick (issue 24: with the pad and the needle, both pairs
following, the tick ≤ 2× the same scene's without them).

Three set-ups of what ``serve --task <exercise> --home`` ticks, the person holding both
handles still after taking control, both teleoperations following
(:func:`bench_teleop.serve_sim`): ``needle_drive`` (the park, the needle and the suture
pad), ``needle_pickup`` (the park and the needle: the same scene without the pad) and
``seed_path`` (no objects). For each: ``Simulation.tick`` one at a time, the live runners'
passes of ``CHUNK_TICKS`` ticks (``live_tick``), and MuJoCo's own ``mj_step`` at the same
state. Then the physics alone with PSM1's closed jaws pressed 2 mm into the skin (contacts
with the flex every step): ``pressed_tick`` against ``clear_tick``, the same scene with the
jaws 15 mm above it. Last, the live passes of ``needle_drive`` with the person's right hand
holding PSM1's tool down on the skin (``pressing_live_tick``) against MuJoCo's step at that
state. ``python benchmarks/bench_suture.py`` writes ``results/suture.json``.
"""

from __future__ import annotations

import logging
import os

import numpy as np

from bench_teleop import mj_step_each, serve_sim
from common import summary, time_each, write
from davinci_sim.model import SceneConfig
from davinci_sim.model.psm import JAW_LENGTH
from davinci_sim.operators.guide import guide_tool
from davinci_sim.sim.runtime.loop import CHUNK_TICKS
from davinci_sim.sim.simulation import Simulation
from davinci_sim.tasks import load_task

SCENE = SceneConfig(arms=("PSM1", "PSM2", "ECM"), include_console=False)


def serve_figures(task: str, n: int) -> dict:
    sim = serve_sim(task=task)
    try:
        out = summary(time_each(sim.tick, n), f"{task}_tick")
        passes = time_each(lambda: sim.advance(CHUNK_TICKS, unchanged=True), n // CHUNK_TICKS)
        out.update(summary([p / CHUNK_TICKS for p in passes], f"{task}_live_tick"))
        out.update(summary(mj_step_each(sim, n), f"{task}_mj_step"))
        out[f"{task}_nv"] = int(sim.model.nv)
        return out
    finally:
        sim.close()


def pressed_figures(n: int) -> dict:
    """PSM1's closed jaws, pointing down, 15 mm above the skin and then 2 mm into it."""
    task = load_task("needle_drive")
    sim = Simulation(SCENE, keyframe="surgical", edit_spec=task.draw)
    try:
        for name in ("PSM1", "PSM2", "ECM"):
            sim.arms[name].state_command("enable")
            sim.arms[name].state_command("home")
        sim.run_until(lambda: all(a.is_homed() and not a.is_busy() for a in sim.arms.values()),
                      20)  # fmt: skip
        m, d = sim.model, sim.data
        T_camera_world = np.linalg.inv(sim.T_cart_camera())
        site = m.site("PSM1/tip").id
        x = d.site_xmat[site].reshape(3, 3)[:, 0] * [1, 1, 0]
        x /= np.linalg.norm(x)
        G = np.eye(4)
        G[:3, :3] = np.column_stack([x, np.cross([0, 0, -1.0], x), [0, 0, -1.0]])
        on = task.pad.T_world_pad[:3, 3] + [0.0, 0.0015, 0.0]
        psm = sim.arms["PSM1"]
        out = {}
        psm.jaw.move_jp(-0.35)  # closed (the dVRK's −20°)
        sim.run_until(lambda: not psm.jaw.is_busy(), 5)
        for label, height in (("clear", 0.015), ("pressed", task.pad.skin_radius - 0.002)):
            G[:3, 3] = on + [0.0, 0.0, JAW_LENGTH + height]
            psm.move_cp(T_camera_world @ G)
            sim.run_until(lambda: not psm.is_busy(), 10)
            sim.run_for(0.3)
            out.update(summary(time_each(sim.tick, n), f"{label}_tick"))
            out[f"{label}_contacts"] = int(d.ncon)
        return out
    finally:
        sim.close()


def pressing_figures(n: int) -> dict:
    """What ``serve --task needle_drive`` ticks while the person's right hand holds PSM1's
    tool down on the skin (every step has contacts with it): the live runners' passes and
    MuJoCo's own step at that state."""
    sim = serve_sim(task="needle_drive")
    try:
        probe, pad = sim.components["task"].task.probe(sim.model), sim.components["task"].task.pad
        above = [pad.center[0], pad.center[1], pad.top + 0.012]  # world, m
        guide_tool(sim, "MTMR_PSM1", above, lambda: probe.read(sim.data).flex_force > 0.2)
        sim.run_for(0.3)
        passes = time_each(lambda: sim.advance(CHUNK_TICKS, unchanged=True), n // CHUNK_TICKS)
        out = summary([p / CHUNK_TICKS for p in passes], "pressing_live_tick")
        out.update(summary(mj_step_each(sim, n), "pressing_mj_step"))
        out["pressing_contacts"] = int(sim.data.ncon)
        out["pressing_skin_force_N"] = probe.read(sim.data).flex_force
        return out
    finally:
        sim.close()


def main(n: int = 3000) -> None:
    logging.getLogger("davinci_sim").setLevel(logging.ERROR)
    figures: dict = {"load_average_before": os.getloadavg()[0]}
    for task in ("needle_drive", "needle_pickup", "seed_path"):
        figures.update(serve_figures(task, n))
    for base in ("needle_pickup", "seed_path"):
        for kind in ("tick", "live_tick"):
            figures[f"drive_over_{base}_{kind}_ratio"] = (
                figures[f"needle_drive_{kind}_median_us"] / figures[f"{base}_{kind}_median_us"]
            )
    figures.update(pressed_figures(n))
    figures["pressed_over_clear_ratio"] = (
        figures["pressed_tick_median_us"] / figures["clear_tick_median_us"]
    )
    figures.update(pressing_figures(n))
    figures["target_drive_over_without_ratio"] = 2.0
    figures["load_average_after"] = os.getloadavg()[0]
    write("suture", figures)


if __name__ == "__main__":
    main()
