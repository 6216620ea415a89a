"""Synthetic trainees: models of people holding an MTM, for studies without people.

* :class:`SyntheticTrainee` — a batch of trainees (one per trial): visuomotor delay,
  minimum-jerk intended motion along the path, crossover-model visual correction,
  signal-dependent motor noise, physiological tremor, limb impedance the MTM's force acts
  through, practice learning (trainee.py).
* :func:`sample_subjects`, :class:`SubjectParams` — per-subject parameters from documented
  distributions (params.py).
* :func:`run_ideal` — trainees on an ideal teleoperation, without the simulator (offline.py).
* :class:`TraineeHand`, :func:`hand_impedance` — one trainee's hand on a simulated MTM of the
  console: the same teleoperation and force-field path as a person (console.py).
* :func:`~davinci_sim.operators.guide.guide_tool` — a scripted hand that brings a
  teleoperated tool to a point through its MTM (guide.py).
"""

from davinci_sim.operators.console import TraineeHand, hand_impedance
from davinci_sim.operators.offline import IdealRun, run_ideal
from davinci_sim.operators.params import SubjectParams, sample_subject, sample_subjects
from davinci_sim.operators.trainee import HandState, SyntheticTrainee, TraineePhase

__all__ = [
    "HandState",
    "IdealRun",
    "SubjectParams",
    "SyntheticTrainee",
    "TraineeHand",
    "TraineePhase",
    "hand_impedance",
    "run_ideal",
    "sample_subject",
    "sample_subjects",
]
