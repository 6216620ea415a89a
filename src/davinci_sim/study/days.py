"""The rota design's figures: each group's performance per day (``design="rota"``,
:mod:`davinci_sim.study.config`), as a table for the report and as numbers to compare with
the measured groups (``operators/data/rota2023_path.json``).

A row is the control group's if it ran the first condition, else the assisted group's; its
day is its block (``order``). Per group and day: the mean over the group's subjects of each
subject's mean over that day's trials, the SD over those subject means, and the subjects.
"""

from __future__ import annotations

import json
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


def measured_rows() -> list[dict]:
    """The trials of Rota's real groups (``operators/data/rota2023_path.json``) as study
    rows: the subject's letter's index, condition 0 for the control group and the day's
    for the assisted group, the day as ``order``, the deviation (eq. 8) and its RMS in m and the
    time in s."""
    from importlib.resources import files

    data = json.loads(
        files("davinci_sim.operators").joinpath("data/rota2023_path.json").read_text()
    )
    return [
        {"subject": "ADIPSV".index(t["subject"]), "order": t["day"],
         "condition_name": f"their day {t['day']}",
         "condition": 0 if t["group"] == "control" else t["day"],
         "deviation_error": t["mean_deviation_mm"] / 1e3,
         "deviation_rms": t["rms_deviation_mm"] / 1e3, "completion_time": t["time_s"]}
        for t in data["trials"]
    ]  # fmt: skip


def days_section(rows: list[dict], conditions, measured: list[dict] | None = None) -> list[str]:
    """The report's section: deviation and time per group and day, and the assisted
    group's condition each day; then the same table of ``measured`` rows (the real groups,
    :func:`measured_rows`) where given."""
    L = [
        "## Groups by day (Rota's protocol)",
        "",
        "Control: the first condition every day; assisted: one condition a day. Each cell: the "
        "mean over the group's subjects of each subject's mean over the day's trials, ± the "
        "SD over those subject means (n subjects).",
        "",
        *_day_table(rows),
    ]
    if measured:
        L += [
            "Measured (Rota's dVRK-console study, `operators/data/rota2023_path.json`; the "
            "seed's eq. 8 deviation):",
            "",
            *_day_table(measured),
        ]
    return L


def _day_table(rows: list[dict]) -> list[str]:
    dev = {(f.group, f.day): f for f in day_figures(rows, "deviation_error")}
    time = {(f.group, f.day): f for f in day_figures(rows, "completion_time")}
    assisted_condition = {int(r["order"]): r["condition_name"] for r in rows if r["condition"]}
    L = [
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
