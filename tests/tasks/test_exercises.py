"""The skill exercises (camera targeting, ring walk, needle targeting): their metrics on
constructed sample streams with answers known by construction, their files, drawing and
check, and each solved at the simulated console by a scripted operator (arm API moves,
the teleoperation clutched, short simulated times)."""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np
import pytest
from drawn import drawn_visual_only

from davinci_sim.study.trial import setup_trial
from davinci_sim.tasks import Phase, Sample, TaskError, TaskMonitor, install_task, load_task
from davinci_sim.tasks.camera_targeting import CameraTargetingTask
from davinci_sim.tasks.check import _pointing, check_task
from davinci_sim.tasks.needle_targeting import NeedleTargetingTask
from davinci_sim.tasks.ring_walk import RingWalkTask
from davinci_sim.tasks.scoring import SCORE_COLUMNS
from davinci_sim.tasks.session import SESSION_COLUMNS

DT = 0.001
EXERCISES = ("camera_targeting", "ring_walk", "needle_targeting")


def _frame_with_z(z) -> np.ndarray:
    """A rotation whose third column is the unit vector of ``z`` (Gram-Schmidt)."""
    z = np.asarray(z, dtype=float) / np.linalg.norm(z)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = helper - (helper @ z) * z
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _tilted(angle_deg: float, about=(0.0, 1.0, 0.0), base=(0.0, 0.0, -1.0)) -> np.ndarray:
    """``base`` turned by ``angle_deg`` about ``about`` (perpendicular to it)."""
    a = math.radians(angle_deg)
    b, k = np.asarray(base, float), np.asarray(about, float)
    return b * math.cos(a) + np.cross(k, b) * math.sin(a)


# ---------------------------------------------------------------- needle targeting
def _needle_task(**kw) -> NeedleTargetingTask:
    args = dict(
        name="n", start=[0.0, 0.0, 0.0], targets=[[0.02, 0.0, 0.0], [0.04, 0.0, 0.0]],
        directions=[[0.0, 0.0, -1.0], [1.0, 0.0, 0.0]], target_radius=0.002,
        angle_tolerance=15.0, dwell=0.0295, start_tolerance=0.002,
    )  # fmt: skip
    args.update(kw)
    return NeedleTargetingTask(**args)


def test_needle_targeting_metrics_on_a_constructed_run():
    """The tip leaves the start along +x at 0.1 m/s (one sample per 0.1 mm). At target 1
    the tool points 10° off its direction (tolerance 15°): hit once it has been inside and
    aligned for the dwell. At target 2 it points 30° off, turns to 25° inside, and leaves:
    a miss, which also ends the run. Orientation error: the mean of the smallest angles,
    (10° + 25°) / 2."""
    task = _needle_task()
    monitor = TaskMonitor(task)
    R1 = _frame_with_z(_tilted(10.0))
    R30 = _frame_with_z(_tilted(30.0, base=(1.0, 0.0, 0.0)))
    R25 = _frame_with_z(_tilted(25.0, base=(1.0, 0.0, 0.0)))
    tips, phases, times = [], [], []
    for k in range(700):
        x = k * 1e-4 + 5e-5
        R = R1 if x < 0.03 else (R30 if x < 0.0405 else R25)
        tips.append([x, 0.0, 0.0])
        times.append(k * DT)
        phases.append(monitor.observe(Sample.of(k * DT, tips[-1], R_task_tip=R))[0])
        if phases[-1] == Phase.FINISHED:
            break
    x = np.array(tips)[:, 0]
    first = phases.index(Phase.RUNNING)
    assert x[first] > 0.002 >= x[first - 1]
    last = len(phases) - 1
    # Target 2 (x 0.038..0.042) left at the first sample beyond 0.042 without a hit.
    assert x[last] > 0.042 >= x[last - 1]
    r = monitor.results
    assert r.targets_hit[0] == 1 and r.missed_targets[0] == 1
    assert math.degrees(r.orientation_error[0]) == pytest.approx(17.5, abs=1e-9)
    assert r.completion_time[0] == pytest.approx(times[last] - times[first])
    assert r.path_length[0] == pytest.approx(x[last] - x[first])
    assert math.isnan(r.instrument_collisions[0])  # no contact field sampled: unavailable


