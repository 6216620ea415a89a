"""Subject parameter distributions and minimum-jerk plans."""

from __future__ import annotations

import numpy as np
import pytest

from davinci_sim.geometry.path import Polyline
from davinci_sim.operators.params import sample_subjects
from davinci_sim.operators.plan import minimum_jerk, path_plan, straight_plan, stroke_durations


def test_subjects_deterministic_and_independent_of_population_size():
    a = sample_subjects(10, seed=3)
    b = sample_subjects(20, seed=3)
    c = sample_subjects(10, seed=4)
    np.testing.assert_array_equal(a.stiffness, b.stiffness[:10])
    np.testing.assert_array_equal(a.delay, sample_subjects(10, seed=3).delay)
    assert not np.array_equal(a.stiffness, c.stiffness)
    assert len(a.take([0, 0, 5])) == 3 and a.take([5]).mass[0] == a.mass[5]


def test_distributions_match_the_documented_table():
    """Medians and ranges of a large population are those of the module's table."""
    s = sample_subjects(3000, seed=0)
    assert np.median(s.stiffness) == pytest.approx(300.0, rel=0.05)
    assert np.median(s.mass) == pytest.approx(1.0, rel=0.05)
    np.testing.assert_allclose(s.damping, 0.05 * s.stiffness)
    assert np.mean(s.delay) == pytest.approx(0.150, abs=0.003)
    assert s.delay.min() >= 0.09 and s.delay.max() <= 0.21
    assert np.median(s.tremor_amplitude) == pytest.approx(60e-6, rel=0.06)
    assert 8.0 <= s.tremor_frequency.min() and s.tremor_frequency.max() <= 12.0
    assert np.median(s.speed) == pytest.approx(0.015, rel=0.05)
    assert s.stiffness.min() >= 300 / 2.5 and s.stiffness.max() <= 300 * 2.5
    f1, f10 = s.practice_factor(1), s.practice_factor(10)
    assert np.all(f1 > f10) and np.all(f10 > 1.0)
    np.testing.assert_allclose(f1, 1 + s.novice_excess)


def test_minimum_jerk_profile():
    u = np.linspace(0, 1, 1001)
    g, dg = minimum_jerk(u)
    assert g[0] == 0 and g[-1] == pytest.approx(1.0) and g[500] == pytest.approx(0.5)
    np.testing.assert_allclose(np.gradient(g, u), dg, atol=2e-3)
    assert dg[0] == 0 and dg[-1] == 0 and dg.max() == pytest.approx(1.875)
    dt = 0.001
    p, v = straight_plan(
        np.zeros((1, 3)), np.array([[0.03, 0, 0]]), np.array([0.6]), np.array([0.3])
    )
    np.testing.assert_allclose(p, [[0.015, 0, 0]])
    assert v[0, 0] == pytest.approx(1.875 * 0.03 / 0.6)
    p2, _ = straight_plan(
        np.zeros((1, 3)), np.array([[0.03, 0, 0]]), np.array([0.6]), np.array([0.3 + dt])
    )
    assert (p2[0, 0] - p[0, 0]) / dt == pytest.approx(v[0, 0], rel=1e-4)


def test_path_plan_strokes_stop_at_the_knots():
    path = Polyline([[0, 0, 0], [0.03, 0, 0], [0.03, 0.02, 0]])
    knots = np.array([0.0, 0.03, 0.05])
    T = stroke_durations(np.diff(knots), np.array([0.01, 0.02]))
    np.testing.assert_allclose(T, [[3.0, 2.0], [1.5, 1.0]])
    t = np.array([3.0, 1.5])  # each trial at its first knot
    p, v, s = path_plan(path, knots, T, t)
    np.testing.assert_allclose(p, [[0.03, 0, 0]] * 2, atol=1e-12)
    np.testing.assert_allclose(v, 0.0, atol=1e-12)
    p, v, s = path_plan(path, knots, T, np.array([100.0, -1.0]))
    np.testing.assert_allclose(p, [[0.03, 0.02, 0], [0, 0, 0]], atol=1e-12)
    ts = np.arange(0, 5.0, 0.001)
    traj = np.stack([path_plan(path, knots, T[:1], np.array([tk]))[0][0] for tk in ts[::50]])
    assert np.max(np.linalg.norm(np.diff(traj, axis=0), axis=1)) < 0.05 * 1.875 * 0.01 * 1.01


