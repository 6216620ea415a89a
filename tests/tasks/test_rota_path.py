"""Rota's dVRK-console Path task as a task file (``scripts/rota_path_task.py``): their
trajectory's length and extent, their scale and fixture, reachable and in view here."""

from __future__ import annotations

import numpy as np
import pytest

from davinci_sim.haptics.viscous_elastic import ViscousElasticGuidance
from davinci_sim.tasks import load_task
from davinci_sim.tasks.check import check_task


@pytest.fixture(scope="module")
def task():
    return load_task("rota_path")


def test_their_trajectory_rigidly_placed(task):
    points = np.asarray(task.waypoints)
    assert len(points) == 80
    # 115.81 mm as they logged it; 80 of its 2,600 vertices keep it to 20 um
    assert task.path.length == pytest.approx(0.1158, abs=1e-4)
    extent = points.max(axis=0) - points.min(axis=0)  # (turned 90 deg about z: x, y swap)
    np.testing.assert_allclose(extent, [0.07109, 0.01125, 0.02764], atol=2e-5)
    assert points[-1, 2] - points[0, 2] > 0.02  # it rises from start to end
    # numbered: its ends only (two markers, one stroke for the trainee, no targets between)
    np.testing.assert_allclose(task.marker_arc_lengths, [0.0, task.path.length])
    assert len(task.view_points) == 80


def test_their_scale_fixture_and_the_assisted_groups_days(task):
    assert task.teleop.scale == 0.5
    fixture = task.guidance(task.fixture_spec)
    assert isinstance(fixture, ViscousElasticGuidance)
    assert (fixture.B, fixture.elastic_gain, fixture.max_force) == (15.0, 0.8, 3.0)
    assert (fixture.threshold, fixture.half, fixture.slope) == (0.002, 0.002, 500.0)
    names = [c["name"] for c in task.conditions]
    assert names == ["control", "assisted x1", "assisted x0.75", "assisted x0.5",
                     "assisted x0.25"]  # fmt: skip
    assert [c.get("assistance") for c in task.conditions[1:]] == [1.0, 0.75, 0.5, 0.25]


def test_every_point_is_reachable_and_in_view(task):
    checks = check_task(task)
    assert len(checks) == 80 and all(c.ok for c in checks)


@pytest.mark.parametrize("numbered", [[1, 79], [0, 40], [0, 50, 20, 79], [0, 1.5, 79]])
def test_numbered_points_must_be_increasing_indices_from_first_to_last(task, numbered):
    from davinci_sim.tasks.base import TaskError
    from davinci_sim.tasks.task import PathTask

    data = {**task.to_dict(), "numbered": numbered}
    with pytest.raises(TaskError, match="numbered"):
        PathTask.from_dict(data)
    assert PathTask.from_dict({**data, "numbered": [0, 30, 79]}).markers.shape == (3, 3)