def test_needle_hit_needs_the_dwell_inside_and_aligned():
    """Aligned inside target 1 for less than the dwell, then out: a miss, not a hit; the
    same touch held for the dwell is a hit at the first sample with t − t_in ≥ dwell."""
    task = _needle_task(targets=[[0.02, 0.0, 0.0]], directions=[[0.0, 0.0, -1.0]], dwell=0.0095)
    R = np.diag([1.0, -1.0, -1.0])  # z = (0, 0, −1): exactly aligned

    def run(stay: int):
        m = TaskMonitor(task)
        path = [[0, 0, 0]] * 2 + [[0.01, 0, 0]] + [[0.02, 0, 0]] * stay + [[0.03, 0, 0]]
        for k, p in enumerate(path):
            m.observe(Sample.of(k * DT, p, R_task_tip=R))
        return m

    short = run(5)  # inside 4 ms of the 9.5 ms dwell
    assert short.results.targets_hit[0] == 0 and short.results.missed_targets[0] == 1
    held = run(12)  # inside at k = 3..14: hit at k = 13 (t − t_in = 10 ms ≥ 9.5)
    assert held.results.targets_hit[0] == 1 and held.results.missed_targets[0] == 0
    assert held.results.completion_time[0] == pytest.approx(13 * DT - 2 * DT)
    assert held.results.orientation_error[0] == pytest.approx(0.0, abs=1e-12)


def test_needle_targeting_refuses_a_sample_without_the_tool_orientation():
    monitor = TaskMonitor(_needle_task())
    with pytest.raises(ValueError, match="R_task_tip"):
        monitor.update(0.0, [0.0, 0.0, 0.0])


# ---------------------------------------------------------------- camera targeting
def _camera_pose(c, z=(0.0, 0.0, 1.0)) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = _frame_with_z(z)
    T[:3, 3] = c
    return T


def test_camera_targeting_metrics_on_a_constructed_run():
    """Camera looking along +z. Still at z = −0.05 (READY), then it moves to z = 0 at 1 m/s
    (RUNNING once 2.5 mm away), which brings target 1 (0, 0, 0.1) to a depth within
    0.1 ± 0.0105 from t = 45 ms: acquired after the dwell (199.5 ms) at t = 245 ms. Then it
    slides along +x to 0.05 at 1 m/s: target 2 (0.05, 0, 0.1) is within 3° off-axis once
    x ≥ 0.1·tan 3° short of it (t = 290 ms), acquired at t = 490 ms."""
    task = CameraTargetingTask(
        "c", start=[0.0, 0.0, 0.0], targets=[[0.0, 0.0, 0.1], [0.05, 0.0, 0.1]], depth=0.1,
        depth_tolerance=0.0105, centre_tolerance=3.0, dwell=0.1995, start_motion=0.0025,
    )  # fmt: skip
    monitor = TaskMonitor(task)
    poses, phases = [], []
    for k in range(700):
        t = k * DT
        cz = -0.05 + min(max(t - 0.005, 0.0), 0.05)
        cx = min(max(t - 0.245, 0.0), 0.05)
        poses.append(_camera_pose([cx, 0.0, cz]))
        sample = Sample.of(t, [0.01, 0.0, 0.0], T_task_camera=poses[-1])
        phases.append(monitor.observe(sample)[0])
        if phases[-1] == Phase.FINISHED:
            break
    assert phases[1] == Phase.READY
    first, last = phases.index(Phase.RUNNING), len(phases) - 1
    assert (first, last) == (8, 490)
    r = monitor.results
    assert r.targets_acquired[0] == 2
    assert r.completion_time[0] == pytest.approx(0.482)
    c = np.array([p[:3, 3] for p in poses[first : last + 1]])
    assert r.camera_path_length[0] == pytest.approx(
        np.linalg.norm(np.diff(c, axis=0), axis=1).sum()
    )
    assert r.camera_path_length[0] == pytest.approx(0.047 + 0.05)
    assert r.path_length[0] == 0.0  # the instrument stayed still


