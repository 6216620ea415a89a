"""Statistics on synthetic data with known answers."""

import numpy as np
import pytest
from scipy import stats

from davinci_sim.study import friedman, holm, pairwise_wilcoxon, subject_means


def test_holm_known_values():
    """Holm: sorted p times (m - rank), running max, capped at 1, in input order."""
    p = [0.01, 0.04, 0.03, 0.005]
    # sorted 0.005, 0.01, 0.03, 0.04 -> x4, x3, x2, x1 = 0.02, 0.03, 0.06, 0.04 -> max 0.06
    np.testing.assert_allclose(holm(p), [0.03, 0.06, 0.06, 0.02])
    np.testing.assert_allclose(holm([0.2, 0.9]), [0.4, 0.9])
    assert holm([0.6, 0.9])[0] == 1.0


def test_friedman_identical_columns_and_clear_ordering():
    """Columns ranked the same in every subject give χ² = n·(k−1) and a small p."""
    n, k = 10, 4
    table = np.arange(k)[None, :] + 0.1 * np.arange(n)[:, None]
    fr = friedman(table)
    assert fr.statistic == pytest.approx(n * (k - 1))
    assert fr.pvalue == pytest.approx(stats.chi2.sf(n * (k - 1), k - 1))
    assert np.isnan(friedman(table[:, :2]).pvalue)  # fewer than 3 conditions


def test_pairwise_wilcoxon_exact_p_and_correction():
    """10 subjects all lower in column 0: exact two-sided p = 2/2^10 for (0, 1)."""
    rng = np.random.default_rng(1)
    base = rng.normal(size=10)
    table = np.stack(
        [base, base + 1 + rng.uniform(0, 0.1, 10), base + 1e-3 * rng.normal(size=10)], 1
    )
    pairs = pairwise_wilcoxon(table)
    assert [(p.a, p.b) for p in pairs] == [(0, 1), (0, 2), (1, 2)]
    assert pairs[0].pvalue == pytest.approx(2 / 2**10)
    assert pairs[0].median_difference < 0
    np.testing.assert_allclose([p.p_holm for p in pairs], holm([p.pvalue for p in pairs]))


def test_subject_means_skips_nan():
    rows = [
        {"subject": 0, "condition": 0, "x": 1.0},
        {"subject": 0, "condition": 0, "x": 3.0},
        {"subject": 0, "condition": 1, "x": float("nan")},
        {"subject": 1, "condition": 1, "x": 5.0},
    ]
    t = subject_means(rows, "x", 2, 2)
    assert t[0, 0] == 2.0 and t[1, 1] == 5.0 and np.isnan(t[0, 1]) and np.isnan(t[1, 0])
