"""Rota's fixture (viscous + logistic elastic, the sum capped, then the assistance factor) on
constructed cases worked out by hand from the law's description, and its identities."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics.kinds import build_fixture, describe_fixture
from davinci_sim.haptics.viscous import viscous_guidance
from davinci_sim.haptics.viscous_elastic import (
    ViscousElasticGuidance,
    elastic_share,
    viscous_elastic_guidance,
)

# Their values (training.md §4): B 15 N·s/m, elastic 0.8 N, threshold and half 2 mm, slope 500.
ROTA = {"B": 15.0, "elastic_gain": 0.8, "threshold": 0.002, "half": 0.002, "slope": 500.0,
        "max_force": 3.0}  # fmt: skip
X, Y = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])


def force(v, phi, **extra):
    return viscous_elastic_guidance(np.array(v, float), np.array(phi, float), **{**ROTA, **extra})


def test_the_logistic_is_half_at_threshold_plus_half_and_steep_as_their_slope():
    assert elastic_share(0.004, threshold=0.002, half=0.002, slope=500) == pytest.approx(0.5)
    # exp(-(500 / 0.2)(d - 0.004)): at 6 mm exp(-5), on the path exp(10)
    assert elastic_share(0.006, threshold=0.002, half=0.002, slope=500) == pytest.approx(
        1 / (1 + math.exp(-5))
    )
    assert elastic_share(0.0, threshold=0.002, half=0.002, slope=500) == pytest.approx(
        1 / (1 + math.exp(10))
    )
    # their floor on the slope: at least 1 / half
    d = np.linspace(0, 0.01, 11)
    floor = elastic_share(d, threshold=0.002, half=0.002, slope=0.0)
    np.testing.assert_allclose(floor, elastic_share(d, threshold=0.002, half=0.002, slope=500))
    assert np.all(np.isfinite(elastic_share([-1e3, 1e3], threshold=0, half=1e-3, slope=1e6)))


def test_a_static_tool_off_the_path_feels_the_elastic_pull_only():
    f = force([0, 0, 0], 0.004 * X)  # 4 mm away, still: 0.8 N x 0.5 towards the path
    np.testing.assert_allclose(f, 0.4 * X, atol=1e-12)
    np.testing.assert_allclose(force([0, 0, 0], [0, 0, 0]), 0.0, atol=1e-15)


def test_moving_straight_away_gives_the_full_viscous_gain_along_the_deviation():
    f = force(-0.1 * X, 0.001 * X)  # 0.1 m/s away, 1 mm off: b = B, plus a small pull
    expected = 15.0 * 0.1 + 0.8 / (1 + math.exp(2500 * 0.003))
    np.testing.assert_allclose(f, expected * X, atol=1e-12)


def test_sideways_motion_turns_towards_the_path_and_the_sum_is_capped_then_scaled():
    # v perpendicular to phi: b = B / sqrt(2), direction rotated by 90 deg: phi's
    viscous = 15.0 / math.sqrt(2) * 0.2
    elastic = 0.8 / (1 + math.exp(-5))
    np.testing.assert_allclose(force(0.2 * Y, 0.006 * X), (viscous + elastic) * X, atol=1e-12)
    assert viscous + elastic < 3.0
    # faster: 3.18 + 0.79 N over the 3 N cap; the assistance factor after the cap
    np.testing.assert_allclose(force(0.3 * Y, 0.006 * X), 3.0 * X, atol=1e-12)
    np.testing.assert_allclose(force(0.3 * Y, 0.006 * X, assistance=0.25), 0.75 * X, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-0.3, 0.3), min_size=6, max_size=6), st.floats(0.0, 1.0))
def test_without_the_elastic_term_and_cap_it_is_the_seeds_law_uncapped(values, assistance):
    v, phi = np.array(values[:3]), 0.01 * np.array(values[3:])
    f = force(v, phi, elastic_gain=0.0, max_force=1e9, assistance=assistance)
    np.testing.assert_allclose(
        f, assistance * viscous_guidance(v, phi, B=15.0, G_max=math.inf), atol=1e-12
    )
    capped = force(v, phi, assistance=assistance)
    assert np.linalg.norm(capped) <= 3.0 * assistance + 1e-12


def test_a_batch_of_trials_each_with_its_assistance():
    v = np.array([0.3 * Y] * 4)
    phi = np.array([0.006 * X] * 4)
    a = np.array([1.0, 0.75, 0.5, 0.25])
    f = viscous_elastic_guidance(v, phi, **ROTA, assistance=a)
    np.testing.assert_allclose(np.linalg.norm(f, axis=1), 3.0 * a, atol=1e-12)


def test_the_kind_from_a_task_files_entry():
    path = Polyline(np.array([[0.0, 0, 0], [0.1, 0, 0]]))
    entry = {"type": "viscous_elastic", **{k: v for k, v in ROTA.items() if k != "max_force"}}
    fixture = build_fixture(entry, path)
    assert isinstance(fixture, ViscousElasticGuidance) and fixture.max_force == 3.0
    f = fixture.force(np.array([[0.05, 0.004, 0.0]]), np.zeros((1, 3)))
    np.testing.assert_allclose(f, [[0.0, -0.4, 0.0]], atol=1e-12)  # towards the path
    assert "viscous + elastic" in describe_fixture(entry)
    with pytest.raises(ValueError):
        ViscousElasticGuidance(path, **{**ROTA, "assistance": 1.5})
    with pytest.raises(ValueError):
        viscous_elastic_guidance(np.zeros(3), np.zeros(3), **ROTA, assistance=-0.1)
