"""The retention block of a study's report: conditions compared with the fixture off.

After each condition's practice block a study may run ``retention`` repetitions of the task
with the fixture off (:mod:`davinci_sim.study.config`). This module writes the report's
section on them and its figure: per-subject means in the retention block per practised
condition, compared with the same machinery as the practice block (within-subject design:
Friedman, then Wilcoxon signed-rank pairs, Holm; between-subject design: Kruskal-Wallis,
then Mann-Whitney pairs, Holm), and the design's limits said in words.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from davinci_sim.operators.params import Mechanisms
from davinci_sim.study.stats import (
    friedman,
    kruskal,
    pairwise_mannwhitney,
    pairwise_wilcoxon,
    subject_means,
)
from davinci_sim.study.store import atomic_path

ALPHA = 0.05
#: The retention block's compared metrics, with their unit and scale to it.
METRICS = (("deviation_error", "mm", 1e3), ("completion_time", "s", 1.0))


def block_rows(rows: list[dict], block: str) -> list[dict]:
    """The rows of ``block`` (``practice`` or ``retention``; rows without a block column,
    of a study before retention blocks, are practice)."""
    return [r for r in rows if r.get("block", "practice") == block]


def _fmt(x: float, digits: int = 4) -> str:
    return "nan" if not np.isfinite(x) else f"{x:.{digits}g}"


def _tests(table, paired: bool):
    if paired:
        return friedman(table), pairwise_wilcoxon(table)
    return kruskal(table), pairwise_mannwhitney(table)


def design_text(cfg) -> str:
    """Which design ran and what its retention block can and cannot tell."""
    if cfg.design == "between":
        return (
            f"**Design: between subjects.** Subject s practised only condition s mod "
            f"{len(cfg.conditions)} ({cfg.n_repetitions} repetitions), then did "
            f"{cfg.retention} repetitions with the fixture off: each retention mean measures "
            "what one condition's practice left, the design of the guidance-hypothesis "
            "studies (e.g. Oquendo et al. 2023). Groups are independent: Kruskal-Wallis, "
            "then Mann-Whitney pairs (Holm). With few subjects per group the tests have "
            "little power, and the groups differ in their subjects' physiology too."
        )
    return (
        f"**Design: within subjects.** Every subject practised every condition in a "
        f"counterbalanced order (`{cfg.order}`), {cfg.n_repetitions} repetitions each, each "
        f"block followed by {cfg.retention} repetitions with the fixture off. A retention "
        "block therefore measures the *carry-over* of that condition's practice on top of "
        "all the practice before it (other conditions' and their retention blocks'); the "
        "counterbalancing spreads the earlier practice over the conditions but does not "
        "remove it, so differences between conditions are diluted compared with a between-"
        "subject design (`--design between`), the literature's usual design for the "
        "guidance hypothesis. Paired tests: Friedman, then Wilcoxon signed-rank pairs (Holm)."
    )


def mechanisms_text(cfg) -> str:
    """Which trainee mechanisms ran, with their values."""
    m = Mechanisms.named(cfg.mechanisms)
    on = []
    if m.reliance > 0:
        on.append(
            f"**reliance on guidance** (reliance {m.reliance:g} at half force "
            f"{m.reliance_half_force:g} N: a guided trial counts 1 − reliance·G/(G + half) of "
            "an unguided one for the trainee's own correction — crossover and motor noise)"
        )
    if m.stiffening_gain > 0:
        on.append(
            f"**arm stiffening** (co-contraction {m.stiffening_gain:g}/N above "
            f"{m.stiffening_threshold:g} N of force on the hand, lag {m.stiffening_time:g} s, "
            f"stiffness and damping at most ×{1 + m.stiffening_max:g})"
        )
    if not on:
        return (
            "Trainee mechanisms: **none** (no reliance on guidance, no stiffening): the "
            "trainees learn the same from guided and unguided practice, so a retention "
            "difference can come only from the practice order and the noise."
        )
    return (
        "Trainee mechanisms on: "
        + "; ".join(on)
        + " (`davinci_sim.operators.params.Mechanisms`: sources and which values are "
        "assumptions)."
    )


def stiffening_reach(rows: list[dict], labels: list[str], n_conditions: int) -> str:
    """How often the guidance reached the stiffening threshold: the share of each
    condition's practice trials whose peak guidance force exceeded it."""
    threshold = Mechanisms.named(["stiffening"]).stiffening_threshold
    parts = []
    for c in range(n_conditions):
        peaks = [float(r["peak_force"]) for r in rows if r["condition"] == c]
        if peaks:
            share = float(np.mean(np.array(peaks) > threshold))
            parts.append(f"{labels[c]} {share:.0%} (largest {max(peaks):.2g} N)")
    return (
        f"The stiffening acts only while the force on the hand exceeds {threshold:g} N: "
        "practice trials whose peak guidance force exceeded it: " + ", ".join(parts) + "."
    )


