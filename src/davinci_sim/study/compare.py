"""A study compared with an earlier run of it: :func:`read_csv` reads the earlier run's
``trials.csv``, :func:`comparison` writes the report's section *Compared with the previous
run* (what changed, said by the caller, then each condition's means, previous → this run).
"""

from __future__ import annotations

import csv

import numpy as np

from davinci_sim.study.runner import StudyResult
from davinci_sim.study.stats import subject_means
from davinci_sim.tasks.task import PathTask

#: The metrics' declarations (the study's task kind), by name.
DECLARED = {m.name: m for m in PathTask.METRICS}


def read_csv(path) -> list[dict]:
    """The rows of a study's ``trials.csv`` (numbers as numbers), e.g. an earlier run's, to
    compare with (:func:`write_report`'s ``previous``)."""
    rows = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            row: dict = {}
            for k, v in r.items():
                if v in ("True", "False"):
                    row[k] = v == "True"
                else:
                    try:
                        row[k] = int(v)
                    except ValueError:
                        try:
                            row[k] = float(v)
                        except ValueError:
                            row[k] = v
            rows.append(row)
    return rows


def comparison(result: StudyResult, previous: list[dict] | None, changes: str | None) -> list:
    """The section comparing this study with an earlier run of it (``previous``: its rows),
    with ``changes`` (what differs, markdown) said first."""
    if previous is None and not changes:
        return []
    L = ["## Compared with the previous run", ""]
    if changes:
        L += [changes.strip(), ""]
    if previous is None:
        return L
    cfg = result.config
    rows = [r for r in result.rows if r.get("block", "practice") == "practice"]
    C, n = len(cfg.conditions), cfg.n_subjects
    keep = [r for r in previous if 0 <= int(r["condition"]) < C]
    keep = [r for r in keep if r.get("block", "practice") == "practice"]
    n_old = max((int(r["subject"]) for r in keep), default=-1) + 1
    if not keep or n_old < 1:
        return [*L, "The previous run has none of these conditions.", ""]
    metrics = [m for m in ("deviation_error", "mean_force", "completion_time")
               if all(m in r for r in keep)]  # fmt: skip
    L.append(
        "Means over subjects of each subject's mean, previous → this run "
        "(conditions matched by their place in the list)."
    )
    L.append("")
    L.append("| condition | " + " | ".join(
        f"{DECLARED[m].label} ({DECLARED[m].report[0]})" for m in metrics) + " |")  # fmt: skip
    L.append("|---|" + "---|" * len(metrics))
    labels = [str(c.get("name", c.get("type"))) for c in cfg.conditions]
    for c in range(C):
        cells = []
        for m in metrics:
            unit, s = DECLARED[m].report
            old = np.nanmean(subject_means(keep, m, n_old, C)[:, c]) * s
            new = np.nanmean(subject_means(rows, m, n, C)[:, c]) * s
            change = f" ({(new - old) / old:+.0%})" if old else ""
            cells.append(f"{_fmt(old)} → {_fmt(new)}{change}")
        L.append(f"| {labels[c]} | " + " | ".join(cells) + " |")
    L.append("")
    return L


def _fmt(x: float, digits: int = 4) -> str:
    return "nan" if not np.isfinite(x) else f"{x:.{digits}g}"
