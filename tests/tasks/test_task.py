"""Task files, and the seed task's geometry: 90° turns, reachable by PSM1, in view."""

from __future__ import annotations

import json

import numpy as np
import pytest

from davinci_sim.haptics.combine import FixtureSum
from davinci_sim.haptics.viscous import ViscousGuidance
from davinci_sim.kinematics.arms import load_arm
from davinci_sim.kinematics.ik import inverse_kinematics
from davinci_sim.sim.simulation import Simulation
from davinci_sim.tasks import PathTask, TaskError, available_tasks, load_task, save_task


@pytest.fixture(scope="module")
def task() -> PathTask:
    return load_task("seed_path")


@pytest.fixture(scope="module")
def sim() -> Simulation:
    return Simulation("psm1_ecm_mtmr", keyframe="surgical")


def test_seed_task_shape(task):
    """Five points, three 90° turns at points 2-4, runs along all three axes, a few cm each,
    the whole within 8 cm; the teleop scale 0.6 and Table I's four conditions."""
    assert "seed_path" in available_tasks()
    w = task.waypoints
    assert w.shape == (5, 3)
    runs = np.diff(w, axis=0)
    lengths = np.linalg.norm(runs, axis=1)
    assert np.all((lengths >= 0.02) & (lengths <= 0.04))
    dirs = runs / lengths[:, None]
    np.testing.assert_allclose(np.einsum("ij,ij->i", dirs[:-1], dirs[1:]), 0.0, atol=1e-12)
    axes = {int(np.argmax(np.abs(d))) for d in dirs}
    assert axes == {0, 1, 2}
    assert np.all(np.ptp(w, axis=0) <= 0.08)
    assert task.teleop.scale == 0.6 and task.teleop.psm == "PSM1"
    table = [(c["B"], c["G_max"]) for c in task.conditions]
    assert table == [(0, 0), (20, 2), (40, 5), (60, 8)]
    assert task.path.length == pytest.approx(np.sum(lengths), abs=0.01)


def test_seed_task_reachable_by_psm1(task, sim):
    """PSM1's closed-form IK reaches every point along the path (every 2 mm), keeping the
    tool's orientation of the surgical keyframe, within the joint limits."""
    kin = load_arm("PSM1")
    T_cart_camera = sim.T_cart_camera()
    T_camera_rcm, _ = sim.default_base_frame("PSM1")
    T_cart_rcm = T_cart_camera @ T_camera_rcm
    R_cart_tip = (T_cart_camera @ sim.arms["PSM1"].measured_cp().T)[:3, :3]
    q = sim.arms["PSM1"].measured_jp()
    s = np.arange(0.0, task.path.length, 0.002)
    for p in task.path.point_at(s):
        T_cart_tip = np.eye(4)
        T_cart_tip[:3, :3], T_cart_tip[:3, 3] = R_cart_tip, p
        result = inverse_kinematics(kin, np.linalg.inv(T_cart_rcm) @ T_cart_tip, q)
        assert result.success, result.message
        q = result.q
        assert kin.chain.qmin[2] + 0.02 < q[2] < kin.chain.qmax[2] - 0.02  # insertion margin


def test_seed_task_in_the_endoscope_view(task, sim):
    """Projected with the endoscope's pinhole (45° vertical fovy, 640x480), the whole path
    lies inside the image with a 15 % margin, 20-30 cm in front of the camera."""
    cam = task.path_in_camera(sim.T_cart_camera())
    p = cam.vertices
    assert np.all((p[:, 2] > 0.2) & (p[:, 2] < 0.3))
    f = 240 / np.tan(np.radians(45) / 2)
    u = 320 - f * p[:, 0] / p[:, 2]  # camera x points to the image's left
    v = 240 - f * p[:, 1] / p[:, 2]  # camera y points up
    assert np.all((u > 0.15 * 640) & (u < 0.85 * 640))
    assert np.all((v > 0.15 * 480) & (v < 0.85 * 480))


def test_yaml_and_json_roundtrip(task, tmp_path):
    for name in ("t.yaml", "t.json"):
        save_task(task, tmp_path / name)
        again = load_task(tmp_path / name)
        np.testing.assert_array_equal(again.waypoints, task.waypoints)
        assert again.to_dict() == task.to_dict()
    data = json.loads((tmp_path / "t.json").read_text())
    assert data["fixture"] == {"type": "viscous", "B": 40.0, "G_max": 5.0}