def test_a_profile_changes_its_medians_draws_only():
    from davinci_sim.operators.params import NOVICE, Profile, sample_subjects

    base = sample_subjects(6, seed=4)
    same = sample_subjects(6, seed=4, profile=NOVICE)
    fitted = sample_subjects(6, seed=4, profile=Profile(noise_median=2 * NOVICE.noise_median,
                                                        speed_median=0.0075))  # fmt: skip
    for name in base.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(base, name), getattr(same, name))
        if name == "noise":  # (the same standard normal draws, the median scaled)
            np.testing.assert_allclose(fitted.noise, 2 * base.noise, rtol=1e-12)
        elif name == "speed":
            np.testing.assert_allclose(fitted.speed, base.speed / 2, rtol=1e-12)
        else:
            np.testing.assert_array_equal(getattr(fitted, name), getattr(base, name))
    faster = sample_subjects(6, seed=4, profile=Profile(exponent_range=(0.4, 1.2)))
    np.testing.assert_allclose(faster.learning_exponent, 2 * base.learning_exponent, rtol=1e-12)
    assert np.all((faster.learning_exponent >= 0.4) & (faster.learning_exponent <= 1.2))
    with pytest.raises(ValueError, match="exponent_range"):
        Profile(exponent_range=(0.6, 0.2))


def test_the_noise_carries_its_share_of_the_novice_excess():
    from davinci_sim.operators.params import Profile, sample_subjects

    table = sample_subjects(5, seed=1)
    f = table.practice_factor(1)
    np.testing.assert_array_equal(table.noise_factor(f), f)  # (the table: the whole factor)
    half = sample_subjects(5, seed=1, profile=Profile(noise_learning=0.5))
    np.testing.assert_allclose(half.noise_factor(f), 1 + 0.5 * table.novice_excess, rtol=1e-12)
    flat = sample_subjects(5, seed=1, profile=Profile(noise_learning=0.0))
    np.testing.assert_array_equal(flat.noise_factor(flat.practice_factor(3)), 1.0)
    with pytest.raises(ValueError, match="noise_learning"):
        Profile(noise_learning=1.5)


def test_the_fitted_population_is_the_table_with_its_profile():
    from davinci_sim.operators.params import ROTA2023, sample_population, sample_subjects

    fitted = sample_population("rota2023", 4, seed=2)
    same = sample_subjects(4, seed=2, profile=ROTA2023)
    for name in fitted.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(fitted, name), getattr(same, name))
    # (noisier than the table's, a larger novice excess, noise learning less than speed)
    assert ROTA2023.noise_median > 0.23 and ROTA2023.excess_median > 1
    assert 0 < ROTA2023.noise_learning < 1


def test_a_trials_pace_is_its_own_lognormal_draw_and_none_in_the_table():
    from davinci_sim.operators.params import Profile, sample_subjects, trial_pace

    keys = [(5, i, 0, j) for i in range(40) for j in range(1, 101)]
    np.testing.assert_array_equal(trial_pace(1.0, keys), 1.0)  # (the table: exactly none)
    pace = trial_pace(1.3, keys)
    assert np.array_equal(pace, trial_pace(np.full(len(keys), 1.3), keys))  # (its key's)
    inside = pace[(pace > 1.3**-3) & (pace < 1.3**3)]  # (the rest clipped at ±3 sd)
    assert len(np.unique(inside)) == len(inside) > 0.99 * len(keys)  # (a draw per trial)
    assert np.isclose(pace.min(), 1.3**-3, rtol=1e-12) and np.isclose(pace.max(), 1.3**3)
    # lognormal ×/÷ 1.3: the SD of its log is log 1.3 (4,000 draws: within 4 %)
    assert abs(np.log(pace).std() / np.log(1.3) - 1.0) < 0.04
    assert abs(np.log(pace).mean()) < 0.01
    assert np.all(sample_subjects(3, seed=1).pace_spread == 1.0)
    assert np.all(sample_subjects(3, seed=1, profile=Profile(pace_spread=1.2)).pace_spread == 1.2)
    with pytest.raises(ValueError, match="pace_spread"):
        Profile(pace_spread=0.9)