def test_camera_targeting_waits_for_a_still_camera_and_needs_its_pose():
    task = CameraTargetingTask("c", start=[0, 0, 0], targets=[[0, 0, 0.1]], depth=0.1)
    monitor = TaskMonitor(task)
    for k in range(50):  # moving at 1 cm/s (10 µm per sample > still_step): never READY
        monitor.observe(Sample.of(k * DT, [0, 0, 0], T_task_camera=_camera_pose([k * 1e-5, 0, 0])))
    assert monitor.phase == Phase.IDLE
    with pytest.raises(ValueError, match="T_task_camera"):
        monitor.update(1.0, [0.0, 0.0, 0.0])


# ---------------------------------------------------------------- ring walk
def test_ring_walk_contact_metrics_on_a_constructed_run():
    """A straight wire along x (10 cm), ring 5 mm, wire 1 mm: contact beyond 4 mm from the
    axis. The tip runs along at 0.1 mm per sample, 6 mm off for samples 300..399 and 5 mm
    off for 600..649: two contacts, 150 samples touching (each pair counted by its end
    sample) = 0.15 s; 4.5 mm off for 800..809 is a third."""
    task = RingWalkTask("r", [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]], corner_radius=0.0,
                        ring_radius=0.005, wire_radius=0.001)  # fmt: skip
    assert task.clearance == pytest.approx(0.004) and task.tube_radius == task.clearance
    monitor = TaskMonitor(task)
    off = np.zeros(1000)
    off[300:400], off[600:650], off[800:810] = 0.006, 0.005, 0.0045
    tips, phases = [], []
    for k in range(1000):
        tips.append([k * 1e-4 + 5e-5, off[k], 0.0])
        phases.append(monitor.observe(Sample.of(k * DT, tips[-1]))[0])
        if k == 500:
            assert task.progress(monitor.state) == "50 % of the wire"
        if phases[-1] == Phase.FINISHED:
            break
    first, last = phases.index(Phase.RUNNING), len(phases) - 1
    r = monitor.results
    assert r.contact_count[0] == 3
    assert r.contact_time[0] == pytest.approx(0.16)
    assert r.deviation_error[0] == pytest.approx(np.mean(off[first : last + 1]))
    p = np.array(tips[first : last + 1])
    assert r.path_length[0] == pytest.approx(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
    assert r.completion_time[0] == pytest.approx((last - first) * DT)


def test_ring_walk_refuses_a_wire_thicker_than_the_ring():
    with pytest.raises(TaskError, match="thinner"):
        RingWalkTask("r", [[0, 0, 0], [0.1, 0, 0]], ring_radius=0.001, wire_radius=0.002)


# ---------------------------------------------------------------- files, drawing, check
@pytest.mark.parametrize("name", EXERCISES)
def test_the_shipped_exercises_load_save_and_pass_the_check(name, tmp_path):
    from davinci_sim.tasks import save_task

    task = load_task(name)
    assert task.kind == name
    save_task(task, tmp_path / "again.yaml")
    again = load_task(tmp_path / "again.yaml")
    assert again.to_dict() == task.to_dict()
    checks = check_task(task)
    assert checks and all(c.ok for c in checks), [c for c in checks if not c.ok]
    declared = {m.name for m in task.METRICS}
    for m in task.METRICS:
        assert m.better in ("lower", "higher", "neither") and m.unit
    assert {"completion_time", "path_length"} <= declared


def test_the_check_fails_a_target_the_ecm_cannot_centre_and_a_direction_out_of_reach():
    far = dataclasses.replace(load_task("camera_targeting"), depth=0.05)  # insertion > 0.255 m
    assert not all(c.ok for c in check_task(far))
    task = load_task("needle_targeting")
    up = np.array(task.directions)
    up[0] = [0.0, 0.0, 1.0]  # the tool pointing up, back at its own shaft
    bad = check_task(dataclasses.replace(task, directions=up))
    assert not bad[1].reachable and all(c.ok for c in bad[2:])


def test_schema_names_a_bad_field_with_its_line(tmp_path):
    text = _data("needle_targeting").read_text()
    (tmp_path / "bad.yaml").write_text(text.replace("angle_tolerance: 15.0", "angle_tolerance: -3"))
    with pytest.raises(TaskError, match=r"line \d+: angle_tolerance"):
        load_task(tmp_path / "bad.yaml")
    text = _data("ring_walk").read_text()
    (tmp_path / "bad2.yaml").write_text(text + "tube_radius: 0.003\n")
    with pytest.raises(TaskError, match="tube_radius"):
        load_task(tmp_path / "bad2.yaml")


def _data(name: str):
    from importlib import resources

    return resources.files("davinci_sim.tasks") / "data" / f"{name}.yaml"


@pytest.mark.parametrize("name", EXERCISES)
def test_each_exercise_draws_visual_only_geoms(name):
    task = load_task(name)
    model, ours = drawn_visual_only(task)
    assert len(ours) > 5
    if name == "ring_walk":  # the ring rides on the tool
        wrist = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "PSM1/wrist_yaw")
        ring = [i for i in ours if model.geom(i).name.startswith("task/ring")]
        assert ring and all(model.geom_bodyid[i] != 0 for i in ring)
        assert all(model.body_parentid[model.geom_bodyid[i]] == wrist for i in ring)


