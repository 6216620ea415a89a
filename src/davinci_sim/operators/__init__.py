"""Synthetic trainees: models of people holding an MTM, for studies without people.

* :class:`SyntheticTrainee` — a batch of trainees (one per trial): visuomotor delay,
  minimum-jerk intended motion along the path, crossover-model visual correction,
  signal-dependent motor noise, physiological tremor, limb impedance the MTM's force acts
  through, practice learning (trainee.py).
* :func:`sample_subjects`, :class:`SubjectParams` — per-subject parameters from documented
  distributions (params.py).
* :func:`run_ideal` — trainees on an ideal teleoperation, without the simulator (offline.py).
"""

from davinci_sim.operators.offline import IdealRun, run_ideal
from davinci_sim.operators.params import SubjectParams, sample_subject, sample_subjects
from davinci_sim.operators.trainee import HandState, SyntheticTrainee, TraineePhase

__all__ = [
    "HandState",
    "IdealRun",
    "SubjectParams",
    "SyntheticTrainee",
    "TraineePhase",
    "run_ideal",
    "sample_subject",
    "sample_subjects",
]
