"""Simulated user studies: the seed's experiment (§II-D, III) with synthetic trainees.

* :class:`StudyConfig`, :func:`plan_trials`, :func:`condition_order` — conditions (default
  Table I), subjects, repetitions, task, seed, counterbalanced order (config.py).
* :func:`run_trial`, :class:`TrialSpec` — one trial through the live simulator, console,
  teleop and haptic loop with a :class:`~davinci_sim.operators.TraineeHand` (trial.py).
* :class:`~davinci_sim.study.batch.TrialBatch`, :func:`~davinci_sim.study.batch.run_batch` —
  the study's engine: many trials stepped together with the same laws (batch.py).
* :func:`run_study` — every trial, in one batch per worker, on a local process pool or Ray
  (runner.py).
* :func:`friedman`, :func:`pairwise_wilcoxon`, :func:`holm`, :func:`subject_means` (stats.py).
* :func:`write_outputs` — ``trials.csv``, Figs 7-9, ``report.md`` (report.py).
* :class:`~davinci_sim.study.store.StudyRows` — each trial's row kept on disk as it ends, to
  resume an interrupted study; :func:`~davinci_sim.study.store.atomic_path` (store.py).
* :func:`~davinci_sim.study.estimate.estimate_study` — a study's wall time, calibrated here
  before it starts (estimate.py).
"""

from davinci_sim.study.config import (
    TABLE_I,
    StudyConfig,
    StudyError,
    condition_order,
    parse_conditions,
    plan_trials,
    williams_row,
)
from davinci_sim.study.report import claims, write_outputs
from davinci_sim.study.runner import StudyResult, run_study
from davinci_sim.study.stats import friedman, holm, pairwise_wilcoxon, subject_means
from davinci_sim.study.trial import METRICS, TrialSpec, run_trial

__all__ = [
    "METRICS",
    "TABLE_I",
    "StudyConfig",
    "StudyError",
    "StudyResult",
    "TrialSpec",
    "claims",
    "condition_order",
    "friedman",
    "holm",
    "pairwise_wilcoxon",
    "parse_conditions",
    "plan_trials",
    "run_study",
    "run_trial",
    "subject_means",
    "williams_row",
    "write_outputs",
]