# ---------------------------------------------------------------- scripted operators
def _row_columns(task, row):
    assert list(row) == [*SESSION_COLUMNS, *(m.name for m in task.METRICS), *SCORE_COLUMNS]


def test_needle_targeting_solved_at_the_console():
    """The tool, teleoperation clutched, moved by the PSM's ``move_cp`` to each target
    pointing along its direction: every target hit, a small orientation error, a score."""
    task = load_task("needle_targeting")
    task = dataclasses.replace(task, targets=task.targets[:2], directions=task.directions[:2])
    setup = setup_trial(task)
    sim, psm = setup.sim, setup.sim.arms[task.teleop.psm]
    session = install_task(sim, task)
    sim.run_for(0.01)
    assert session.snapshot().phase == "READY"
    setup.teleop.clutch(True)
    T_camera_task = np.linalg.inv(setup.T_task_camera)
    for p, d in zip(task.targets, task.directions, strict=True):
        goal = psm.setpoint_cp().T.copy()
        goal[:3, 3] = (T_camera_task @ np.append(p, 1.0))[:3]
        goal[:3, :3] = _pointing(goal[:3, :3], T_camera_task[:3, :3] @ d)
        assert psm.move_cp(goal)
        assert sim.run_until(lambda: not psm.is_busy(), 5.0)
        sim.run_for(task.dwell + 0.02)
        if not session.results:  # the panel says which target is next
            assert session.snapshot().progress == "touch target 2 of 2"
    assert session.results, session.snapshot()
    row = session.results[0]
    _row_columns(task, row)
    assert row["targets_hit"] == 2 and row["missed_targets"] == 0
    assert math.degrees(row["orientation_error"]) < 2.0
    assert row["instrument_collisions"] == 0 and row["out_of_view"] == 0.0
    assert row["score"] > 80.0


def test_ring_walk_solved_at_the_console():
    """The tool, clutched, servoed along a short wire at 3 cm/s: finished without touching;
    then along the same wire 5 mm off for its middle third: contact once."""
    task = load_task("ring_walk")
    w0 = task.waypoints[0]
    task = dataclasses.replace(
        task, waypoints=np.array([w0, w0 + [0.012, -0.008, 0.006], w0 + [0.024, -0.004, 0.012]]),
        corner_radius=0.004,
    )  # fmt: skip
    setup = setup_trial(task)
    sim, psm = setup.sim, setup.sim.arms[task.teleop.psm]
    session = install_task(sim, task)
    sim.run_for(0.01)
    setup.teleop.clutch(True)
    T_camera_task = np.linalg.inv(setup.T_task_camera)
    path, goal = task.path, psm.setpoint_cp().T.copy()

    def walk(offset):
        s = 0.0
        while s < path.length + 0.005 and len(session.results) < walked + 1:
            arc = min(s, path.length)
            p = path.point_at(arc) + (offset if path.length / 3 < arc < 2 * path.length / 3 else 0)
            goal[:3, 3] = (T_camera_task @ np.append(p, 1.0))[:3]
            psm.servo_cp(goal)
            sim.step()
            s += 0.03 * DT

    walked = 0
    walk(np.zeros(3))
    assert len(session.results) == 1
    first = session.results[0]
    _row_columns(task, first)
    assert first["contact_count"] == 0 and first["contact_time"] == 0.0
    assert first["deviation_error"] < 0.001 and first["score"] > 60.0
    goal[:3, 3] = (T_camera_task @ np.append(task.start, 1.0))[:3]  # back to the start
    psm.move_cp(goal)
    assert sim.run_until(lambda: session.snapshot().phase == "READY", 5.0)
    walked = 1
    walk(np.array([0.0, 0.0, 0.005]))
    second = session.results[1]
    assert second["contact_count"] == 1 and second["contact_time"] > 0.05
    assert second["score"] < first["score"]


