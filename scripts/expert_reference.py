#!/usr/bin/env python
"""Make the expert reference data set of a task (the default pass marks of its scoring).

    PYTHONPATH=src python scripts/expert_reference.py seed_path

runs 9 expert-parameter synthetic trainees x 5 unassisted repetitions of the task in the
study's batch engine (davinci_sim.study.reference) and writes
src/davinci_sim/tasks/data/reference/<task>.json (or --out): per metric the mean, SD and n,
and how the file was made.

    PYTHONPATH=src python scripts/expert_reference.py --exercise needle_targeting

does a skill exercise (needle_targeting, camera_targeting, ring_walk, peg_transfer,
peg_transfer_icra) with the scripted expert operators at the simulated console
(davinci_sim.study.experts; default 3 experts x 2 repetitions). Re-run it when the
task's geometry, the metrics or the trainee model change (a reference made on another
version of the task is not used).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from davinci_sim.study.reference import (
    EXERCISE_REPETITIONS,
    EXERCISE_SUBJECTS,
    REFERENCE_SEED,
    REPETITIONS,
    SUBJECTS,
    exercise_reference,
    expert_reference,
    write_reference,
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("task", nargs="?", help="shipped path task name or task file")
    ap.add_argument("--exercise", help="a skill exercise (scripted expert operators)")
    ap.add_argument("--subjects", type=int, default=None)
    ap.add_argument("--repetitions", type=int, default=None)
    ap.add_argument("--seed", type=int, default=REFERENCE_SEED)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    if (args.task is None) == (args.exercise is None):
        ap.error("give a path task or --exercise NAME (one of them)")
    if args.exercise is not None:
        data = exercise_reference(
            args.exercise,
            subjects=args.subjects or EXERCISE_SUBJECTS,
            repetitions=args.repetitions or EXERCISE_REPETITIONS,
            seed=args.seed,
            progress=lambda s, r, row: print(
                f"expert {s + 1} repetition {r}: {'finished' if row['finished'] else 'unfinished'}",
                flush=True,
            ),  # fmt: skip
        )
    else:
        data = expert_reference(
            args.task,
            subjects=args.subjects or SUBJECTS,
            repetitions=args.repetitions or REPETITIONS,
            seed=args.seed,
        )
    out = args.out
    if out is None:
        import davinci_sim.tasks

        folder = Path(davinci_sim.tasks.__file__).parent / "data" / "reference"
        out = folder / f"{data['task']}.json"
    write_reference(data, out)
    print(f"{out}: {data['finished']}/{data['attempts']} attempts finished")


if __name__ == "__main__":
    main()