def retention_section(result, labels: list[str]) -> list[str]:
    """The report's lines on the retention block (none when the study ran none)."""
    cfg, rows = result.config, result.rows
    ret = block_rows(rows, "retention")
    if not cfg.retention or not ret:
        return []
    C, n = len(cfg.conditions), cfg.n_subjects
    prac = block_rows(rows, "practice")
    paired = cfg.design != "between"
    L = ["## Retention: the fixture off after each condition's practice", ""]
    L += [design_text(cfg), "", mechanisms_text(cfg), ""]
    if "stiffening" in cfg.mechanisms:
        L += [stiffening_reach(prac, labels, C), ""]
    L += [
        "Means over subjects of each subject's retention mean (± sd over subjects), per "
        "practised condition; 'end of practice' is the mean of the practice block's last "
        f"{min(cfg.retention, cfg.n_repetitions)} repetitions (with the fixture on).",
        "",
        "| practised condition | deviation, end of practice (mm) | deviation, retention (mm) "
        "| completion time, retention (s) | finished |",
        "|---|---|---|---|---|",
    ]
    last = max(1, cfg.n_repetitions - min(cfg.retention, cfg.n_repetitions) + 1)
    end = [r for r in prac if r["repetition"] >= last]
    end_dev = subject_means(end, "deviation_error", n, C) * 1e3
    tables = {m: subject_means(ret, m, n, C) * s for m, _, s in METRICS}
    for c in range(C):
        dev, ct = tables["deviation_error"][:, c], tables["completion_time"][:, c]
        fin = sum(r["finished"] for r in ret if r["condition"] == c)
        tot = sum(1 for r in ret if r["condition"] == c)
        L.append(
            f"| {labels[c]} | {_fmt(np.nanmean(end_dev[:, c]))} | "
            f"{_fmt(np.nanmean(dev))} ± {_fmt(np.nanstd(dev), 2)} | "
            f"{_fmt(np.nanmean(ct))} ± {_fmt(np.nanstd(ct), 2)} | {fin}/{tot} |"
        )
    L.append("")
    significant = []
    for metric, unit, _ in METRICS:
        omnibus, pairs = _tests(tables[metric], paired)
        name = "Friedman χ²" if paired else "Kruskal-Wallis H"
        L += [f"### retention {metric.replace('_', ' ')}", ""]
        if C > 2:
            L += [f"{name} = {_fmt(omnibus.statistic)}, p = {_fmt(omnibus.pvalue)}.", ""]
        L += [f"| pair | median difference ({unit}) | statistic | p | p (Holm) |",
              "|---|---|---|---|---|"]  # fmt: skip
        for p in pairs:
            L.append(
                f"| {labels[p.a]} vs {labels[p.b]} | {_fmt(p.median_difference)} | "
                f"{_fmt(p.statistic)} | {_fmt(p.pvalue)} | {_fmt(p.p_holm)} |"
            )
            if p.p_holm < ALPHA:
                significant.append(f"{metric.replace('_', ' ')}: {labels[p.a]} vs {labels[p.b]}")
        L.append("")
    L += ["### What the retention block shows", "", *_reading(tables, labels, significant), ""]
    L += ["Figure: `fig10_retention.png`.", ""]
    return L


def _reading(tables, labels, significant) -> list[str]:
    dev = np.nanmean(tables["deviation_error"], axis=0)
    best, worst = int(np.nanargmin(dev)), int(np.nanargmax(dev))
    out = [
        f"With the fixture off, the lowest mean deviation followed practice with "
        f"{labels[best]} ({_fmt(dev[best])} mm), the highest practice with {labels[worst]} "
        f"({_fmt(dev[worst])} mm); spread across conditions {_fmt(dev[worst] - dev[best])} mm."
    ]
    if significant:
        out.append("Significant after Holm (α = 0.05): " + "; ".join(significant) + ".")
    else:
        out.append(
            "No pair differs significantly after Holm (α = 0.05): with these subjects the "
            "retention block gives no evidence either way that a condition trained better."
        )
    return out


def plot_retention(result, folder: Path, labels: list[str]) -> Path | None:
    """``fig10_retention.png``: per practised condition, the mean deviation at the end of
    practice (fixture on) and in retention (fixture off), bars the sd over subjects."""
    cfg, rows = result.config, result.rows
    ret = block_rows(rows, "retention")
    if not cfg.retention or not ret:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    C, n = len(cfg.conditions), cfg.n_subjects
    prac = block_rows(rows, "practice")
    last = max(1, cfg.n_repetitions - min(cfg.retention, cfg.n_repetitions) + 1)
    end = subject_means([r for r in prac if r["repetition"] >= last], "deviation_error", n, C)
    kept = subject_means(ret, "deviation_error", n, C)
    x = np.arange(C)
    fig, ax = plt.subplots(figsize=(1.8 * C + 2, 3.5))
    for k, (table, name, colour) in enumerate(
        (
            (end, "end of practice (fixture on)", "tab:gray"),
            (kept, "retention (fixture off)", "tab:blue"),
        )  # fmt: skip
    ):
        sd = np.nanstd(table, axis=0) * 1e3 if n > 1 else None
        ax.bar(x + (k - 0.5) * 0.38, np.nanmean(table, axis=0) * 1e3, 0.38, yerr=sd,
               color=colour, capsize=3, label=name)  # fmt: skip
    ax.set_xticks(x, labels)
    ax.set_xlabel("practised condition")
    ax.set_ylabel("deviation error e (mm)")
    ax.set_title(f"{cfg.design}-subject design; bars: sd of the subjects' means", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = folder / "fig10_retention.png"
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)
    return path
