"""The outputs of a study of a needle exercise: ``trials.csv``, a figure, ``report.md``.

A path study's report (:mod:`davinci_sim.study.report`) is the seed's: deviation and time,
its figures and claims. An exercise has its own metrics (:attr:`Task.METRICS
<davinci_sim.tasks.base.Task.METRICS>`, e.g. entry and exit errors, tissue trauma, drops)
and score; its report gives, per condition, the means over subjects of each metric the
task reports and of the score, the pass rate, and the same tests as a path study
(per-subject means; Friedman across three or more conditions, Wilcoxon signed-rank pairs
with Holm's correction) on the score and the completion time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from davinci_sim.haptics.kinds import describe_fixture
from davinci_sim.operators.params import population_method
from davinci_sim.study.report import ALPHA, _fmt, _label, law_summary, short_labels, write_csv
from davinci_sim.study.retention import block_rows
from davinci_sim.study.runner import StudyResult
from davinci_sim.study.stats import friedman, pairwise_wilcoxon, subject_means
from davinci_sim.study.store import atomic_path, write_text_atomic
from davinci_sim.tasks.scoring import SCORE_COLUMNS

#: The columns of a row before the task's metrics (:func:`~davinci_sim.study.trial.
#: spec_columns`).
SPEC_COLUMNS = ("subject", "condition", "condition_name", "B", "G_max", "fixture", "law",
                "order", "block", "repetition", "practice", "own_practice", "mechanisms",
                "seed", "task", "finished")  # fmt: skip
#: The metrics the tests compare (every exercise has both).
TESTED = ("score", "completion_time")


def exercise_columns(task) -> tuple[str, ...]:
    """The columns of ``task``'s study rows, in order."""
    return (*SPEC_COLUMNS, *(m.name for m in task.METRICS), *SCORE_COLUMNS, "sim_time",
            "wall_time")  # fmt: skip


def _entry(condition: dict) -> dict:
    return {k: v for k, v in condition.items() if k != "name"}


def _task(result: StudyResult):
    from davinci_sim.study.config import study_task

    return study_task(result.config.task)


