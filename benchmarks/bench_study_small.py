"""Small studies (issue 11, item 6): a study's fixed cost, its cost per trial, and how close
the printed estimate comes, end to end through the command line.

Figures (``results/study_small.json``; wall times, s, unless the name says otherwise):

* ``import_s``: ``import davinci_sim.cli, davinci_sim.study`` in a fresh interpreter (the
  interpreter's own start subtracted).
* ``setup_cold_s``, ``setup_warm_s``: the first trial set-up of a process
  (:func:`~davinci_sim.study.trial.setup_trial`: the model, homing, the reach to point 1,
  the teleoperation starting) and its first batch ticks, with an empty numba cache (every
  law compiled) and with the cache on disk; ``restore_s``: a later set-up in the same process
  (the saved state restored); ``forked_worker_cold_s``: the same first set-up and ticks in
  a worker process forked after the cold one (what a study's workers pay: nothing is
  compiled or built again).
* ``calibration_s``, ``tick_ms`` (``a``), ``trial_tick_us`` (``b``): the estimate's
  calibration for the 16-trial study (:func:`~davinci_sim.study.estimate.estimate_study`).
* ``cli_<n>_*``: ``davinci-sim study`` with n trials of the seed task in a fresh process:
  ``process_s`` (the whole command), ``trials_s`` (running the trials, as it prints),
  ``fixed_s`` = process − trials (imports, task check, calibration, outputs),
  ``estimate_s`` (printed before the trials), ``sim_s`` (simulated time of the trials).
  n = 1 (one condition) and 16 (Table I, 2 subjects × 2 repetitions, 2 workers).

The machine is shared: wall times vary with its load (``load_avg_1min`` at the start).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import davinci_sim  # noqa: E402, F401  (sets MUJOCO_GL)
from common import write  # noqa: E402

SRC = str(Path(__file__).resolve().parents[1] / "src")

SETUP = """
import json, time
t0 = time.perf_counter()
from davinci_sim.study import StudyConfig, plan_trials
from davinci_sim.study.batch import TrialBatch
specs = plan_trials(StudyConfig(n_subjects=1, n_repetitions=1, conditions=((40, 5),)))
t1 = time.perf_counter()
batch = TrialBatch(specs)
for _ in range(20):
    batch.tick()
t2 = time.perf_counter()
TrialBatch(specs)
t3 = time.perf_counter()
def worker(out):  # a worker process as the study starts them (fork: inherits the set-up)
    t = time.perf_counter()
    batch = TrialBatch(specs)
    for _ in range(20):
        batch.tick()
    out.put(time.perf_counter() - t)
import multiprocessing as mp
q = mp.get_context().Queue()
p = mp.get_context().Process(target=worker, args=(q,))
p.start()
forked = q.get()
p.join()
print(json.dumps({"import": t1 - t0, "setup": t2 - t1, "restore": t3 - t2, "forked": forked}))
"""


def _env(**extra) -> dict:
    env = {**os.environ, "PYTHONPATH": SRC, **extra}
    env.setdefault("MUJOCO_GL", "egl")
    return env


def _python(code: str, **env) -> str:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=_env(**env), check=True)  # fmt: skip
    return out.stdout


def import_cost() -> float:
    t0 = time.perf_counter()
    _python("pass")
    bare = time.perf_counter() - t0
    t0 = time.perf_counter()
    _python("import davinci_sim.cli, davinci_sim.study")
    return time.perf_counter() - t0 - bare


def setup_costs() -> dict:
    with tempfile.TemporaryDirectory(prefix="davinci-numba-") as cache:
        cold = json.loads(_python(SETUP, NUMBA_CACHE_DIR=cache))
        warm = json.loads(_python(SETUP, NUMBA_CACHE_DIR=cache))
    return {
        "setup_cold_s": cold["setup"],
        "setup_warm_s": warm["setup"],
        "restore_s": warm["restore"],
        "forked_worker_cold_s": cold["forked"],
    }


def calibration() -> dict:
    from davinci_sim.study import StudyConfig
    from davinci_sim.study.estimate import estimate_study

    estimate_study(StudyConfig(n_subjects=1, n_repetitions=1))  # (the set-up, built once)
    e = estimate_study(StudyConfig(n_subjects=2, n_repetitions=2))
    return {
        "calibration_s": e.calibration_s,
        "tick_ms": e.tick_s * 1e3,
        "trial_tick_us": e.trial_tick_s * 1e6,
    }


def cli_study(name: str, *args: str) -> dict:
    with tempfile.TemporaryDirectory(prefix="davinci-study-") as out:
        t0 = time.perf_counter()
        run = subprocess.run(
            [sys.executable, "-m", "davinci_sim.cli", "study", "-o", out, "--no-progress", *args],
            capture_output=True, text=True, env=_env(), check=True,
        )  # fmt: skip
        process = time.perf_counter() - t0
    estimate = re.search(r"about ([\d.]+) s", run.stdout)
    ran = re.search(r"wall time ([\d.]+) s, simulated time ([\d.]+) s", run.stdout)
    return {
        f"{name}_process_s": process,
        f"{name}_trials_s": float(ran[1]),
        f"{name}_fixed_s": process - float(ran[1]),
        f"{name}_estimate_s": float(estimate[1]),
        f"{name}_sim_s": float(ran[2]),
    }


def main() -> dict:
    figures = {"load_avg_1min": os.getloadavg()[0], "import_s": import_cost(), **setup_costs()}
    figures.update(calibration())
    figures.update(cli_study("cli_1", "--subjects", "1", "--repetitions", "1",
                             "--conditions", "40:5"))  # fmt: skip
    figures.update(cli_study("cli_16", "--subjects", "2", "--repetitions", "2", "--workers", "2"))
    write("study_small", figures)
    return figures


if __name__ == "__main__":
    print(main())