def test_fixtures_from_the_task(task):
    f = task.fixture()
    assert isinstance(f, FixtureSum) and isinstance(f.fixtures[0], ViscousGuidance)
    assert (f.fixtures[0].B, f.fixtures[0].G_max) == (40.0, 5.0)
    g = task.fixture("B=60").fixtures[0]
    assert (g.B, g.G_max) == (60.0, 8.0)
    assert task.fixture({"type": "none"}).fixtures == ()
    p = task.path.point_at(0.01) + [0, 0, 0.004]
    assert np.linalg.norm(task.fixture().force(p, [0, 0, 0.02])) > 0


def test_user_task_with_walls_in_camera_frame(tmp_path):
    text = """
name: mine
frame: camera
waypoints: [[0, 0, 0.25], [0.02, 0, 0.25], [0.02, 0.02, 0.25]]
corner_radius: 0.004
fixture: {type: spring, stiffness: 200, damping: 5, max_force: 3}
walls:
  - {type: plane, point: [0, 0, 0.26], normal: [0, 0, -1], stiffness: 300}
"""
    (tmp_path / "mine.yaml").write_text(text)
    t = load_task(tmp_path / "mine.yaml")
    assert t.frame == "camera" and len(t.fixture().fixtures) == 2
    assert t.path_in_camera(np.diag([1.0, -1, -1, 1])) is t.path
    f = t.fixture().force([0.01, 0.0, 0.262], [0, 0, 0])
    assert f[2] < -0.5  # the wall pushes back towards the camera


@pytest.mark.parametrize(
    ("patch", "message"),
    [
        ({"colour": "red"}, "unknown keys"),
        ({"frame": "table"}, "unknown frame"),
        ({"fixture": {"type": "magnetic"}}, "unknown fixture type"),
        ({"fixture": {"type": "viscous", "B": 20, "Gmax": 2}}, "unknown keys"),
        ({"fixture": {"type": "viscous", "B": -20, "G_max": 2}}, "must be"),
        ({"conditions": [{"type": "viscous", "B": 1, "G_max": 1}]}, "name"),
        ({"corner_radius": 0.05}, "too large"),
        ({"teleop": {"scale": 2.0}}, "scale"),
        ({"walls": [{"type": "cube"}]}, "wall type"),
    ],
)
def test_invalid_task_files_say_what_is_wrong(task, patch, message):
    data = task.to_dict() | patch
    with pytest.raises(TaskError, match=message):
        PathTask.from_dict(data)


def test_unknown_task_lists_the_shipped_ones():
    with pytest.raises(TaskError, match="seed_path"):
        load_task("no_such_task")


def test_the_panel_names_the_next_point_of_the_path_while_a_repetition_runs(task):
    """The console's "to do" while the seed's path runs: the next numbered point past the
    furthest the tool has come (a point within the finish's tolerance counts as reached);
    nothing before the repetition starts or once it is over."""
    from davinci_sim.tasks.state import Phase, TaskState

    arcs = task.marker_arc_lengths  # (points 1-5 along the path, m)

    def at(phase, furthest):
        return task.progress(TaskState(np.array([int(phase)], dtype=np.int8), np.array([0.0]),
                                       np.array([np.nan]), np.array([furthest])))  # fmt: skip

    assert len(arcs) == 5
    assert at(Phase.IDLE, 0.0) == at(Phase.READY, 0.0) == at(Phase.FINISHED, arcs[-1]) == ""
    assert at(Phase.RUNNING, 0.0) == "follow the path to point 2 of 5"
    assert (
        at(Phase.RUNNING, arcs[1] - 2 * task.finish_tolerance) == "follow the path to point 2 of 5"
    )
    assert (
        at(Phase.RUNNING, arcs[1] - 0.5 * task.finish_tolerance)
        == "follow the path to point 3 of 5"
    )
    assert at(Phase.RUNNING, arcs[3] + 0.001) == "follow the path to point 5 of 5"
    assert at(Phase.RUNNING, arcs[-1]) == "follow the path to point 5 of 5"
