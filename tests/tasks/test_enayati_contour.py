"""The stand-in for Enayati et al. 2016's static task (``scripts/enayati_contour_task.py``):
their motion scale, their two cases (UC, VR with their B, F and D_m), reachable and in view."""

from __future__ import annotations

import numpy as np
import pytest

from davinci_sim.haptics.viscous import ViscousGuidance, viscous_guidance
from davinci_sim.tasks import load_task
from davinci_sim.tasks.check import check_task


@pytest.fixture(scope="module")
def task():
    return load_task("enayati_contour")


def test_half_a_circle_around_the_mass(task):
    points = np.asarray(task.waypoints)
    centre = np.array([0.080, 1.185, 0.795])
    np.testing.assert_allclose(np.linalg.norm(points - centre, axis=1), 0.015, atol=1e-6)
    assert task.path.length == pytest.approx(np.pi * 0.015, abs=3e-5)  # chords of 3 degrees
    np.testing.assert_allclose(task.marker_arc_lengths, [0.0, task.path.length])


def test_their_scale_and_their_two_cases(task):
    assert task.teleop.scale == pytest.approx(1 / 3, abs=1e-6)
    assert [c["name"] for c in task.conditions] == ["UC", "VR"]
    assert task.conditions[0]["type"] == "none"
    vr = task.guidance(task.conditions[1])
    assert isinstance(vr, ViscousGuidance)
    assert (vr.B, vr.G_max, vr.transition) == (80.0, 5.0, 0.002)


def test_their_law_below_the_cap_is_enayatis_downscaled_viscosity(task):
    """Within D_m of the path Enayati scale B by ‖d‖/D_m before the cap; the ramp scales
    the force: the same force while B'·‖v‖ stays under F (checked against their form)."""
    vr = task.conditions[1]
    rng = np.random.default_rng(3)
    for _ in range(200):
        d = rng.uniform(0.0002, 0.004) * _unit(rng)
        v = rng.uniform(0.001, 0.06) * _unit(rng)  # (B·‖v‖ <= 4.8 N: under the cap)
        ours = viscous_guidance(v, d, B=vr["B"], G_max=vr["G_max"], transition=vr["transition"])
        B_prime = 80.0 * min(1.0, np.linalg.norm(d) / 0.002)
        theirs = viscous_guidance(v, d, B=B_prime, G_max=5.0, transition=0.0)
        np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=1e-15)


def test_every_point_is_reachable_and_in_view(task):
    checks = check_task(task)
    assert len(checks) == 61 and all(c.ok for c in checks)


def _unit(rng):
    x = rng.normal(size=3)
    return x / np.linalg.norm(x)