def test_camera_targeting_solved_at_the_console():
    """The ECM, homed, moved by ``move_cp`` to the pose on the line from its RCM through
    each target at the task's depth (the instrument's teleoperation clutched, so it stays
    put): each target acquired after the dwell; the camera's path is at least the straight
    runs between the viewpoints."""
    task = load_task("camera_targeting")
    task = dataclasses.replace(task, targets=task.targets[:2], dwell=0.1)
    setup = setup_trial(task)
    sim = setup.sim
    setup.teleop.clutch(True)
    session = install_task(sim, task)
    ecm = sim.arms["ECM"]
    ecm.state_command("enable")
    ecm.state_command("home")
    assert sim.run_until(lambda: ecm.is_homed() and not ecm.is_busy(), 10.0)
    assert session.snapshot().phase == "READY"
    rcm = ecm.base_frame()[0][:3, 3]
    views = []
    for p in task.targets:
        axis = (p - rcm) / np.linalg.norm(p - rcm)
        goal = ecm.measured_cp().T.copy()
        goal[:3, 3] = p - task.depth * axis
        views.append(goal[:3, 3])
        assert ecm.move_cp(goal)
        assert sim.run_until(lambda: not ecm.is_busy(), 10.0)
        sim.run_for(task.dwell + 0.02)
        if not session.results:
            assert session.snapshot().progress == "centre target 2 of 2"
    assert session.results, session.snapshot()
    row = session.results[0]
    _row_columns(task, row)
    assert row["targets_acquired"] == 2
    assert row["camera_path_length"] >= np.linalg.norm(views[1] - views[0]) - 1e-3
    assert row["path_length"] < 0.002  # the instrument stayed where it was
    assert row["score"] is not None


@pytest.mark.parametrize("name", EXERCISES)
def test_the_study_command_refuses_an_exercise_with_the_reason(name, tmp_path, capsys):
    from davinci_sim.cli import main

    assert main(["study", "--task", name, "--output", str(tmp_path / "out")]) == 2
    assert f"is a {name} exercise" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("name", EXERCISES)
def test_the_web_study_tab_refuses_an_exercise_with_the_reason(name):
    """The study (trials, batch engine, report) is the path kind's: an exercise is refused
    before any thread starts, saying why."""
    from davinci_sim.web.study_job import StudyJob

    job = StudyJob(name, lambda message: None)
    why = job.start(1, 1)
    assert why is not None and name in why and "path" in why and not job.running


