"""Calibrate the synthetic trainees' unassisted deviation (issue 11, item 3).

Runs the unassisted (B = 0) trials of the seed's study (``seed_path``, 10 subjects, the
study's plan and practice counts) for a few values of the median of the signal-dependent
noise coefficient k (:data:`davinci_sim.operators.params.NOISE_MEDIAN`; every subject's k
scales with it, the draws are otherwise unchanged), and finds by the secant method the
median that gives :data:`TARGET_DEVIATION_M` as the mean of the subjects' mean deviations.
The target and why it is what it is: :data:`davinci_sim.operators.params.CALIBRATION`.

``python benchmarks/calibrate_trainees.py`` writes ``results/calibration.json``.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

import davinci_sim  # noqa: E402, F401  (sets MUJOCO_GL)
from common import write  # noqa: E402
from davinci_sim.operators import params  # noqa: E402
from davinci_sim.study import StudyConfig, plan_trials, subject_means  # noqa: E402
from davinci_sim.study.runner import _local  # noqa: E402


class _Bar:
    n = 0

    def update(self, k):
        pass

    def refresh(self):
        pass


def unassisted_deviation(median: float, config: StudyConfig) -> dict:
    """Mean over subjects of each subject's mean unassisted deviation, m, for a median k."""
    params.NOISE_MEDIAN = median  # forked workers inherit it
    specs = [s for s in plan_trials(config) if s.condition == 0]
    rows = _local(specs, config.workers, "batch", _Bar())
    dev = subject_means(rows, "deviation_error", config.n_subjects, len(config.conditions))
    return {
        "noise_median": median,
        "deviation_mm": float(np.nanmean(dev[:, 0]) * 1e3),
        "sd_mm": float(np.nanstd(dev[:, 0]) * 1e3),
        "finished": int(sum(r["finished"] for r in rows)),
        "trials": len(rows),
    }


def main(target_m: float = None, start: float = 0.10, tolerance: float = 0.01) -> dict:
    target_mm = (params.TARGET_DEVIATION_M if target_m is None else target_m) * 1e3
    config = StudyConfig(workers=2)
    runs = [unassisted_deviation(start, config)]
    print(runs[-1], flush=True)
    x = start * target_mm / runs[-1]["deviation_mm"]  # deviation ~ proportional to k
    for _ in range(6):
        runs.append(unassisted_deviation(x, config))
        print(runs[-1], flush=True)
        if abs(runs[-1]["deviation_mm"] / target_mm - 1) < tolerance:
            break
        (x0, y0), (x1, y1) = ((r["noise_median"], r["deviation_mm"]) for r in runs[-2:])
        x = x1 + (target_mm - y1) * (x1 - x0) / (y1 - y0)
    out = {"target_deviation_mm": target_mm, "runs": runs, "fitted_noise_median": x}
    write("calibration", out)
    return out


if __name__ == "__main__":
    import json

    print(json.dumps(main(), indent=1))
