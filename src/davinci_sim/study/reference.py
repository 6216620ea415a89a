"""The expert reference data set of a task: the group the default pass marks come from.

:func:`expert_reference` runs ``subjects`` expert-parameter synthetic trainees
(:func:`~davinci_sim.operators.params.sample_experts`) for ``repetitions`` unassisted
repetitions each (no fixture: experts are measured doing the exercise itself) in the
study's batch engine (:func:`~davinci_sim.study.batch.run_batch`), and summarises every
metric of the finished attempts as mean, SD (n − 1) and n
(:func:`~davinci_sim.tasks.scoring.reference_from_rows`). The defaults are Hugo RAS's
reference group: 9 experts x 5 repetitions (training.md §1). ``scripts/expert_reference.py``
writes the result to ``davinci_sim/tasks/data/reference/<task>.json``, which the task's
scoring then uses (:func:`~davinci_sim.tasks.scoring.task_scoring`).

The skill exercises (needle and camera targeting, ring walk, peg transfer), which the
path-following trainees cannot do, get theirs from :func:`exercise_reference`: the same
experts as scripted operators at the simulated console
(:mod:`davinci_sim.study.experts`), each attempt recorded by the task's session; the
metrics those operators do not exercise (:func:`~davinci_sim.study.experts.not_measured`)
are left out (null), so they take no pass mark from the reference.
"""

from __future__ import annotations

import json
from pathlib import Path

from davinci_sim.study.trial import TrialSpec, load_spec_task

#: Hugo RAS's expert reference group (training.md §1).
SUBJECTS, REPETITIONS = 9, 5
#: The reference's population seed (its own: no trainee of a study shares its draws).
REFERENCE_SEED = 9001


def expert_specs(
    task: str, *, subjects: int = SUBJECTS, repetitions: int = REPETITIONS,
    seed: int = REFERENCE_SEED, timeout: float = 120.0,
) -> list[TrialSpec]:  # fmt: skip
    """The trials of the reference: each expert's repetitions 1..``repetitions``,
    unassisted (B = G_max = 0)."""
    if subjects < 2 or repetitions < 1:
        raise ValueError("a reference needs at least 2 experts and 1 repetition (an SD)")
    return [
        TrialSpec(task, subject=s, condition=0, B=0.0, G_max=0.0, repetition=r, order=1,
                  practice=r, seed=seed, timeout=timeout, population="expert")
        for s in range(subjects)
        for r in range(1, repetitions + 1)
    ]  # fmt: skip


def expert_reference(
    task: str, *, subjects: int = SUBJECTS, repetitions: int = REPETITIONS,
    seed: int = REFERENCE_SEED, timeout: float = 120.0,
) -> dict:  # fmt: skip
    """The reference mapping of ``task`` (a shipped task name or a task file), JSON-ready,
    with how it was made."""
    from davinci_sim import __version__
    from davinci_sim.study.batch import run_batch

    specs = expert_specs(task, subjects=subjects, repetitions=repetitions, seed=seed,
                         timeout=timeout)  # fmt: skip
    rows = run_batch(specs)
    loaded = load_spec_task(specs[0])
    from davinci_sim.tasks.scoring import reference_from_rows

    return reference_from_rows(
        loaded,
        rows,
        population="expert",
        subjects=subjects,
        repetitions=repetitions,
        seed=seed,
        condition={"type": "none"},
        engine="batch",
        produced_by=(
            f"scripts/expert_reference.py {Path(task).name} --subjects {subjects} "
            f"--repetitions {repetitions} --seed {seed}"
        ),
        version=__version__,
    )


def write_reference(data: dict, path: str | Path) -> Path:
    """Write a reference mapping as JSON (nan as null)."""
    p = Path(path)
    p.write_text(json.dumps(data, indent=2) + "\n")
    return p


#: The exercises' reference group: fewer attempts than the path task's (a scripted attempt
#: at the console costs a minute or more of computing, the batch engine's milliseconds):
#: 3 experts x 2 repetitions (the shipped needle targeting, ring-walk, camera, needle
#: pick-up, needle-driving, peg-transfer and running-suture references; the running
#: suture's rests on 2 of the 6 attempts: see :mod:`davinci_sim.study.experts`).
EXERCISE_SUBJECTS, EXERCISE_REPETITIONS = 3, 2


def exercise_reference(
    task: str, *, subjects: int = EXERCISE_SUBJECTS, repetitions: int = EXERCISE_REPETITIONS,
    seed: int = REFERENCE_SEED, progress=None,
) -> dict:  # fmt: skip
    """The reference mapping of the exercise ``task`` (a shipped name or a task file),
    JSON-ready, from its scripted expert operators' attempts
    (:func:`~davinci_sim.study.experts.expert_attempts`), with how it was made."""
    from davinci_sim import __version__
    from davinci_sim.study.experts import (
        ANGULAR_SPEED,
        MAX_CORRECTIONS,
        REACH_SPEED_FACTOR,
        expert_attempts,
        not_measured,
    )
    from davinci_sim.tasks import load_task
    from davinci_sim.tasks.scoring import reference_from_rows

    if subjects < 2 or repetitions < 1:
        raise ValueError("a reference needs at least 2 experts and 1 repetition (an SD)")
    loaded = load_task(task)
    skipped = not_measured(loaded.kind, loaded.name)
    rows = expert_attempts(loaded, subjects=subjects, repetitions=repetitions, seed=seed,
                           progress=progress)  # fmt: skip
    data = reference_from_rows(
        loaded,
        rows,
        population="expert",
        subjects=subjects,
        repetitions=repetitions,
        seed=seed,
        condition={"type": "none"},
        engine="scripted",
        operator=(
            f"davinci_sim.study.experts ({loaded.kind}): arms scripted at the simulated "
            f"console (servo_cp streamed, jaws servo_jp, ECM move_cp), teleoperation "
            f"clutched; expert parameters (operators.params.sample_experts) at repetition "
            f"j: speed/f, noise k*f, f = 1 + E*j^-alpha; reach speed {REACH_SPEED_FACTOR:g}x "
            f"the practised speed, reorientation {ANGULAR_SPEED:g} rad/s, open-loop "
            f"endpoint SD k*sqrt(A*v*2tau*10/7) with up to {MAX_CORRECTIONS} corrective "
            f"reaches after the visuomotor delay, tremor scaled by the motion scale"
        ),
        not_measured=skipped,
        produced_by=(
            f"scripts/expert_reference.py --exercise {Path(task).name} --subjects "
            f"{subjects} --repetitions {repetitions} --seed {seed}"
        ),
        version=__version__,
    )
    for name in skipped:
        if name in data["metrics"]:
            data["metrics"][name].update(mean=None, sd=None, n=0)
    return data
