"""Adaptive guidance's update rules (issue 12, item 4) on constructed histories, and the
fixture kind that runs them (the seed's viscous law with the current B)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics.adaptive import (
    AdaptiveRule,
    B_at,
    B_schedule,
    assist_as_needed_B,
    fading_B,
    next_B,
)
from davinci_sim.haptics.kinds import build_fixture, describe_fixture, resolve_fixture
from davinci_sim.haptics.viscous import ViscousGuidance
from davinci_sim.tasks import TaskError, load_task

AAN = AdaptiveRule(B0=20.0, target=0.002, gain=5000.0, max_step=4.0, B_min=5.0, B_max=30.0,
                   window=2)  # fmt: skip


def test_assist_as_needed_rises_with_error_and_falls_after_good_repetitions():
    # ē = 2.4 mm over the last two: 5000·0.4e-3 = 2 N·s/m up (below the step limit).
    assert assist_as_needed_B(20.0, [0.0024, 0.0024], AAN) == pytest.approx(22.0)
    # Good repetitions (1.6 mm, below the 2 mm target): 2 down.
    assert assist_as_needed_B(20.0, [0.0016, 0.0016], AAN) == pytest.approx(18.0)
    # Only the last `window` errors count: an old bad repetition is forgotten.
    assert assist_as_needed_B(20.0, [0.05, 0.0016, 0.0016], AAN) == pytest.approx(18.0)
    # On target: no change.
    assert assist_as_needed_B(20.0, [0.002, 0.002], AAN) == pytest.approx(20.0)


def test_assist_as_needed_step_limit_and_bounds():
    assert assist_as_needed_B(20.0, [0.1], AAN) == pytest.approx(24.0)  # +4 at most
    assert assist_as_needed_B(20.0, [0.0], AAN) == pytest.approx(16.0)  # -4 at most
    assert assist_as_needed_B(29.0, [0.1], AAN) == 30.0  # B_max
    assert assist_as_needed_B(6.0, [0.0], AAN) == 5.0  # B_min
    # A long run of bad repetitions climbs by the step limit to B_max and stays there.
    Bs = B_schedule([0.1] * 6, AAN)
    assert Bs == pytest.approx([20.0, 24.0, 28.0, 30.0, 30.0, 30.0, 30.0])
    assert np.all(np.abs(np.diff(B_schedule(list(np.linspace(0, 0.01, 9)), AAN))) <= 4.0)


def test_assist_as_needed_ignores_repetitions_without_an_error():
    assert assist_as_needed_B(20.0, [], AAN) == 20.0
    assert assist_as_needed_B(20.0, [math.nan], AAN) == 20.0
    assert assist_as_needed_B(20.0, [math.nan, 0.0024], AAN) == pytest.approx(22.0)


def test_fading_reaches_zero_at_the_declared_repetition():
    rule = AdaptiveRule(mode="fading", B0=40.0, zero_at=5)
    Bs = [fading_B(j, rule) for j in range(1, 8)]
    assert Bs == pytest.approx([40.0, 30.0, 20.0, 10.0, 0.0, 0.0, 0.0])
    assert Bs[3] > 0  # not before
    # The errors do not matter, only how many repetitions came before.
    assert B_at(3, [0.5, 0.0], rule) == B_at(3, [math.nan, math.nan], rule) == 20.0
    assert next_B(40.0, [0.1, 0.1], rule) == 20.0
    with pytest.raises(ValueError):
        fading_B(0, rule)


def test_the_live_update_and_the_study_schedule_agree():
    """next_B applied after each repetition (the live session) gives B_schedule (the study)."""
    errors = [0.003, 0.0025, 0.001, 0.0005, 0.004, math.nan, 0.002]
    B, live = AAN.B0, [AAN.B0]
    for k in range(len(errors)):
        B = next_B(B, errors[: k + 1], AAN)
        live.append(B)
    assert live == B_schedule(errors, AAN)
    assert B_at(4, errors[:3], AAN) == live[3]
    with pytest.raises(ValueError):
        B_at(4, errors[:2], AAN)


@pytest.mark.parametrize(
    "bad",
    [
        {"mode": "sometimes"},
        {"B_min": 10.0, "B_max": 5.0},
        {"B0": 70.0},  # above B_max
        {"window": 0},
        {"window": 1.5},
        {"zero_at": 1},
        {"gain": -1.0},
        {"target": math.inf},
    ],
)
def test_bad_rules_are_refused(bad):
    with pytest.raises(ValueError):
        AdaptiveRule(**bad)


def test_the_fixture_kind_is_the_viscous_law_with_the_current_B():
    path = Polyline([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0]])
    entry = {"type": "adaptive", "mode": "assist_as_needed", "B0": 30, "G_max": 4}
    f = build_fixture(entry, path)
    assert isinstance(f, ViscousGuidance) and (f.B, f.G_max) == (30.0, 4.0)  # B0 at first
    f = build_fixture({**entry, "B": 12.5}, path)
    assert (f.B, f.G_max, f.transition) == (12.5, 4.0, 0.0)
    p, v = np.array([[0.01, 0.002, 0.0]]), np.array([[0.0, 0.05, 0.0]])
    want = ViscousGuidance(path, 12.5, 4.0).force(p, v)
    np.testing.assert_array_equal(f.force(p, v), want)
    resolved = resolve_fixture(entry)
    assert resolved["target"] == 0.0015 and resolved["metric"] == "deviation_error"
    assert "B" not in resolved  # the B that runs is set by whoever runs it
    assert "now B=12.5" in describe_fixture({**entry, "B": 12.5})
    assert "fading" in describe_fixture({"type": "adaptive", "mode": "fading"})
    with pytest.raises(ValueError):
        build_fixture({**entry, "speed": 1.0}, path)


def test_a_path_task_offers_it_and_refuses_a_bad_entry():
    task = load_task("seed_path")
    task.check_fixture({"type": "adaptive", "mode": "fading", "B0": 40, "zero_at": 6})
    with pytest.raises(TaskError):
        task.check_fixture({"type": "adaptive", "mode": "never"})
    with pytest.raises(TaskError):
        task.check_fixture({"type": "adaptive", "window": 0})
