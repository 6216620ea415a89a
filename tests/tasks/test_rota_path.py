"""Rota's dVRK-console Path task as a task file (``scripts/rota_path_task.py``): their
trajectory's length and extent, their scale and fixture, the torus carried in the jaws and
the wrist's turns, reachable and in view here."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from drawn import drawn_visual_only

from davinci_sim.haptics.viscous_elastic import ViscousElasticGuidance
from davinci_sim.tasks import load_task
from davinci_sim.tasks.check import check_task
from davinci_sim.tasks.task import PathTask


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


def test_every_point_is_reachable_and_in_view_with_the_wrist_turned(task):
    checks = check_task(task)
    # the 80 points, then the 11 knots of the wrist's turns (reached turned)
    assert len(checks) == 91 and all(c.ok for c in checks)
    np.testing.assert_allclose(
        [c.p_task for c in checks[80:]],
        task.path.point_at(np.linspace(0, 1, 11) * task.path.length),
    )
    assert all(c.turned_deg is None for c in checks[:80])
    turned = np.degrees(np.linalg.norm(task.carry.turn, axis=1))
    np.testing.assert_allclose([c.turned_deg for c in checks[80:]], turned)


def test_a_turn_the_wrist_cannot_make_fails_the_check_at_its_knot(task):
    turn = np.array(task.carry.turn)
    turn[5] = [0.0, 2.6, 0.0]  # 150 deg about the world's y: beyond the wrist's joints
    data = task.to_dict()
    data["carry"] = {**data["carry"], "turn": turn.tolist()}
    checks = check_task(PathTask.from_dict(data))
    assert [c.index for c in checks if not c.reachable] == [86]
    assert "inverse_kinematics" in checks[85].why


def test_their_torus_and_their_control_groups_wrist_turns(task):
    carry = task.carry
    # their scene's torus: tube 0.675 mm, centre line 6.1-6.7 mm (scripts/rota_path_task.py)
    assert (carry.torus_radius, carry.tube_radius) == (0.0064, 0.000675)
    assert carry.progress == tuple(np.round(np.linspace(0, 1, 11), 12))
    angles = np.degrees(np.linalg.norm(carry.turn, axis=1))
    # no turn at the start; the mean turn grows to ~30 deg by the end
    # (docs/study/rota_path/wrist.json)
    assert angles[0] < 1.0 and 25.0 < angles[-1] < 40.0
    # the turn is about the vertical and the horizontal across the path, not about the path
    assert np.abs(carry.turn[:, 0]).max() < 0.01


def test_the_torus_rides_in_the_jaws_visual_only(task):
    model, torus = drawn_visual_only(task, "task/carried_torus")
    assert len(torus) == 20
    wrist = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "PSM1/wrist_yaw")
    assert all(model.body_parentid[model.geom_bodyid[i]] == wrist for i in torus)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    site = model.site("PSM1/tip").id
    R_tip, p_tip = data.site_xmat[site].reshape(3, 3), data.site_xpos[site]
    centres = data.geom_xpos[torus] - p_tip
    # the ring's plane holds the jaws (tip z) and the hinge (tip x): nothing along y
    np.testing.assert_allclose(centres @ R_tip[:, 1], 0.0, atol=1e-9)
    # its nearest point is the gripped tube, grasp_depth ahead of the tip point
    along = centres @ R_tip[:, 2]
    assert along.min() == pytest.approx(task.carry.grasp_depth, abs=0.5e-3)
    assert along.max() == pytest.approx(task.carry.grasp_depth + 2 * 0.0064, abs=0.5e-3)


@pytest.mark.parametrize("numbered", [[1, 79], [0, 40], [0, 50, 20, 79], [0, 1.5, 79]])
def test_numbered_points_must_be_increasing_indices_from_first_to_last(task, numbered):
    from davinci_sim.tasks.base import TaskError
    from davinci_sim.tasks.task import PathTask

    data = {**task.to_dict(), "numbered": numbered}
    with pytest.raises(TaskError, match="numbered"):
        PathTask.from_dict(data)
    assert PathTask.from_dict({**data, "numbered": [0, 30, 79]}).markers.shape == (3, 3)
