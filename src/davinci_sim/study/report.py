"""The outputs of a study: ``trials.csv``, the figures like the seed's Figs 7-9, ``report.md``.

The claims section compares the simulated study with the seed's results (§III) on the
numbers only: each claim has a rule stated in the report, and the verdict is what the rule
gives (``agrees``, ``direction agrees, not significant``, or ``does not agree``). The claims
refer to Table I's conditions, so they are checked only for a study with 4 viscous conditions
whose first has no assistance (B = G_max = 0) and whose B increases. The report says which
law each condition ran (:func:`~davinci_sim.haptics.kinds.describe_fixture`).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from davinci_sim.haptics.kinds import describe_fixture, viscous_law
from davinci_sim.operators.params import population_method
from davinci_sim.study.compare import comparison
from davinci_sim.study.config import pair_labels
from davinci_sim.study.days import days_section, measured_rows
from davinci_sim.study.retention import (
    block_rows,
    mechanisms_text,
    plot_retention,
    retention_section,
)
from davinci_sim.study.runner import StudyResult
from davinci_sim.study.stats import friedman, pairwise_wilcoxon, subject_means
from davinci_sim.study.store import atomic_path, write_text_atomic
from davinci_sim.study.trial import METRICS
from davinci_sim.tasks.scoring import SCORE_COLUMNS
from davinci_sim.tasks.task import PathTask

#: The metrics' declarations (the study's task kind), by name.
DECLARED = {m.name: m for m in PathTask.METRICS}
#: The metrics of the report's summary table, in order, with their (unit, scale).
SUMMARY = tuple(m for m in PathTask.METRICS if m.report is not None)

COLUMNS = (
    "subject",
    "condition",
    "condition_name",
    "B",
    "G_max",
    "fixture",
    "law",
    "order",
    "block",
    "repetition",
    "practice",
    "own_practice",
    "mechanisms",
    "seed",
    "task",
    "finished",
    *METRICS,
    *SCORE_COLUMNS,
    "sim_time",
    "wall_time",
)
#: Columns that depend on the machine, not on the seed (left out of comparisons).
TIMING_COLUMNS = ("wall_time",)
ALPHA = 0.05


def write_csv(rows: list[dict], path: Path, columns=COLUMNS) -> None:
    """``rows`` as CSV in ``path`` (``columns``: a path study's), whole or not at all."""
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns)
        w.writeheader()
        for r in rows:
            w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()})


def _label(c) -> str:
    """The long label of a condition (a fixture entry or a (B, G_max) pair)."""
    if not isinstance(c, dict):
        return f"B={c[0]:g} Ns/m, Gmax={c[1]:g} N"
    if c.get("type") == "viscous":
        return f"B={c['B']:g} Ns/m, Gmax={c['G_max']:g} N"
    return str(c.get("name", c.get("type")))


def short_labels(conditions) -> list[str]:
    """Axis and table labels of ``conditions``: fixture entries by their names; (B, G_max)
    pairs ``B=40`` while B tells them apart, ``B=40/Gmax=5`` when two share a B."""
    if all(isinstance(c, dict) for c in conditions):
        return [str(c.get("name", c.get("type"))) for c in conditions]
    return pair_labels(conditions)


def _viscous_b(conditions) -> list[float] | None:
    """The B of each condition if every one is the seed's viscous law (else None)."""
    if not all(c.get("type") == "viscous" for c in conditions):
        return None
    return [float(c["B"]) for c in conditions]


def law_summary(conditions) -> str:
    """Which law the study ran, in one sentence (the viscous conditions' ramp said)."""
    ramps = {c.get("transition", 0.0) for c in conditions if c.get("type") == "viscous"}
    kinds = sorted({c.get("type", "none") for c in conditions})
    if kinds == ["viscous"] and len(ramps) == 1:
        return f"Viscous guidance, {viscous_law(ramps.pop())}."
    parts = [k for k in kinds if k != "viscous"]
    if ramps:
        parts.append("viscous, " + " and ".join(viscous_law(t) for t in sorted(ramps)))
    return "Fixtures: " + "; ".join(parts) + " (each condition's law below)."


