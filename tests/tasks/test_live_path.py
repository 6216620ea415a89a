"""The live session's compiled tick of its path trial (``tasks/live_path.py``) leaves the
monitor — state machine, observations, metrics, previous sample, results — with the same
bits as the Python path (``live_sample`` then the monitor's ``observe`` with the reducers),
tick after tick of a trainee's repetition: from no master input yet, through a reset, a
restored state, the repetition's finish and the next one's start."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bits import assert_same_bits
from davinci_sim.model.cameras import CameraConfig
from davinci_sim.operators.console import TraineeHand, hand_impedance
from davinci_sim.study.trial import TrialSpec, setup_trial, trial_inputs
from davinci_sim.tasks import install_task, live_path, load_task, path_row
from davinci_sim.tasks.session import live_sample, sample_of
from davinci_sim.tasks.state import Phase, TaskMonitor

SHORT_TASK = str(Path(__file__).resolve().parents[1] / "study" / "short_path.yaml")

pytestmark = pytest.mark.skipif(not path_row.COMPILED, reason="numba is off: no compiled tick")


@pytest.fixture(scope="module")
def checked_run():
    """A trainee's repetition of the short path task, each tick's compiled sample checked
    against the Python path's on a shadow monitor set to the same state before the tick."""
    task = load_task(SHORT_TASK)
    setup = setup_trial(task)
    sim = setup.sim
    session = install_task(sim, task, condition={"type": "viscous", "B": 40.0, "G_max": 5.0})
    assert session._live_tick is not None  # (the path kind, compiled: the tick applies)
    spec = TrialSpec(SHORT_TASK, subject=0, condition=2, B=40.0, G_max=5.0, repetition=1,
                     order=1, practice=3, seed=1)  # fmt: skip
    params, trainee = trial_inputs([spec], task, setup.T_world_camera, np.zeros(3))
    shadow = TaskMonitor(task)
    original, tick = session.post_step, session._live_tick.tick
    seen = {"checked": 0, "measured": 0, "phases": set(), "ticked": []}

    def compiled_tick(*args):
        seen["ticked"].append(tick(*args))
        return seen["ticked"][-1]

    def post_step(t):
        before = session.monitor.get_state()
        seen["ticked"].clear()
        original(t)
        if seen["ticked"] != [True]:
            return  # (a tick the session did not sample, or sampled in Python)
        shadow.set_state(before)
        T_task_camera = task.T_task_camera(sim.T_cart_camera())
        sample = live_sample(task, T_task_camera, session.teleop, session.console, t)
        compiled, path_row.COMPILED = path_row.COMPILED, False  # the reducers' path
        try:
            shadow.observe(sample)
        finally:
            path_row.COMPILED = compiled
        assert_same_bits(session.monitor.get_state(), shadow.get_state(), f"t={t}")
        seen["checked"] += 1
        seen["measured"] += bool(session.monitor.metrics._prev_in[0])
        seen["phases"].add(session.monitor.phase)

    session.post_step, session._live_tick.tick = post_step, compiled_tick
    sim.run_for(0.05)  # the trainee not yet there
    setup.device.hand = hand_impedance(params)
    hand = TraineeHand(trainee, setup.device, sim.arms["PSM1"])
    sim.add_component(hand, before=next(iter(sim.components)))
    sim.run_for(0.3)
    session.monitor.reset()  # (a session's reset: the previous sample forgotten)
    sim.run_for(0.2)
    kept = session.get_state()  # a restored state: its previous sample is a copy
    sim.run_for(0.1)
    session.set_state(kept)
    end = sim.time + 20.0
    while not session.results and sim.time < end:
        sim.tick()
    sim.run_for(0.05)
    yield session, seen
    sim.close()


def test_the_compiled_tick_is_the_python_path_bit_for_bit(checked_run):
    session, seen = checked_run
    assert seen["checked"] > 1000
    assert seen["measured"] > 500  # a repetition measured, sample after sample
    assert {Phase.READY, Phase.RUNNING, Phase.FINISHED} <= seen["phases"]
    assert len(session.results) == 1 and session.results[0]["samples"] > 500


def test_the_session_compiles_nothing_in_its_loop(checked_run):
    """The tick's kernel ran with the signature its module compiled at import (another one
    would compile inside the 1 kHz loop: a stall of seconds)."""
    assert len(path_row.live_path_row.signatures) == 1


def test_a_session_of_another_kind_keeps_the_python_path():
    task = load_task("needle_targeting")
    monitor = TaskMonitor(task)
    assert live_path.LivePathTick.build(task, monitor, None) is None


