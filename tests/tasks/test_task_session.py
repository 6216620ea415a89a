"""A training session: a trainee does the short task at the simulated console with guidance,
and the session measures the repetition, logs it and starts over from point 1."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from davinci_sim.operators.console import TraineeHand, hand_impedance
from davinci_sim.study.trial import TrialSpec, setup_trial, trial_inputs
from davinci_sim.tasks import install_task, load_task

SHORT_TASK = str(Path(__file__).resolve().parents[1] / "study" / "short_path.yaml")


@pytest.fixture(scope="module")
def session_run(tmp_path_factory):
    task = load_task(SHORT_TASK)
    log = tmp_path_factory.mktemp("task") / "reps.csv"
    setup = setup_trial(task)
    sim = setup.sim
    session = install_task(sim, task, condition={"type": "viscous", "B": 40.0, "G_max": 5.0},
                           log=log)  # fmt: skip
    spec = TrialSpec(SHORT_TASK, subject=0, condition=2, B=40.0, G_max=5.0, repetition=1,
                     order=1, practice=3, seed=1)  # fmt: skip
    params, trainee = trial_inputs([spec], task, setup.T_world_camera, np.zeros(3))
    setup.device.hand = hand_impedance(params)
    hand = TraineeHand(trainee, setup.device, sim.arms["PSM1"])
    sim.add_component(hand, before=next(iter(sim.components)))
    phases = set()
    end = sim.time + 20.0
    while not session.results and sim.time < end:
        sim.tick()
        phases.add(session.snapshot().phase)
    yield sim, session, log, phases
    sim.close()


def test_a_repetition_is_measured_and_logged(session_run):
    sim, session, log, phases = session_run
    assert {"READY", "RUNNING"} <= phases
    assert len(session.results) == 1
    row = session.results[0]
    assert row["repetition"] == 1 and row["condition"] == "viscous(B=40, G_max=5)"
    assert 0 < row["deviation_error"] < 0.003  # the trainee stays within mm of the path
    assert 0 < row["peak_force"] <= 5.0 + 1e-9  # guided, within G_max
    assert row["samples"] > 500
    with open(log) as f:
        logged = list(csv.DictReader(f))
    assert len(logged) == 1
    assert float(logged[0]["deviation_error"]) == pytest.approx(row["deviation_error"])
    state = session.snapshot()
    assert state.completed == 1 and state.last["repetition"] == 1
    assert state.distance_to_path < 0.003


def test_back_at_point_1_the_next_repetition_starts_and_reset_abandons_it(session_run):
    sim, session, log, _ = session_run
    task = session.task
    # The trainee lets go; the PSM is brought back to point 1 by its own API (clutched).
    for name in [n for n in sim.components if n.endswith("/trainee")]:
        sim.remove_component(name)
    sim.components["MTMR_PSM1"].clutch(True)
    psm = sim.arms["PSM1"]
    T = psm.setpoint_cp().T.copy()
    T[:3, 3] = (np.linalg.inv(sim.T_cart_camera()) @ np.append(task.start, 1.0))[:3]
    assert psm.move_cp(T)
    assert sim.run_until(lambda: not psm.is_busy(), 10.0)
    sim.run_for(0.05)
    state = session.snapshot()
    assert state.repetition == 2 and state.phase == "READY" and state.completed == 1
    assert session.reset()
    assert session.snapshot().phase == "IDLE" and session.snapshot().repetition == 2


def test_a_task_needs_its_teleoperation():
    from davinci_sim.console import install_console
    from davinci_sim.sim.simulation import Simulation

    sim = Simulation("psm1_ecm_mtmr")
    install_console(sim)
    task = load_task(SHORT_TASK)
    with pytest.raises(KeyError, match="MTMR_PSM2"):
        from dataclasses import replace

        install_task(sim, replace(task, teleop=replace(task.teleop, psm="PSM2")))
    with pytest.raises(KeyError, match="install the console"):
        install_task(Simulation("psm1_ecm_mtmr"), task)
    sim.close()


@pytest.fixture
def fresh_session():
    from davinci_sim.console import install_console
    from davinci_sim.sim.simulation import Simulation

    sim = Simulation("psm1_ecm_mtmr")
    install_console(sim)
    session = install_task(sim, load_task(SHORT_TASK))
    yield sim, session
    sim.close()


def guidance_force(sim, session) -> np.ndarray:
    """The session's fixture force (task frame, N) 2 mm off the path's start, moving away
    from it at 5 cm/s."""
    fixture = sim.components["haptics"].field(session.field_name).fixture
    task = session.task
    p = np.asarray(task.start, dtype=float) + [0.0, 0.0, 0.002]
    return np.asarray(fixture.force(p[None], np.array([[0.0, 0.0, 0.05]]))).reshape(-1)[:3]


def test_set_condition_puts_the_new_fixture_in_the_loop_and_restarts_the_repetition(
    fresh_session,
):
    sim, session = fresh_session
    sim.run_for(0.01)
    assert session.set_condition({"type": "viscous", "B": 60.0, "G_max": 8.0})
    strong = np.linalg.norm(guidance_force(sim, session))
    assert session.snapshot().condition == "viscous(B=60, G_max=8)"
    assert session.set_condition({"type": "viscous", "B": 20.0, "G_max": 2.0})
    weak = np.linalg.norm(guidance_force(sim, session))
    assert 0 < weak < strong
    assert session.set_condition({"type": "none"})
    assert np.linalg.norm(guidance_force(sim, session)) == 0.0
    assert session.snapshot().phase == "IDLE"
    # One guidance field at any time, under the same name.
    names = sim.components["haptics"].field_names()
    assert names.count(session.field_name) == 1 and len(names) == 1


@pytest.mark.parametrize(
    "condition, words",
    [
        ("B=1000", "has no condition"),
        ({"type": "magnet"}, "unknown fixture type"),
        ({"type": "viscous", "B": 40.0, "G_max": 5.0, "color": 1.0}, "unknown keys"),
    ],
)
def test_a_refused_condition_changes_nothing(fresh_session, condition, words):
    sim, session = fresh_session
    before = sim.components["haptics"].field(session.field_name)
    label = session.condition
    result = session.set_condition(condition)
    assert not result and words in result.message
    assert sim.components["haptics"].field(session.field_name) is before
    assert session.condition == label


def test_frame_view_brings_the_endoscope_to_the_task():
    from davinci_sim.model.cameras import CameraConfig, project_left
    from davinci_sim.system import SystemDescription, TaskDescription
    from davinci_sim.system.build import build_simulation

    description = SystemDescription(
        scene="psm1_ecm_mtmr", home=True, runner="none",
        task=TaskDescription("seed_path", frame_view=0.13),
    )  # fmt: skip
    sim = build_simulation(description)
    session, ecm = sim.components["task"], sim.arms["ECM"]
    T_before = sim.T_cart_camera().copy()
    assert sim.run_until(lambda: ecm.is_homed() and not ecm.is_busy(), 20.0)
    sim.run_for(0.01)
    assert sim.run_until(lambda: not ecm.is_busy(), 20.0)
    sim.run_for(0.2)
    T_camera_world = np.linalg.inv(sim.T_cart_camera())
    points = session.task.view_points
    p_camera = (T_camera_world @ np.c_[points, np.ones(len(points))].T).T[:, :3]
    centre = p_camera.mean(axis=0)
    # The path's centre is straight ahead at the distance asked (the IK keeps the shaft
    # through the RCM: the centre is on the camera's axis).
    assert np.linalg.norm(centre[:2]) < 0.005 and centre[2] == pytest.approx(0.13, abs=0.005)
    pixels = np.array([project_left(p, CameraConfig()) for p in p_camera])
    width, height = np.ptp(pixels, axis=0)
    assert width > 0.4 * 640  # the path spans a good part of the view, not a corner
    assert not np.allclose(T_before, sim.T_cart_camera())
    # Then the tool is brought to the start, in view.
    psm = sim.arms["PSM1"]
    assert sim.run_until(lambda: not psm.is_busy(), 20.0)
    sim.run_for(0.2)
    tip = psm.measured_cp().position
    start_camera = (T_camera_world @ np.append(session.task.start, 1.0))[:3]
    assert np.linalg.norm(tip - start_camera) < 0.002
    assert session.snapshot().phase in ("READY", "IDLE")
    sim.close()