def plot_scores(result: StudyResult, folder: Path) -> Path:
    """``scores_per_repetition.png``: the mean score (%) of the finished attempts per
    repetition, a line per condition (practice blocks)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cfg, rows = result.config, [r for r in block_rows(result.rows, "practice") if r["finished"]]
    fig, ax = plt.subplots(figsize=(6.0, 3.6))
    reps = np.arange(1, cfg.n_repetitions + 1)
    for c, label in enumerate(short_labels(cfg.conditions)):
        means = [np.nanmean([float(r["score"]) for r in rows
                             if r["condition"] == c and r["repetition"] == j] or [np.nan])
                 for j in reps]  # fmt: skip
        ax.plot(reps, means, "o-", label=label)
    ax.set_xlabel("repetition")
    ax.set_ylabel("score (%)")
    ax.set_title(f"{cfg.task}: score per repetition")
    ax.legend(fontsize=8)
    ax.set_xticks(reps)
    fig.tight_layout()
    path = folder / "scores_per_repetition.png"
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return path


def write_exercise_report(result: StudyResult, path: Path) -> None:
    """Write the exercise study's ``report.md`` (see the module docstring)."""
    cfg, all_rows = result.config, result.rows
    task = _task(result)
    rows = block_rows(all_rows, "practice")
    C, n = len(cfg.conditions), cfg.n_subjects
    shown = [m for m in task.METRICS if m.report is not None]
    sim_time = sum(r["sim_time"] for r in all_rows)
    labels = short_labels(cfg.conditions)
    L = [
        "# Simulated user study",
        "",
        f"Task `{cfg.task}` (a `{task.kind}` exercise), {cfg.design}-subject design: {n} "
        f"subjects × {cfg.days} condition block(s) × {cfg.n_repetitions} practice "
        f"repetitions"
        + (f" + {cfg.retention} retention" if cfg.retention else "")
        + f" = {len(all_rows)} trials; seed {cfg.seed}; condition order `{cfg.order}`; "
        "`live` engine (one simulation per trial, both teleoperations and the haptic loop "
        "as at the console).",
        "",
        law_summary(cfg.conditions),
        "",
        "## Conditions",
        "",
        "The fixture acts on the task's MTM (the driving instrument's), along the task's "
        "guidance path (a needle drive: the needle driver's tool tip turning the needle "
        "through each pair of marks).",
        "",
        "| condition | law that ran | fixture entry |",
        "|---|---|---|",
        *(
            f"| {label} | {describe_fixture(c)} | `{_entry(c)}` |"
            for label, c in zip(labels, cfg.conditions, strict=True)
        ),  # fmt: skip
        "",
        "## Synthetic trainees",
        "",
        f"Population `{cfg.population}`. " + population_method(cfg.population),
        "",
        "Each trainee does the exercise as the scripted expert plans it "
        "(`davinci_sim.study.experts`: reaches, grasps, hand-offs and turns), with its own "
        "speed, motor noise, tremor, visuomotor delay and practice, its hands on both MTMs "
        "through the console (`davinci_sim.study.console_trial`). It corrects each reach by "
        "what it sees of the tool; it does not plan differently from the expert, misjudge "
        "depth or feel the guidance as intrusive.",
        "",
        "## Run time",
        "",
        f"- wall time of the study: {result.wall_time:.1f} s "
        f"({result.wall_time / max(len(all_rows), 1):.1f} s per trial)",
        f"- simulated time of the trials: {sim_time:.1f} s",
        f"- unfinished trials (a fault, a teleoperation that stopped, or out of time): "
        f"{sum(not r['finished'] for r in all_rows)}",
        "",
        "## Summary",
        "",
        "Means over subjects of each subject's mean over its finished repetitions (± sd over "
        "subjects; an unfinished attempt's metrics are of the part it did, left out here).",
        "",
        "| condition | "
        + "".join(f"{m.label} ({m.report[0]}) | " for m in shown)
        + "score (%) | passed | finished |",
        "|---|" + "---|" * (len(shown) + 3),
    ]
    finished = [r for r in rows if r["finished"]]  # (an unfinished attempt's part: no mean)
    tables = {m: subject_means(finished, m, n, C)
              for m in {*(x.name for x in shown), *TESTED}}  # fmt: skip
    for c in range(C):

        def cell(k, s=1.0, c=c):
            col = tables[k][:, c] * s
            if not np.isfinite(col).any():
                return "—"
            return f"{_fmt(np.nanmean(col))} ± {_fmt(np.nanstd(col), 2)}"

        mine = [r for r in rows if r["condition"] == c]
        passed = sum(bool(r.get("passed")) for r in mine)
        fin = sum(bool(r["finished"]) for r in mine)
        cells = "".join(f"{cell(m.name, m.report[1])} | " for m in shown)
        L.append(f"| {_label(cfg.conditions[c])} | {cells}{cell('score')} | "
                 f"{passed}/{len(mine)} | {fin}/{len(mine)} |")  # fmt: skip
    L += ["", "## Statistical tests", ""]
    if C < 2 or cfg.design == "between":
        L += ["None: the tests compare conditions within subjects (two or more conditions, "
              "within-subject design).", ""]  # fmt: skip
    else:
        L += [
            f"Per-subject means; Friedman across the conditions, then two-sided Wilcoxon "
            f"signed-rank tests of every pair, Holm-corrected (α = {ALPHA})."
            if C > 2
            else "Per-subject means; the two-sided Wilcoxon signed-rank test of the pair.",
            "",
        ]
        for metric in TESTED:
            L += [f"### {metric.replace('_', ' ')}", ""]
            if C > 2:
                fr = friedman(tables[metric])
                L += [f"Friedman χ² = {_fmt(fr.statistic)}, p = {_fmt(fr.pvalue)}.", ""]
            L += ["| pair | median difference | W | p | p (Holm) |", "|---|---|---|---|---|"]
            for p in pairwise_wilcoxon(tables[metric]):
                L.append(
                    f"| {labels[p.a]} vs {labels[p.b]} | {_fmt(p.median_difference)} | "
                    f"{_fmt(p.statistic)} | {_fmt(p.pvalue)} | {_fmt(p.p_holm)} |"
                )
            L.append("")
    L += [
        "## Files",
        "",
        "- `trials.csv`: one row per trial, every metric of the exercise",
        "- `scores_per_repetition.png`: the mean score of the finished attempts per "
        "repetition and condition",
        "",
    ]
    write_text_atomic(path, "\n".join(L))


def write_exercise_outputs(result: StudyResult, folder) -> list[Path]:
    """Write ``trials.csv``, ``scores_per_repetition.png`` and ``report.md`` of an exercise
    study into ``folder``, each whole or not at all."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    write_csv(result.rows, folder / "trials.csv", exercise_columns(_task(result)))
    figure = plot_scores(result, folder)
    write_exercise_report(result, folder / "report.md")
    return [folder / "trials.csv", figure, folder / "report.md"]
