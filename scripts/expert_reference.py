#!/usr/bin/env python
"""Make the expert reference data set of a task (the default pass marks of its scoring).

    PYTHONPATH=src python scripts/expert_reference.py seed_path

runs 9 expert-parameter synthetic trainees x 5 unassisted repetitions of the task in the
study's batch engine (davinci_sim.study.reference) and writes
src/davinci_sim/tasks/data/reference/<task>.json (or --out): per metric the mean, SD and n,
and how the file was made. Re-run it when the task's geometry, the metrics or the trainee
model change (a reference made on another version of the task is not used).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from davinci_sim.study.reference import (
    REFERENCE_SEED,
    REPETITIONS,
    SUBJECTS,
    expert_reference,
    write_reference,
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("task", help="shipped task name or task file")
    ap.add_argument("--subjects", type=int, default=SUBJECTS)
    ap.add_argument("--repetitions", type=int, default=REPETITIONS)
    ap.add_argument("--seed", type=int, default=REFERENCE_SEED)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    data = expert_reference(
        args.task, subjects=args.subjects, repetitions=args.repetitions, seed=args.seed
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
