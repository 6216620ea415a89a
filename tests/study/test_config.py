"""Study configuration, counterbalancing and the plan of trials."""

import pytest

from davinci_sim.study import (
    TABLE_I,
    StudyConfig,
    StudyError,
    condition_order,
    parse_conditions,
    plan_trials,
    williams_row,
)


def test_defaults_are_the_seed_study():
    c = StudyConfig()
    assert TABLE_I == ((0, 0), (20, 2), (40, 5), (60, 8))
    # The seed_path task's conditions: Table I, the seed's viscous law as printed.
    assert [(e["type"], e["B"], e["G_max"], e["transition"]) for e in c.conditions] == [
        ("viscous", b, g, 0.0) for b, g in TABLE_I
    ]
    assert [e["name"] for e in c.conditions] == ["B=0", "B=20", "B=40", "B=60"]
    assert (c.n_subjects, c.n_repetitions, c.n_trials) == (10, 10, 400)


def test_williams_square_is_latin_and_carry_over_balanced():
    n = 4
    rows = [williams_row(r, n) for r in range(n)]
    for r in rows:
        assert sorted(r) == list(range(n))
    for col in zip(*rows, strict=True):
        assert sorted(col) == list(range(n))
    follows = {(a, b): 0 for a in range(n) for b in range(n) if a != b}
    for r in rows:
        for a, b in zip(r, r[1:], strict=False):
            follows[(a, b)] += 1
    assert set(follows.values()) == {1}


def test_plan_practice_carries_across_conditions():
    cfg = StudyConfig(n_subjects=3, n_repetitions=2)
    specs = plan_trials(cfg)
    assert len(specs) == cfg.n_trials == 24
    s1 = [s for s in specs if s.subject == 1]
    assert [s.condition for s in s1[::2]] == condition_order(cfg, 1) == williams_row(1, 4)
    assert [s.practice for s in s1] == list(range(1, 9))
    assert len({s.key for s in specs}) == len(specs)
    fixed = StudyConfig(n_subjects=2, order="fixed")
    assert condition_order(fixed, 1) == [0, 1, 2, 3]


def test_practice_before_the_study_starts_the_count_there():
    """Subjects who trained before the study (Enayati et al.'s 23 min): the practice count
    of their first trial is prior_practice + 1, and the trainee's practice factor is that
    of a practised subject (lower than a first trial's)."""
    from davinci_sim.operators.params import sample_population

    cfg = StudyConfig(n_subjects=2, n_repetitions=2, prior_practice=40)
    s1 = [s for s in plan_trials(cfg) if s.subject == 1]
    assert [s.practice for s in s1] == list(range(41, 49))
    params = sample_population("trainee", 1)
    assert params.practice_factor(41)[0] < params.practice_factor(1)[0]
    for bad in (-1, 1.5, True, "40"):
        with pytest.raises(StudyError, match="prior_practice"):
            StudyConfig(prior_practice=bad)


def test_bad_configs_fail_early():
    assert parse_conditions("0:0, 20:2") == ((0, 0), (20, 2))
    with pytest.raises(StudyError, match="B:G_max"):
        parse_conditions("0,20")
    with pytest.raises(StudyError, match="backends"):
        StudyConfig(backend="dask")
    with pytest.raises(StudyError, match="orders"):
        StudyConfig(order="random")
    with pytest.raises(StudyError):
        StudyConfig(n_subjects=0)
