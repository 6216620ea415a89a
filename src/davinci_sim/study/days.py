"""The rota design's figures: each group's performance per day (``design="rota"``,
:mod:`davinci_sim.study.config`), as a table for the report and as numbers to compare with
the measured groups (``operators/data/rota2023_path.json``).

A row is the control group's if it ran the first condition, else the assisted group's; its
day is its block (``order``). Per group and day: the mean over the group's subjects of each
subject's mean over that day's trials, the SD over those subject means, and the subjects.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

GROUPS = ("control", "assisted")


@dataclass(frozen=True)
class DayFigure:
    """One group's figure on one day."""

    group: str
    day: int
    mean: float
    """Mean over subjects of the subject's mean over the day's trials (the metric's unit)."""
    sd: float
    """SD over the subjects' means (n − 1; nan with one subject)."""
    subjects: int


def group_of(row: dict) -> str:
    return "control" if row["condition"] == 0 else "assisted"


def day_figures(rows: list[dict], metric: str) -> list[DayFigure]:
    """Per group and day (in that order), the figure of ``metric`` over finished or not,
    finite values (a trial's metric is nan only where it has none)."""
    per: dict[tuple[str, int, int], list[float]] = {}
    for r in rows:
        value = float(r[metric])
        if np.isfinite(value):
            per.setdefault((group_of(r), int(r["order"]), int(r["subject"])), []).append(value)
    out = []
    for group in GROUPS:
        days = sorted({d for g, d, _ in per if g == group})
        for day in days:
            means = [np.mean(v) for (g, d, _), v in per.items() if g == group and d == day]
            sd = float(np.std(means, ddof=1)) if len(means) > 1 else float("nan")
            out.append(DayFigure(group, day, float(np.mean(means)), sd, len(means)))
    return out


def days_section(rows: list[dict], conditions) -> list[str]:
    """The report's section: deviation and time per group and day, and the assisted
    group's condition each day."""
    dev = {(f.group, f.day): f for f in day_figures(rows, "deviation_error")}
    time = {(f.group, f.day): f for f in day_figures(rows, "completion_time")}
    assisted_condition = {int(r["order"]): r["condition_name"] for r in rows if r["condition"]}
    L = [
        "## Groups by day (Rota's protocol)",
        "",
        "Control: the first condition every day; assisted: one condition a day. Each cell: the "
        "mean over the group's subjects of each subject's mean over the day's trials, ± the "
        "SD over those subject means (n subjects).",
        "",
        "| day | control deviation (mm) | control time (s) | assisted condition | "
        "assisted deviation (mm) | assisted time (s) |",
        "|---|---|---|---|---|---|",
    ]
    for day in sorted({d for _, d in dev}):

        def cell(table, group, scale=1.0, day=day):
            f = table.get((group, day))
            if f is None:
                return "–"
            return f"{scale * f.mean:.2f} ± {scale * f.sd:.2f} ({f.subjects})"

        L.append(
            f"| {day} | {cell(dev, 'control', 1e3)} | {cell(time, 'control')} | "
            f"{assisted_condition.get(day, '–')} | {cell(dev, 'assisted', 1e3)} | "
            f"{cell(time, 'assisted')} |"
        )
    return [*L, ""]
