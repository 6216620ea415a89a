"""The bedside view (:mod:`davinci_sim.web.scene3d`) of the full scene with the seed's task
drawn: its size (scene nodes, the initial scene a browser downloads), the cost of one live
update (kinematics + pose messages + flush) when every moving body moves and when one PSM
moves (and with every body moving through viser's public setters, the fallback), and the
update rate a connected client receives, at the default 30 Hz and as fast as it goes.

A :class:`~davinci_sim.web.viser_probe.ViserProbe` stands for the browser (it receives and
decodes every frame, as a page would, but draws nothing). ``python
benchmarks/bench_scene3d.py`` writes ``results/scene3d.json``.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import davinci_sim  # noqa: E402, F401  (sets MUJOCO_GL)
from common import summary, time_each, write  # noqa: E402
from davinci_sim.sim.handle import Snapshot  # noqa: E402
from davinci_sim.system import SystemDescription, TaskDescription, scene_model  # noqa: E402
from davinci_sim.web.scene3d import BedsideView  # noqa: E402
from davinci_sim.web.viser_probe import ViserProbe  # noqa: E402


class MovingSnapshots:
    """Snapshots whose qpos moves every joint (or one arm's) a little more each call."""

    def __init__(self, model: mujoco.MjModel, joints: list[int]):
        self.q0 = model.key("surgical").qpos.copy()
        self.adr = np.array([model.jnt_qposadr[j] for j in joints], dtype=int)
        self.tick = 0

    def snapshot(self) -> Snapshot:
        self.tick += 1
        q = self.q0.copy()
        q[self.adr] += 0.05 * np.sin(0.01 * self.tick + np.arange(len(self.adr)))
        return Snapshot(self.tick * 0.001, self.tick, {}, {"qpos": q})


def hinge_and_slide_joints(model: mujoco.MjModel, prefix: str = "") -> list[int]:
    kinds = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    return [
        j
        for j in range(model.njnt)
        if int(model.jnt_type[j]) in kinds and model.joint(j).name.startswith(prefix)
    ]


def main(n: int = 300, rate_seconds: float = 3.0) -> None:
    description = SystemDescription("full", task=TaskDescription("seed_path"))
    model = scene_model(description)
    figures: dict = {"load_average_1min": os.getloadavg()[0]}
    t0 = time.perf_counter()
    view = BedsideView(lambda: model).start()
    figures["start_s"] = time.perf_counter() - t0
    try:
        figures["geom_nodes"] = len(view.geom_nodes)
        figures["body_nodes"] = len(view.body_nodes)
        figures["moving_bodies"] = len(view.moving)
        t0 = time.perf_counter()
        with ViserProbe(view.url) as probe:
            probe.wait_for(lambda f: any("ReplayDoneMessage" in x.types for x in f))
            frames = probe.received()
            figures["initial_scene_s"] = frames[-1].t - t0
            figures["initial_scene_bytes"] = sum(f.nbytes for f in frames)
            figures["initial_scene_messages"] = sum(len(f.types) for f in frames)

            data = mujoco.MjData(model)
            figures.update(
                summary(time_each(lambda: mujoco.mj_kinematics(model, data), n), "kinematics")
            )
            # (all_arms_setters: the same through viser's public pose setters, the fallback)
            cases = (("all_arms", "", True), ("one_psm", "PSM1/", True),
                     ("all_arms_setters", "", False))  # fmt: skip
            for case, prefix, fast in cases:
                view.fast_poses = fast
                source = MovingSnapshots(model, hinge_and_slide_joints(model, prefix))
                before = len(probe.received())
                samples = time_each(lambda s=source: view.update(s.snapshot()), n, warmup=20)
                figures.update(summary(samples, f"update_{case}"))
                probe.wait_for(lambda f, k=before + n + 20: len(f) >= k, timeout=10.0)
                sizes = [f.nbytes for f in probe.received()[before:]]
                figures[f"update_{case}_bytes_median"] = float(np.median(sizes))
        # The rate a client receives: at the default poll rate (30 Hz), and with the view's
        # thread polling as fast as it can; every poll sees a new tick, every arm moving.
        for label, rate_hz in (("default", 30.0), ("max", 1000.0)):
            source = MovingSnapshots(model, hinge_and_slide_joints(model))
            live = BedsideView(lambda: model, source, rate_hz=rate_hz).start()
            try:
                with ViserProbe(live.url) as probe:
                    probe.wait_for(lambda f: any("ReplayDoneMessage" in x.types for x in f))
                    start = len(probe.received())
                    time.sleep(rate_seconds)
                    got = [f for f in probe.received()[start:] if "SetPositionMessage" in f.types]
                    if len(got) > 1:
                        rate = (len(got) - 1) / (got[-1].t - got[0].t)
                        figures[f"client_update_rate_{label}_hz"] = rate
            finally:
                live.stop()
    finally:
        view.stop()
    write("scene3d", figures)


if __name__ == "__main__":
    main()