def _rigid(rng) -> np.ndarray:
    """A random rigid transform (rotation from a unit quaternion, a translation within 0.2 m)."""
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    T = np.eye(4)
    T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                 [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                 [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]  # fmt: skip
    T[:3, 3] = rng.uniform(-0.2, 0.2, 3)
    return T


def test_every_input_case_against_the_python_path():
    """Constructed inputs the simulation seldom gives: no guidance force and no master input
    at first, contacts, the tip behind the camera or out of the image, a camera that moves,
    the repetition run to its results and the next one begun, a reset and a restored state
    in the middle."""
    task = load_task("seed_path")
    camera = CameraConfig()
    monitor, shadow = TaskMonitor(task), TaskMonitor(task)
    tick = live_path.LivePathTick.build(task, monitor, camera)
    assert tick is not None
    rng = np.random.default_rng(7)
    # The tip: at point 1, along the path to its end (1 mm noise), back to point 1.
    arc = np.linspace(0.0, task.path.length, 1500)
    there = np.array([task.path.point_at(s) for s in arc]) + rng.normal(0, 0.001, (1500, 3))
    tips = np.vstack([np.repeat([task.start], 60, axis=0), there,
                      np.repeat([task.finish], 30, axis=0), there[::-5],
                      np.repeat([task.start], 30, axis=0), there[:200]])  # fmt: skip
    cameras = [_rigid(rng) for _ in range(3)]
    kept = None
    phases = set()
    for i, tip in enumerate(tips):
        t = 0.001 * i
        T_task_camera = cameras[0] if i % 400 < 390 else cameras[1 + i % 2]
        T_task_tip = np.eye(4)
        T_task_tip[:3, :3] = _rigid(rng)[:3, :3]
        T_task_tip[:3, 3] = tip
        p_camera = np.linalg.inv(T_task_camera) @ T_task_tip
        p_camera.setflags(write=False)
        force = None if i < 5 else rng.normal(0, 2.0, 3)
        master = None if i < 20 else np.asfortranarray(rng.normal(0, 0.1, (3, 3)))[:, 1]
        count = int(rng.integers(0, 3)) if i % 97 < 20 else 0
        inputs = (p_camera, force, bool(i % 150 < 10), master, (count, 0.7 * count))
        if i == 1000:
            kept = monitor.get_state()
        if i == 1100:  # (running: the previous sample a copy, measured)
            monitor.set_state(kept)
        if i == 2060:  # (away from point 1: IDLE from now on)
            monitor.reset()
        before = monitor.get_state()
        assert tick.tick(T_task_camera, inputs, t)
        shadow.set_state(before)
        compiled, path_row.COMPILED = path_row.COMPILED, False
        try:
            shadow.observe(sample_of(T_task_camera, inputs, camera, t, {}))
        finally:
            path_row.COMPILED = compiled
        assert_same_bits(monitor.get_state(), shadow.get_state(), f"sample {i}")
        phases.add(monitor.phase)
    assert {Phase.IDLE, Phase.READY, Phase.RUNNING, Phase.FINISHED, Phase.RESULTS} <= phases
    assert len(path_row.live_path_row.signatures) == 1  # (non-contiguous master included)


def test_samples_in_turn_are_the_samples_one_by_one():
    """``ticks`` (an environment's samples of a compiled period, no force, clutch or master)
    leaves the monitor as the Python path's samples one by one, period after period, through
    a finished repetition."""
    task = load_task("seed_path")
    camera = CameraConfig()
    monitor, shadow = TaskMonitor(task), TaskMonitor(task)
    tick = live_path.LivePathTick.build(task, monitor, camera)
    rng = np.random.default_rng(11)
    arc = np.linspace(0.0, task.path.length, 1200)
    there = np.array([task.path.point_at(s) for s in arc]) + rng.normal(0, 0.0005, (1200, 3))
    tips = np.vstack([np.repeat([task.start], 40, axis=0), there,
                      np.repeat([task.finish], 40, axis=0)])  # fmt: skip
    T_task_camera = _rigid(rng)
    T_task_tip = np.tile(np.eye(4), (len(tips), 1, 1))
    T_task_tip[:, :3, 3] = tips
    p_camera = np.linalg.inv(T_task_camera) @ T_task_tip
    t = 0.001 * np.arange(len(tips))
    contacts = (np.arange(len(tips)) % 50 < 5).astype(np.int64)

    def python(j):
        inputs = (p_camera[j], None, False, None, (int(contacts[j]), 0.5 * contacts[j]))
        sample = sample_of(T_task_camera, inputs, camera, float(t[j]), {})
        compiled, path_row.COMPILED = path_row.COMPILED, False
        try:
            shadow.observe(sample)
        finally:
            path_row.COMPILED = compiled

    frozen = p_camera[0].copy()
    frozen.setflags(write=False)
    assert tick.tick(T_task_camera, (frozen, None, False, None, (1, 0.5)), 0.0)
    python(0)
    in_turn = 0
    for first in range(1, len(tips), 20):
        rows = slice(first, min(first + 20, len(tips)))
        cameras = np.tile(T_task_camera, (rows.stop - rows.start, 1, 1))
        took = tick.ticks(cameras, cameras @ p_camera[rows], p_camera[rows], t[rows],
                          contacts[rows], 0.5 * contacts[rows])  # fmt: skip
        assert took
        in_turn += rows.stop - rows.start
        for j in range(rows.start, rows.stop):
            python(j)
        assert_same_bits(monitor.get_state(), shadow.get_state(), f"samples {rows}")
    assert monitor.results is not None and monitor.phase == Phase.RESULTS
    assert in_turn == len(tips) - 1
