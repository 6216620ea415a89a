"""What the page draws over the endoscope image: the projection of the left camera and the
path's depth cue, against independent computations."""

import math

import pytest


def test_path_guide_gives_the_closest_point_and_its_depth_against_an_independent_check():
    import numpy as np

    from davinci_sim.geometry.path import Polyline
    from davinci_sim.model.cameras import CameraConfig, project_left
    from davinci_sim.web.view import path_guide

    # A camera at (0, 0, 1) looking down -z of the world (its z axis = world -z, y = world y).
    T_world_camera = np.array([[-1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, 1.0], [0, 0, 0, 1]])
    path = Polyline(np.array([[-0.1, 0.0, 0.7], [0.1, 0.0, 0.7]]))  # 0.3 m from the camera
    tip_camera = np.array([0.02, 0.01, 0.25])  # 5 cm nearer than the path, off to the side
    guide = path_guide(tip_camera, T_world_camera, path, CameraConfig())
    tip_world = T_world_camera[:3, :3] @ tip_camera + T_world_camera[:3, 3]
    closest_world = np.array([tip_world[0], 0.0, 0.7])  # the straight path's foot point
    closest_camera = T_world_camera[:3, :3].T @ (closest_world - T_world_camera[:3, 3])
    assert guide["depth_mm"] == pytest.approx(50.0)  # the path is 5 cm deeper: push in
    assert guide["pixel"] == pytest.approx(list(project_left(closest_camera, CameraConfig())))
    assert guide["distance_mm"] == pytest.approx(1000 * np.hypot(0.01, 0.05))


def test_project_left_is_the_pinhole_of_the_left_camera():
    from davinci_sim.model.cameras import CameraConfig, project_left

    cam = CameraConfig()
    f = 240 / math.tan(math.radians(cam.fovy_deg) / 2)
    # On the left camera's axis (half a baseline towards +x): the image centre.
    assert project_left([cam.baseline_m / 2, 0, 0.2], cam) == pytest.approx((320, 240))
    # x is the image's left, y up (dvrk.md 1.6).
    u, v = project_left([cam.baseline_m / 2 + 0.01, 0.02, 0.2], cam)
    assert u == pytest.approx(320 - f * 0.05) and v == pytest.approx(240 - f * 0.1)
    assert project_left([0, 0, -0.1], cam) is None


def test_task_marks_put_an_exercises_targets_and_directions_in_the_camera_frame():
    """Needle targets (world) seen from a camera at (0, 0, 1) looking down: each target's
    camera-frame position and its stem's direction (unit) by the inverse transform, its
    pixel by the pinhole; the current target read from the panel's words."""
    import numpy as np

    from davinci_sim.model.cameras import CameraConfig, project_left
    from davinci_sim.tasks.needle_targeting import NeedleTargetingTask
    from davinci_sim.web.view import task_marks

    T_world_camera = np.array([[-1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, 1.0], [0, 0, 0, 1]])
    task = NeedleTargetingTask(
        "n", start=[0.0, 0.0, 0.8], targets=[[0.01, 0.02, 0.75], [0.0, -0.01, 0.78]],
        directions=[[0.0, 0.0, -2.0], [1.0, 0.0, -1.0]],
    )  # fmt: skip
    cam = CameraConfig()
    marks = task_marks(task, T_world_camera, cam, "touch target 2 of 2")
    assert marks["current"] == 1
    first, second = marks["targets"]
    assert first["label"] == "1"
    # World (x, y, z) -> camera (-x, y, 1 - z): the camera's x is the world's -x.
    assert first["p_camera"] == pytest.approx([-0.01, 0.02, 0.25])
    assert first["pixel"] == pytest.approx(list(project_left([-0.01, 0.02, 0.25], cam)))
    assert first["direction"] == pytest.approx([0.0, 0.0, 1.0])  # down = into the image
    assert second["direction"] == pytest.approx([-math.sqrt(0.5), 0.0, math.sqrt(0.5)])
    tail = np.array(second["p_camera"]) - 0.012 * np.array(second["direction"])
    assert second["shaft_pixel"] == pytest.approx(list(project_left(tail, cam)))
    assert task_marks(task, T_world_camera, cam, "")["current"] is None


def test_task_marks_of_a_wire_sample_it_every_2_mm_and_skip_the_seeds_path():
    import numpy as np

    from davinci_sim.model.cameras import CameraConfig
    from davinci_sim.tasks import load_task
    from davinci_sim.tasks.ring_walk import RingWalkTask
    from davinci_sim.web.view import task_marks

    T_world_camera = np.array([[-1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, 1.0], [0, 0, 0, 1]])
    wire = RingWalkTask("r", [[0.0, 0.0, 0.7], [0.02, 0.0, 0.7]], corner_radius=0.0)
    marks = task_marks(wire, T_world_camera, CameraConfig())
    p = np.array(marks["wire"]["p_camera"])
    assert len(p) == 11 and "targets" not in marks
    assert p[0] == pytest.approx([0.0, 0.0, 0.3]) and p[-1] == pytest.approx([-0.02, 0.0, 0.3])
    assert task_marks(load_task("seed_path"), T_world_camera, CameraConfig()) is None


