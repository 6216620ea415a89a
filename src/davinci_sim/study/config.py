"""The configuration of a study and its plan of trials.

Condition order: each subject does every condition in one block of ``n_repetitions``
repetitions, the blocks in a counterbalanced order. ``order="latin"`` (default) gives
subject s row s mod C of a Williams design (C conditions): a Latin square where, for an even
C, each condition follows each other equally often (first-order carry-over balanced); for an
odd C it is a cyclic Latin square. ``order="fixed"`` runs the conditions as listed (the
seed does not say in which order its subjects did them).

Practice carries across conditions: the practice count j of the trainee's power law of
practice (:class:`~davinci_sim.operators.SubjectParams`) counts all the subject's trials so
far, j = (block − 1)·n_repetitions + repetition, so a later block is done by a more practised
trainee; the counterbalancing spreads this over the conditions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from davinci_sim.study.trial import TrialSpec

#: The seed's Table I: (B in N·s/m, G_max in N).
TABLE_I: tuple[tuple[float, float], ...] = ((0.0, 0.0), (20.0, 2.0), (40.0, 5.0), (60.0, 8.0))
ORDERS = ("latin", "fixed")
BACKENDS = ("local", "ray")
ENGINES = ("batch", "live")


class StudyError(ValueError):
    """A study configuration that cannot be run; the message says what to fix."""


@dataclass(frozen=True)
class StudyConfig:
    """A simulated user study (see the module docstring)."""

    conditions: tuple[tuple[float, float], ...] = TABLE_I
    """(B, G_max) of each condition, N·s/m and N."""
    n_subjects: int = 10
    n_repetitions: int = 10
    task: str = "seed_path"
    """Task name or task file (:func:`davinci_sim.tasks.load_task`)."""
    seed: int = 0
    order: str = "latin"
    """Condition order policy: ``latin`` or ``fixed``."""
    workers: int = 2
    """Worker processes (local backend) or concurrent tasks (ray)."""
    backend: str = "local"
    """``local`` (a process pool) or ``ray``."""
    timeout: float = 60.0
    """Simulated time a trial may take before it is reported as unfinished, s."""
    engine: str = "batch"
    """``batch`` (trials stepped together, :mod:`davinci_sim.study.batch`) or ``live`` (one
    live simulation per trial: the slow reference the batch is checked against)."""

    def __post_init__(self) -> None:
        conditions = tuple((float(b), float(g)) for b, g in self.conditions)
        object.__setattr__(self, "conditions", conditions)
        if not conditions:
            raise StudyError("a study needs at least one condition")
        if not all(math.isfinite(b) and math.isfinite(g) for b, g in conditions):
            raise StudyError(f"B and G_max must be finite numbers, got {conditions!r}")
        if any(b < 0 or g < 0 for b, g in conditions):
            raise StudyError(f"B and G_max must be >= 0, got {conditions!r}")
        if self.n_subjects < 1 or self.n_repetitions < 1:
            raise StudyError("n_subjects and n_repetitions must be >= 1")
        if self.order not in ORDERS:
            raise StudyError(f"unknown order {self.order!r}; orders: {ORDERS}")
        if self.backend not in BACKENDS:
            raise StudyError(f"unknown backend {self.backend!r}; backends: {BACKENDS}")
        if self.engine not in ENGINES:
            raise StudyError(f"unknown engine {self.engine!r}; engines: {ENGINES}")
        if self.workers < 1:
            raise StudyError(f"workers must be >= 1, got {self.workers!r}")
        if not self.timeout > 0:
            raise StudyError(f"timeout must be > 0, got {self.timeout!r}")

    @property
    def n_trials(self) -> int:
        return self.n_subjects * len(self.conditions) * self.n_repetitions


def parse_conditions(text: str) -> tuple[tuple[float, float], ...]:
    """``"0:0,20:2,40:5,60:8"`` → ((0, 0), (20, 2), (40, 5), (60, 8))."""
    out = []
    for item in text.split(","):
        try:
            b, g = item.split(":")
            out.append((float(b), float(g)))
        except ValueError as e:
            raise StudyError(
                f"conditions are 'B:G_max' pairs separated by commas, got {text!r}"
            ) from e
    return tuple(out)


def williams_row(row: int, n: int) -> list[int]:
    """Row ``row`` (mod n) of a Williams design of n treatments (cyclic if n is odd)."""
    if n % 2:
        return [(row + k) % n for k in range(n)]
    first, lo, hi = [0], 1, n - 1
    while len(first) < n:
        first.append(lo)
        lo += 1
        if len(first) < n:
            first.append(hi)
            hi -= 1
    return [(c + row) % n for c in first]


def condition_order(config: StudyConfig, subject: int) -> list[int]:
    """Indices of the conditions in the order subject ``subject`` does them."""
    n = len(config.conditions)
    return williams_row(subject, n) if config.order == "latin" else list(range(n))


def plan_trials(config: StudyConfig) -> list[TrialSpec]:
    """Every trial of the study, in the order each subject does them."""
    specs = []
    for s in range(config.n_subjects):
        for block, c in enumerate(condition_order(config, s), start=1):
            B, G = config.conditions[c]
            for r in range(1, config.n_repetitions + 1):
                specs.append(
                    TrialSpec(
                        task=config.task,
                        subject=s,
                        condition=c,
                        B=B,
                        G_max=G,
                        repetition=r,
                        order=block,
                        practice=(block - 1) * config.n_repetitions + r,
                        seed=config.seed,
                        timeout=config.timeout,
                    )
                )
    return specs
