"""The study's time estimate as the terminal shows it (:mod:`davinci_sim.study.estimate`)."""

from __future__ import annotations

import pytest

from davinci_sim.study.estimate import StudyEstimate


@pytest.mark.parametrize(("wall_s", "shown"), [(0.0342, "0.034"), (3.44, "3.4"), (123.4, "123")])
def test_the_line_gives_two_significant_digits_below_ten_seconds(wall_s, shown):
    estimate = StudyEstimate(3, 2, 2e-5, 1e-5, 1.5, wall_s, 0.4)
    assert f"estimate: 3 trials on 2 worker processes, about {shown} s (" in estimate.line()