def test_task_marks_number_the_peg_rings_and_give_the_needles_pose():
    import numpy as np

    from davinci_sim.model.cameras import CameraConfig
    from davinci_sim.tasks import load_task
    from davinci_sim.web.view import task_marks

    T_world_camera = np.array([[-1.0, 0, 0, 0.06], [0, 1, 0, 1.2], [0, 0, -1, 1.0], [0, 0, 0, 1]])
    centres = np.array([[0.10, 1.19, 0.80], [0.12, 1.17, 0.80], [0.12, 1.21, 0.80]])
    peg = task_marks(load_task("peg_transfer"), T_world_camera, CameraConfig(), objects=centres)
    assert [m["label"] for m in peg["rings"]] == ["1", "2", "3"]
    task = load_task("needle_pickup")
    needle = task_marks(task, T_world_camera, CameraConfig(), objects=centres[:1])
    assert "rings" not in needle  # (the needle's centre is off its wire)
    T_camera_world = np.linalg.inv(T_world_camera)
    top = T_camera_world[:3, :3] @ task.view_points[1] + T_camera_world[:3, 3]
    assert needle["needle"]["start"][1]["p_camera"] == pytest.approx(top)
    assert needle["needle"]["normal"] == pytest.approx([0.0, -1.0, 0.0])  # (x flipped: 0, −1)
    centre = T_camera_world[:3, :3] @ centres[0] + T_camera_world[:3, 3]
    assert needle["needle"]["centre"]["p_camera"] == pytest.approx(centre)
    assert "sutures" not in needle and "now" not in needle["needle"]
    # Where it is now, from its sampled frame: turned 90° about the world's z and moved.
    T_now = np.eye(4)
    T_now[:3, :3] = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]) @ task.T_world_start[:3, :3]
    T_now[:3, 3] = task.T_world_start[:3, 3] + [0.01, 0.0, 0.02]
    now = task_marks(task, T_world_camera, CameraConfig(), objects=centres[:1],
                     object_frame=T_now)["needle"]["now"]  # fmt: skip
    for mark, s in zip(now["ends"], (0.0, 0.5, 1.0), strict=True):
        p_world = T_now[:3, :3] @ task.needle.points(s) + T_now[:3, 3]
        assert mark["p_camera"] == pytest.approx(T_camera_world[:3, :3] @ p_world
                                                 + T_camera_world[:3, 3])  # fmt: skip
    assert now["normal"] == pytest.approx(T_camera_world[:3, :3] @ T_now[:3, 2])
    assert abs(np.dot(now["normal"], needle["needle"]["normal"])) < 1e-9  # (it turned)


def test_task_marks_give_the_suture_pairs_and_the_one_to_pass():
    import numpy as np

    from davinci_sim.model.cameras import CameraConfig
    from davinci_sim.tasks import load_task
    from davinci_sim.web.view import task_marks

    T_world_camera = np.array([[-1.0, 0, 0, 0.06], [0, 1, 0, 1.2], [0, 0, -1, 1.0], [0, 0, 0, 1]])
    task = load_task("running_suture")
    marks = task_marks(task, T_world_camera, CameraConfig(),
                       progress="enter the tissue at entry mark 3 of 4")  # fmt: skip
    assert [p["label"] for p in marks["sutures"]] == ["1", "2", "3", "4"]
    assert marks["current_pair"] == 2
    T_camera_world = np.linalg.inv(T_world_camera)
    world = task.pad.marks_world()
    for pair, (entry, exit_) in zip(marks["sutures"], world, strict=True):
        assert pair["entry"]["p_camera"] == pytest.approx(T_camera_world[:3, :3] @ entry
                                                          + T_camera_world[:3, 3])  # fmt: skip
        assert pair["exit"]["p_camera"] == pytest.approx(T_camera_world[:3, :3] @ exit_
                                                         + T_camera_world[:3, 3])  # fmt: skip
    assert task_marks(task, T_world_camera, CameraConfig())["current_pair"] is None


def _view(arms=None, teleop_state="ENABLED", on=True, t=10.0) -> dict:
    return {
        "time": t,
        "arms": {n: {"state": s, "homed": True} for n, s in (arms or {"PSM1": "ENABLED"}).items()},
        "console": {"teleop_enabled": on, "buttons": {"operator_present": on}},
        "teleops": {"MTMR_PSM1": {"state": teleop_state, "selected": True}},
    }


def test_problems_name_faults_stopped_and_stuck_teleoperations_with_their_reasons():
    from davinci_sim.web.view import problems

    reason = "PSM1: tracking error on joint 'yaw': 0.65 exceeds 0.35; arm in FAULT"
    stopped = "MTMR_PSM1: PSM1 is not ready anymore (FAULT); disabling"
    messages = {"PSM1": ("error", reason, 9.0, 1), "MTMR_PSM1": ("error", stopped, 9.0, 1)}
    out = problems(_view({"PSM1": "FAULT", "PSM2": "FAULT"}, "DISABLED"), messages)
    assert out == [
        {"source": "PSM1", "kind": "fault", "reason": reason},
        {"source": "PSM2", "kind": "fault", "reason": "PSM2 is in FAULT"},
        {"source": "MTMR_PSM1", "kind": "stopped", "reason": stopped},
    ]
    # The teleoperation switched off, or nobody at the console: it is not stopped by a fault.
    assert problems(_view(teleop_state="DISABLED", on=False), messages) == []
    assert problems(_view(), {}) == []


def test_an_aligning_teleoperation_is_a_problem_from_its_second_fresh_warning():
    from davinci_sim.web.view import problems

    text = "MTMR_PSM1: unable to align MTM, angle error is 23.1 (deg)"
    view = _view(teleop_state="ALIGNING_MTM", t=10.0)
    assert problems(view, {"MTMR_PSM1": ("warning", text, 9.5, 1)}) == []  # an ordinary start
    assert problems(view, {"MTMR_PSM1": ("warning", text, 9.5, 2)}) == [
        {"source": "MTMR_PSM1", "kind": "aligning", "reason": text}
    ]
    assert problems(view, {"MTMR_PSM1": ("warning", text, 6.0, 3)}) == []  # stale
    assert problems(_view(t=10.0), {"MTMR_PSM1": ("warning", text, 9.5, 2)}) == []  # aligned