def _by(rows, condition, key="repetition", metric="deviation_error"):
    out: dict[int, list[float]] = {}
    for r in rows:
        if r["condition"] == condition and np.isfinite(r[metric]):
            out.setdefault(r[key], []).append(float(r[metric]))
    return out


def _savefig(fig, path: Path) -> None:
    with atomic_path(path) as tmp:  # (whole or not at all)
        fig.savefig(tmp, dpi=120)


def plot_figures(result: StudyResult, folder: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cfg, rows = result.config, block_rows(result.rows, "practice")
    C = len(cfg.conditions)
    paths = []
    # Fig. 7: mean deviation per repetition, 20th-80th percentile bars, a panel per condition.
    fig, axes = plt.subplots(1, C, figsize=(3.2 * C, 3.2), sharey=True, squeeze=False)
    for c, ax in enumerate(axes[0]):
        per = _by(rows, c)
        reps = sorted(per)
        mean = np.array([np.mean(per[j]) for j in reps]) * 1e3
        lo = np.array([np.percentile(per[j], 20) for j in reps]) * 1e3
        hi = np.array([np.percentile(per[j], 80) for j in reps]) * 1e3
        # The bar is the 20th-80th percentile range itself: with a skewed distribution the
        # mean can lie outside it, which an errorbar (offsets from the mean) cannot draw.
        ax.vlines(reps, lo, hi, color="gray")
        ax.plot(reps, mean, "o", color="tab:blue")
        ax.set_title(_label(cfg.conditions[c]), fontsize=9)
        ax.set_xlabel("repetition")
        ax.set_xticks(reps)
    axes[0][0].set_ylabel("deviation error e (mm)")
    fig.tight_layout()
    paths.append(folder / "fig7_deviation_per_repetition.png")
    _savefig(fig, paths[-1])
    plt.close(fig)
    # Fig. 8: distribution of the deviation per condition.
    fig, ax = plt.subplots(figsize=(1.6 * C + 2, 3.5))
    data = [
        [
            r["deviation_error"] * 1e3
            for r in rows
            if r["condition"] == c and np.isfinite(r["deviation_error"])
        ]
        for c in range(C)
    ]
    ax.boxplot(data, whis=(5, 95))
    ax.set_xticks(range(1, C + 1), short_labels(cfg.conditions))
    ax.set_ylabel("deviation error e (mm)")
    ax.set_title("all repetitions of all subjects (whiskers 5-95 %)", fontsize=9)
    fig.tight_layout()
    paths.append(folder / "fig8_deviation_distribution.png")
    _savefig(fig, paths[-1])
    plt.close(fig)
    # Fig. 9: mean completion time per condition (bars: sd over subjects' means).
    table = subject_means(rows, "completion_time", cfg.n_subjects, C)
    fig, ax = plt.subplots(figsize=(1.6 * C + 2, 3.5))
    ax.bar(
        range(C),
        np.nanmean(table, axis=0),
        yerr=np.nanstd(table, axis=0) if cfg.n_subjects > 1 else None,
        color="tab:blue",
        capsize=4,
    )
    ax.set_xticks(range(C), short_labels(cfg.conditions))
    ax.set_ylabel("completion time (s)")
    ax.set_title("mean over subjects (bars: sd of the subjects' means)", fontsize=9)
    fig.tight_layout()
    paths.append(folder / "fig9_completion_time.png")
    _savefig(fig, paths[-1])
    plt.close(fig)
    return paths


def _pair(pairs, a, b):
    for p in pairs:
        if (p.a, p.b) == (a, b) or (p.a, p.b) == (b, a):
            return p
    raise KeyError((a, b))


def _lower(dev, pairs, a, b) -> str:
    """Verdict for 'condition a has a lower deviation than b'."""
    ma, mb = np.nanmean(dev[:, a]), np.nanmean(dev[:, b])
    if not ma < mb:
        return "does not agree"
    return "agrees" if _pair(pairs, a, b).p_holm < ALPHA else "direction agrees, not significant"


def claims(result: StudyResult) -> list[tuple[str, str, str]]:
    """(claim of the seed, what the simulation gives, verdict) for Table I-like studies."""
    cfg, rows = result.config, block_rows(result.rows, "practice")
    C, n = len(cfg.conditions), cfg.n_subjects
    if cfg.design != "within":  # (the rules use paired tests)
        return []
    b = _viscous_b(cfg.conditions)
    if C != 4 or b is None or b != sorted(b):
        return []
    if (cfg.conditions[0]["B"], cfg.conditions[0]["G_max"]) != (0.0, 0.0):
        return []
    dev = subject_means(rows, "deviation_error", n, C)
    ct = subject_means(rows, "completion_time", n, C)
    pairs = pairwise_wilcoxon(dev)
    m = np.nanmean(dev, axis=0) * 1e3
    out = []
    per = _by(rows, 0)
    reps = sorted(per)
    means = [np.mean(per[j]) for j in reps]
    if len(reps) >= 2:
        slope = float(np.polyfit(reps, np.array(means) * 1e3, 1)[0])
        verdict = "agrees" if slope < 0 else "does not agree"
        out.append(
            (
                "Without assistance (B=0) the deviation decreases slightly with repetition.",
                f"slope of the mean deviation over repetitions: {slope:+.4f} mm/repetition "
                "(rule: < 0)",
                verdict,
            )
        )
    for k, text in (
        (1, "B=20 reduces the deviation compared to B=0 (limited improvement)."),
        (2, "B=40 gives a significant reduction of the deviation compared to B=0."),
        (3, "B=60 also reduces the deviation compared to B=0."),
    ):
        p = _pair(pairs, 0, k)
        out.append(
            (
                text,
                f"mean of subjects' means {m[k]:.4f} mm vs {m[0]:.4f} mm, Wilcoxon p_Holm = "
                f"{p.p_holm:.3g} (rule: lower, p_Holm < {ALPHA})",
                _lower(dev, pairs, k, 0),
            )
        )
    mono = bool(m[0] > m[1] > m[2])
    out.append(
        (
            "The deviation decreases as the force increases (B = 0 → 20 → 40).",
            f"means {m[0]:.4f} > {m[1]:.4f} > {m[2]:.4f} mm? {'yes' if mono else 'no'}",
            "agrees" if mono else "does not agree",
        )
    )
    p = _pair(pairs, 2, 3)
    no_better = bool(not (m[3] < m[2] and p.p_holm < ALPHA))
    out.append(
        (
            "B=60 does not improve the deviation compared to B=40 (it tends to increase).",
            f"B=60 {m[3]:.4f} mm vs B=40 {m[2]:.4f} mm, p_Holm = {p.p_holm:.3g} "
            "(rule: not significantly lower)",
            ("agrees" if m[3] >= m[2] else "agrees (not significantly lower)")
            if no_better
            else "does not agree",
        )
    )
    t = np.nanmean(ct, axis=0)
    tp = pairwise_wilcoxon(ct)
    p = _pair(tp, 2, 3)
    if t[3] > t[2]:
        v = "agrees" if p.p_holm < ALPHA else "direction agrees, not significant"
    else:
        v = "does not agree"
    out.append(
        (
            "The task takes longer with B=60 than with B=40 (Fig. 9).",
            f"mean completion time {t[3]:.2f} s vs {t[2]:.2f} s, p_Holm = {p.p_holm:.3g}",
            v,
        )
    )
    sd = np.nanstd(dev, axis=0) * 1e3
    less = bool(np.all(sd[1:] < sd[0]))
    out.append(
        (
            "The variability of the deviation among subjects is reduced with assistance.",
            "sd of the subjects' means: "
            + ", ".join(f"B={b[k]:g}: {sd[k]:.4f} mm" for k in range(C))
            + " (rule: every assisted condition below B=0)",
            "agrees" if less else "does not agree",
        )
    )
    return out


def _fmt(x: float, digits: int = 4) -> str:
    return "nan" if not np.isfinite(x) else f"{x:.{digits}g}"


def write_report(
    result: StudyResult,
    path: Path,
    *,
    previous: list[dict] | None = None,
    changes: str | None = None,
) -> None:
    """Write ``report.md``. ``previous``: the rows of an earlier run of the same study
    (:func:`read_csv`), compared per condition; ``changes``: what differs from it
    (markdown, said first in that section)."""
    cfg, all_rows = result.config, result.rows
    rows = block_rows(all_rows, "practice")
    C, n = len(cfg.conditions), cfg.n_subjects
    sim_time = sum(r["sim_time"] for r in all_rows)
    trial_wall = sum(r["wall_time"] for r in all_rows)
    blocks = cfg.days
    rota = cfg.design == "rota"
    design = "Rota's two-group" if rota else f"{cfg.design}-subject"
    block = "day" if rota else "condition block"
    retention = (
        f" + {cfg.retention} retention repetitions (fixture off) after each practice block"
        if cfg.retention else ""
    )  # fmt: skip
    prior = (
        f", after {cfg.prior_practice} trials of practice before the study"
        if cfg.prior_practice else ""
    )  # fmt: skip
    L = [
        "# Simulated user study",
        "",
        f"Task `{cfg.task}`, {design} design: {n} subjects × {blocks} {block}(s) × "
        f"({cfg.n_repetitions} practice repetitions{retention}{prior}) "
        f"= {len(all_rows)} trials ({len(rows)} practice); seed {cfg.seed}; condition order "
        f"`{cfg.order}`; "
        f"`{cfg.engine}` engine, backend `{cfg.backend}` with {cfg.workers} worker(s); trial "
        f"timeout {cfg.timeout:g} s (simulated).",
        "",
        law_summary(cfg.conditions),
        "",
        "## Conditions",
        "",
        "| condition | law that ran | fixture entry |",
        "|---|---|---|",
        *(
            f"| {label} | {describe_fixture(c)} | "
            f"`{ {k: v for k, v in c.items() if k != 'name'} }` |"
            for label, c in zip(short_labels(cfg.conditions), cfg.conditions, strict=True)
        ),
        "",
        "## Synthetic trainees",
        "",
        f"Population `{cfg.population}`. " + population_method(cfg.population),
        "",
        mechanisms_text(cfg),
        "",
        *comparison(result, previous, changes),
        "## Run time",
        "",
        f"- wall time of the study: {result.wall_time:.1f} s "
        f"({result.wall_time / max(len(rows), 1):.2f} s per trial)",
        f"- simulated time of the trials: {sim_time:.1f} s (each from the trainee taking the "
        "handle, the tool at point 1, to the end); "
        f"{sim_time / max(result.wall_time, 1e-9):.2f}× real time overall, "
        f"{sim_time / max(trial_wall, 1e-9):.2f}× per worker",
        f"- unfinished trials (timed out): {sum(not r['finished'] for r in all_rows)}",
        *(
            [
                f"- resumed: {result.resumed} trials were kept from an interrupted run (not run "
                "again; the wall time above is this run's)"
            ]
            if result.resumed
            else []
        ),
        "",
        "## Summary",
        "",
        "Means over subjects of each subject's mean over its repetitions (± sd over subjects).",
        "",
        "| condition | " + "".join(f"{m.label} ({m.report[0]}) | " for m in SUMMARY) + "finished |",
        "|---|" + "---|" * len(SUMMARY) + "---|",
    ]
    tables = {k: subject_means(rows, k, n, C) for k in METRICS}
    for c in range(C):

        def cell(k, s=1.0, tables=tables, c=c):
            col = tables[k][:, c] * s
            return f"{_fmt(np.nanmean(col))} ± {_fmt(np.nanstd(col), 2)}"

        fin = sum(r["finished"] for r in rows if r["condition"] == c)
        tot = sum(1 for r in rows if r["condition"] == c)
        cells = "".join(f"{cell(m.name, m.report[1])} | " for m in SUMMARY)
        L.append(f"| {_label(cfg.conditions[c])} | {cells}{fin}/{tot} |")
    L.append("")
    if rota:  # (groups over days, no retention: not the conditions' tests below)
        measured = measured_rows() if cfg.task == "rota_path" else None  # (theirs beside)
        L += days_section(rows, cfg.conditions, measured)
        _report_end(L, result)
        write_text_atomic(path, "\n".join(L))
        return
    L += [
        "## Statistical tests",
        "",
        "Per-subject means; Friedman test across the conditions, then two-sided Wilcoxon "
        f"signed-rank tests of every pair, Holm-corrected (α = {ALPHA})."
        if C > 2
        else "Per-subject means; with two conditions the test is the two-sided Wilcoxon "
        "signed-rank test of the pair (Friedman's needs three or more).",
        "",
    ]
    labels = short_labels(cfg.conditions)
    for metric in ("deviation_error", "completion_time"):  # the seed's claims' metrics
        unit, s = DECLARED[metric].report
        L.append(f"### {metric.replace('_', ' ')}")
        L.append("")
        if C > 2:
            fr = friedman(tables[metric])
            L.append(f"Friedman χ² = {_fmt(fr.statistic)}, p = {_fmt(fr.pvalue)}.")
            L.append("")
        L.append(f"| pair | median difference ({unit}) | W | p | p (Holm) |")
        L.append("|---|---|---|---|---|")
        for p in pairwise_wilcoxon(tables[metric]):
            L.append(
                f"| {labels[p.a]} vs {labels[p.b]} | "
                f"{_fmt(p.median_difference * s)} | {_fmt(p.statistic)} | {_fmt(p.pvalue)} | "
                f"{_fmt(p.p_holm)} |"
            )
        L.append("")
    if cfg.design == "between":
        L += [
            "(Between-subject design: each subject did one condition, so the paired tests "
            "above have no complete subject; see the retention section's independent tests.)",
            "",
        ]
    L += retention_section(result, labels)
    _report_end(L, result)
    write_text_atomic(path, "\n".join(L))


def _report_end(L: list[str], result: StudyResult) -> None:
    """The report's last sections (the seed's claims, the trainees' limits, the files)."""
    cfg = result.config
    L += ["## The seed's claims", ""]
    found = claims(result)
    if not found:
        L.append(
            "Not applicable: the claims refer to Table I's four conditions (the first "
            "without assistance, B increasing); this study has other conditions."
        )
    else:
        L.append(
            "Each claim of the seed's §III, the rule applied to this study's numbers, and the "
            f"verdict (significance: Wilcoxon on per-subject means, Holm, α = {ALPHA}). With "
            "few subjects the tests have little power: read 'not significant' as 'no evidence "
            "either way'."
        )
        L.append("")
        L.append("| claim of the seed | simulated study | verdict |")
        L.append("|---|---|---|")
        for claim, numbers, verdict in found:
            L.append(f"| {claim} | {numbers} | **{verdict}** |")
    L += [
        "",
        "## What the synthetic trainees leave out",
        "",
        "The trainees (`davinci_sim.operators`) are a motor-control model: delayed visual "
        "feedback, minimum-jerk plans, signal-dependent noise, tremor, a limb impedance the "
        "guidance pushes against, a power law of practice. They do not misjudge depth in the "
        "stereo view, feel the guidance as intrusive, get tired or clutch; they rely on the "
        "guidance or stiffen their arm under it only when those mechanisms are on (above). "
        "A claim that hinges on such a reaction (e.g. strong "
        "guidance feeling too aggressive) is outside what this study can reproduce; a "
        "disagreement there says more about the model than about the fixture.",
        "",
        "## Files",
        "",
        "- `trials.csv`: one row per trial, every metric",
        "- `fig7_deviation_per_repetition.png`, `fig8_deviation_distribution.png`, "
        "`fig9_completion_time.png`" + (", `fig10_retention.png`" if cfg.retention else ""),
        "",
    ]


def write_outputs(result: StudyResult, folder) -> list[Path]:
    """Write ``trials.csv``, the three figures and ``report.md`` into ``folder``, each whole
    or not at all (temporary files renamed); a needle exercise's: :mod:`.exercise_report`."""
    if result.config.kind != "path":
        from davinci_sim.study.exercise_report import write_exercise_outputs as write

        return write(result, folder)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    write_csv(result.rows, folder / "trials.csv")
    paths = [folder / "trials.csv", *plot_figures(result, folder)]
    extra = plot_retention(result, folder, short_labels(result.config.conditions))
    paths += [extra] if extra is not None else []
    write_report(result, folder / "report.md")
    return [*paths, folder / "report.md"]
