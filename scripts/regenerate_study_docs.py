"""Regenerate ``docs/study/seed_path/``: the full default study (as ``davinci-sim study``),
its report comparing it with the run the folder held before, and what changed since.

``python scripts/regenerate_study_docs.py [--changes FILE]``: reads the folder's current
``trials.csv`` as the previous run, runs the study (10 subjects x Table I x 10 repetitions,
2 workers, ~2 min on 2 idle cores), writes the outputs, then the report with a "Compared with
the previous run" section (the per-condition means, previous -> this run) led by the text of
``--changes`` (markdown). ``--retention N``, ``--mechanisms NAMES`` and ``--population
NAME`` as ``davinci-sim study``'s; ``--folder NAME`` writes ``docs/study/NAME/`` instead
(e.g. the study rerun with the trainees fitted to Rota's control group: ``--population
rota2023 --folder seed_path_rota2023``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import davinci_sim  # noqa: F401  (sets MUJOCO_GL)
from davinci_sim.study import StudyConfig, run_study, write_outputs
from davinci_sim.study.compare import read_csv
from davinci_sim.study.report import write_report

DOCS = Path(__file__).resolve().parent.parent / "docs" / "study"


def main(changes: str | None, retention: int = 0, mechanisms: tuple[str, ...] = (),
         population: str = "trainee", folder: str = "seed_path") -> None:  # fmt: skip
    out = DOCS / folder
    old = out / "trials.csv"
    previous = read_csv(old) if old.exists() else None
    result = run_study(StudyConfig(workers=2, retention=retention, mechanisms=mechanisms,
                                   population=population))  # fmt: skip
    write_outputs(result, out)
    write_report(result, out / "report.md", previous=previous, changes=changes)
    print(f"wall time {result.wall_time:.1f} s")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--changes", help="markdown file: what changed since the previous run")
    parser.add_argument("--retention", type=int, default=0, help="as davinci-sim study's")
    parser.add_argument("--mechanisms", default="", help="as davinci-sim study's")
    parser.add_argument("--population", default="trainee", help="as davinci-sim study's")
    parser.add_argument("--folder", default="seed_path", help="under docs/study/")
    args = parser.parse_args()
    main(
        Path(args.changes).read_text() if args.changes else None,
        args.retention,
        tuple(m for m in args.mechanisms.split(",") if m),
        args.population,
        args.folder,
    )
