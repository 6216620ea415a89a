"""Statistics of a study: per-subject means, Friedman test, pairwise Wilcoxon with Holm.

The unit of analysis is the subject (repeated measures): each subject's metric is averaged
over its repetitions in each condition, giving an (n_subjects, n_conditions) table. The
Friedman test asks whether the conditions differ; the pairwise Wilcoxon signed-rank tests
(two-sided, every pair of conditions) say which, their p-values corrected for the number of
pairs by Holm's step-down method (Holm 1979).
"""

from __future__ import annotations

from itertools import combinations
from typing import NamedTuple

import numpy as np
from scipy import stats


class FriedmanResult(NamedTuple):
    statistic: float
    pvalue: float


class PairwiseResult(NamedTuple):
    a: int
    """Condition index."""
    b: int
    statistic: float
    pvalue: float
    """Uncorrected two-sided p-value."""
    p_holm: float
    """Holm-corrected p-value."""
    median_difference: float
    """Median over subjects of (a − b)."""


def subject_means(rows: list[dict], metric: str, n_subjects: int, n_conditions: int):
    """(n_subjects, n_conditions) means of ``metric`` over each subject's repetitions
    (nan values, e.g. of trials that never started, are left out)."""
    sums = np.zeros((n_subjects, n_conditions))
    counts = np.zeros((n_subjects, n_conditions))
    for r in rows:
        v = float(r[metric])
        if np.isfinite(v):
            sums[r["subject"], r["condition"]] += v
            counts[r["subject"], r["condition"]] += 1
    with np.errstate(invalid="ignore"):
        return np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)


def holm(pvalues) -> np.ndarray:
    """Holm-corrected p-values, in the input's order (monotone, capped at 1)."""
    p = np.asarray(pvalues, dtype=float)
    m = len(p)
    order = np.argsort(p, kind="stable")
    adjusted = np.empty(m)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, (m - rank) * p[i])
        adjusted[i] = min(1.0, running)
    return adjusted


def friedman(table) -> FriedmanResult:
    """Friedman test over the columns (conditions) of ``table`` (subjects × conditions);
    nan if there are fewer than 3 conditions or 2 complete subjects."""
    t = np.asarray(table, dtype=float)
    t = t[np.all(np.isfinite(t), axis=1)]
    if t.shape[1] < 3 or t.shape[0] < 2:
        return FriedmanResult(float("nan"), float("nan"))
    s, p = stats.friedmanchisquare(*t.T)
    return FriedmanResult(float(s), float(p))


def pairwise_wilcoxon(table) -> list[PairwiseResult]:
    """Two-sided Wilcoxon signed-rank test of every pair of columns, Holm-corrected."""
    t = np.asarray(table, dtype=float)
    raw = []
    for a, b in combinations(range(t.shape[1]), 2):
        ok = np.isfinite(t[:, a]) & np.isfinite(t[:, b])
        d = t[ok, a] - t[ok, b]
        if len(d) == 0 or np.all(d == 0):
            s, p = float("nan"), 1.0
        else:
            s, p = stats.wilcoxon(t[ok, a], t[ok, b])
        med = float(np.median(d)) if len(d) else float("nan")
        raw.append((a, b, float(s), float(p), med))
    adjusted = holm([r[3] for r in raw]) if raw else []
    return [
        PairwiseResult(a, b, s, p, float(q), med)
        for (a, b, s, p, med), q in zip(raw, adjusted, strict=True)
    ]


def kruskal(table) -> FriedmanResult:
    """Kruskal-Wallis test over the columns (independent groups) of ``table`` (subjects ×
    conditions, nan where a subject did not do the condition: the between-subject design);
    nan if fewer than 2 groups have 2 or more values."""
    groups = [c[np.isfinite(c)] for c in np.asarray(table, dtype=float).T]
    groups = [g for g in groups if len(g) >= 2]
    if len(groups) < 2 or all(np.all(g == groups[0][0]) for g in groups):
        return FriedmanResult(float("nan"), float("nan"))
    s, p = stats.kruskal(*groups)
    return FriedmanResult(float(s), float(p))


def pairwise_mannwhitney(table) -> list[PairwiseResult]:
    """Two-sided Mann-Whitney U test of every pair of columns (independent groups), Holm-
    corrected; ``median_difference`` is median(a) − median(b)."""
    t = np.asarray(table, dtype=float)
    raw = []
    for a, b in combinations(range(t.shape[1]), 2):
        x, y = t[np.isfinite(t[:, a]), a], t[np.isfinite(t[:, b]), b]
        if len(x) == 0 or len(y) == 0:
            raw.append((a, b, float("nan"), 1.0, float("nan")))
            continue
        s, p = stats.mannwhitneyu(x, y, alternative="two-sided")
        raw.append((a, b, float(s), float(p), float(np.median(x) - np.median(y))))
    adjusted = holm([r[3] for r in raw]) if raw else []
    return [
        PairwiseResult(a, b, s, p, float(q), med)
        for (a, b, s, p, med), q in zip(raw, adjusted, strict=True)
    ]
