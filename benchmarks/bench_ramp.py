"""The viscous fixture's on-path ramp: how much smoother does it make the force on the hand,
and what does it cost in guidance? (issue 11, item 3: the study runs the law as printed;
should the live console keep a narrowed ramp?)

The seed's law as printed flips the force's direction as the tool crosses the path (see
:mod:`davinci_sim.haptics.viscous`); a ramp of width ``transition`` scales it to zero on the
path. This runs the same synthetic trainees on ``seed_path`` (batch engine, the study's
laws) with B = 40 N·s/m, G_max = 5 N and several ramp widths, and records every tick's
force sent to the MTM (after the safety clamp). Per width:

* ``reversals_per_s``: ticks where the force turns by more than 90° from one tick to the
  next while both exceed 0.05 N (the chatter a hand feels as buzz), per second of trial;
* ``jerk_rms_N_per_tick``: rms of the tick-to-tick change of the force vector, N;
* ``mean_force_N``, ``deviation_mm``: what the guidance does.

Timing-free (counts and forces only). ``python benchmarks/bench_ramp.py`` writes
``results/ramp.json``.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

import davinci_sim  # noqa: E402, F401  (sets MUJOCO_GL)
import davinci_sim.study.batch as batch_module  # noqa: E402
from common import write  # noqa: E402
from davinci_sim.study.batch import TrialBatch  # noqa: E402
from davinci_sim.study.trial import TrialSpec, condition_spec  # noqa: E402

#: Ramp widths compared, m (0: the law as printed).
TRANSITIONS = (0.0, 0.00005, 0.0001, 0.0005)
SUBJECTS = 10
PRACTICE = 10
FORCE_FLOOR = 0.05


def main(subjects: int = SUBJECTS) -> dict:
    specs = [
        TrialSpec("seed_path", subject=s, condition=k, repetition=1, order=1,
                  practice=PRACTICE, seed=0,
                  fixture=condition_spec(40.0, 5.0, transition=t) | {"name": f"t={t}"})
        for k, t in enumerate(TRANSITIONS)
        for s in range(subjects)
    ]  # fmt: skip
    batch_module.COMPACT_MIN_ROWS = 10**9  # keep one row per trial (per-row histories)
    batch = TrialBatch(specs)
    n = len(specs)
    prev = np.zeros((n, 3))
    reversals = np.zeros(n)
    jerk2 = np.zeros(n)
    ticks = np.zeros(n)
    while batch.active.any():
        active = batch.active.copy()
        batch.tick()
        f = batch.wrench_sent[:, :3]
        both = (np.linalg.norm(f, axis=1) > FORCE_FLOOR) & (
            np.linalg.norm(prev, axis=1) > FORCE_FLOOR
        )
        turned = np.einsum("ij,ij->i", f, prev) < 0
        reversals += active & both & turned
        jerk2 += np.where(active, np.sum((f - prev) ** 2, axis=1), 0.0)
        ticks += active
        prev = f.copy()
    rows = batch.run()  # every trial has ended: collects the rows
    batch._setup.sim.close()
    out = {"subjects": subjects, "practice": PRACTICE, "B": 40.0, "G_max": 5.0}
    for k, t in enumerate(TRANSITIONS):
        sel = [i for i, s in enumerate(specs) if s.condition == k]
        seconds = ticks[sel].sum() * batch.dt
        key = f"transition_{t * 1e3:g}mm"
        out[key] = {
            "reversals_per_s": float(reversals[sel].sum() / seconds),
            "jerk_rms_N_per_tick": float(np.sqrt(jerk2[sel].sum() / ticks[sel].sum())),
            "mean_force_N": float(np.mean([rows[i]["mean_force"] for i in sel])),
            "deviation_mm": float(np.mean([rows[i]["deviation_error"] for i in sel]) * 1e3),
            "finished": int(sum(rows[i]["finished"] for i in sel)),
        }
    write("ramp", out)
    return out


if __name__ == "__main__":
    import json

    print(json.dumps(main(), indent=1))