def test_camera_targeting_with_the_camera_pedal_and_both_hands():
    """At the console with both MTMs (simulated devices): the camera pedal held, a scripted
    operator turns both hands about the eyes (HRSV) by the target's angles off the view
    axis, a few times (a proportional loop, 150 ms apart), as a person steers the view:
    the target, 3 cm to the image's left at the right depth, is acquired; the instrument,
    its teleoperation suspended by the pedal, does not move; the masters did."""
    from davinci_sim.console import SIMULATED_SYSTEM, install_console
    from davinci_sim.model.config import SceneConfig
    from davinci_sim.sim.simulation import Simulation

    scene = SceneConfig(arms=("PSM1", "ECM", "MTML", "MTMR"), include_patient=False)
    sim = Simulation(scene, keyframe="surgical")
    console = install_console(sim, teleop_config=SIMULATED_SYSTEM.replace(align_mtm=False))
    console.emulate_operator_present([1])
    console.teleop_enable(True)
    assert sim.run_until(console.psm_teleops["MTMR_PSM1"].is_following, 5)
    T_cart_camera = sim.T_cart_camera().copy()
    target = (T_cart_camera @ np.array([0.03, 0.005, 0.20, 1.0]))[:3]
    tip = (T_cart_camera @ sim.arms["PSM1"].measured_cp().T)[:3, 3]
    task = CameraTargetingTask("pedal", start=tip, targets=[target], depth=0.20,
                               depth_tolerance=0.02, centre_tolerance=2.0, dwell=0.2)  # fmt: skip
    session = install_task(sim, task)
    left, right = sim.components["MTML/device"], sim.components["MTMR/device"]
    assert console.emulate_camera([1])
    assert sim.run_until(console.ecm_teleop.is_following, 2)
    left.grasp(hold_orientation=False)
    right.grasp(hold_orientation=False)
    sim.run_for(0.05)
    assert session.snapshot().phase == "READY"
    p_left, p_right = left.input().position.copy(), right.input().position.copy()
    yaw = pitch = 0.0
    for _ in range(20):
        if session.results:
            break
        q = np.linalg.solve(sim.T_cart_camera(), np.append(target, 1.0))[:3]
        yaw += 0.8 * math.atan2(q[0], q[2])  # the target's angle to the image's left
        pitch += 0.8 * math.atan2(q[1], q[2])  # ... and up
        c, s = math.cos(-yaw), math.sin(-yaw)
        R = np.array([[1, 0, 0], [0, math.cos(pitch), -math.sin(pitch)],
                      [0, math.sin(pitch), math.cos(pitch)]]) @ np.array(
            [[c, 0, s], [0, 1, 0], [-s, 0, c]])  # fmt: skip
        left.move_hand(R @ p_left)
        right.move_hand(R @ p_right)
        sim.run_for(0.15)
    assert session.results, session.snapshot()
    row = session.results[0]
    assert row["targets_acquired"] == 1
    assert row["camera_path_length"] > 0.005  # the view turned ~9°: the tip moves ~1 cm
    assert row["path_length"] < 1e-6 and row["out_of_view"] < 1e-6
    assert row["master_workspace"] > 0.005
    sim.close()


def test_the_sample_carries_camera_poses_and_tool_orientations():
    """``Sample.of`` takes one pose for every trial or one each; ``take`` and ``where``
    keep them per trial (a field is None unless both samples have it)."""
    T = _camera_pose([0.0, 0.0, 0.1])
    s = Sample.of([0.0, 1.0], np.zeros((2, 3)), T_task_camera=T, R_task_tip=np.eye(3))
    assert s.T_task_camera.shape == (2, 4, 4) and s.R_task_tip.shape == (2, 3, 3)
    np.testing.assert_array_equal(s.T_task_camera[1], T)
    other = Sample.of([0.0, 1.0], np.ones((2, 3)), T_task_camera=np.stack([np.eye(4)] * 2),
                      R_task_tip=np.stack([-np.eye(3)] * 2))  # fmt: skip
    mixed = s.where([False, True], other)
    np.testing.assert_array_equal(mixed.T_task_camera[0], T)
    np.testing.assert_array_equal(mixed.R_task_tip[1], -np.eye(3))
    assert s.take([1]).T_task_camera.shape == (1, 4, 4)
    assert s.where([True, True], Sample.of([0.0, 1.0], np.ones((2, 3)))).R_task_tip is None


def test_where_with_every_row_taken_gives_np_wheres_values_types_and_nones():
    """The shortcut for a mask true everywhere (no array arithmetic) against ``np.where``
    field by field."""
    from davinci_sim.tasks.base import _FIELDS

    rng = np.random.default_rng(0)
    a = Sample.of([0.0, 1.0], rng.normal(size=(2, 3)), T_task_camera=np.eye(4),
                  contacts=[1, 2], visible=[True, False])  # fmt: skip
    b = Sample.of([0.5, 1.5], rng.normal(size=(2, 3)), R_task_tip=np.eye(3),
                  tool_force=[0.1, 0.2], contacts=[3, 0], visible=[False, False])  # fmt: skip
    for first, second in ((a, b), (b, a), (a, a)):
        got = first.where([True, True], second)
        for k in _FIELDS:
            x, y = getattr(first, k), getattr(second, k)
            if x is None or y is None:
                assert getattr(got, k) is None, k
                continue
            want = np.where(np.ones((2,) + (1,) * (x.ndim - 1), dtype=bool), y, x)
            assert getattr(got, k).dtype == want.dtype, k
            np.testing.assert_array_equal(getattr(got, k), want, err_msg=k)
            # its own arrays, as np.where's: a caller may refill its sample's buffers
            assert not np.shares_memory(getattr(got, k), y), k
