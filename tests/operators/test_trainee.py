"""Synthetic trainees: determinism, tracking, impedance, tremor, learning."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import signal

from davinci_sim.geometry.path import Polyline
from davinci_sim.operators import SyntheticTrainee, TraineePhase, run_ideal, sample_subjects
from davinci_sim.operators.plan import path_plan
from davinci_sim.tasks import load_task

DT = 0.001
TASK = load_task("seed_path")
# The task expressed in a camera-like frame: a fixed rigid transform, so that the tests do
# not need the simulator (the study uses the camera pose of the surgical keyframe).
T_CAMERA_WORLD = np.array(
    [
        [0.85, -0.5, -0.19, 0.66],
        [-0.25, -0.69, 0.68, 0.31],
        [-0.47, -0.53, -0.71, 1.31],
        [0, 0, 0, 1],
    ]
)
T_CAMERA_WORLD[:3, :3] = np.linalg.qr(T_CAMERA_WORLD[:3, :3])[0] * [1, 1, 1]
PATH = TASK.path.transformed(T_CAMERA_WORLD)


def subjects(n, seed=1, **overrides):
    p = sample_subjects(n, seed=seed)
    return dataclasses.replace(p, **{k: np.full(n, v, dtype=float) for k, v in overrides.items()})


def trainee(params, *, repetition=1, keys=None, path=PATH, **kw):
    n = len(params)
    return SyntheticTrainee(
        params,
        repetition=np.full(n, repetition),
        path=path,
        knots=TASK.marker_arc_lengths,
        hand_start=np.zeros((n, 3)),
        scale=0.6,
        start_tolerance=TASK.start_tolerance,
        noise_keys=keys if keys is not None else [(7, i) for i in range(n)],
        dt=DT,
        **kw,
    )


def ideal(tr, tool_start, fixture=None, duration=30.0, record=False):
    return run_ideal(
        tr,
        tool_start=tool_start,
        fixture=fixture,
        start_tolerance=TASK.start_tolerance,
        finish_tolerance=TASK.finish_tolerance,
        tube_radius=TASK.tube_radius,
        duration=duration,
        record=record,
    )


def test_deterministic_per_key_and_independent_of_the_batch():
    """Same keys, same hands; a trial alone equals the same trial inside a larger batch;
    another key, another trajectory."""
    p = subjects(3)
    start = np.tile(PATH.point_at(0.0) + [0.01, 0.0, 0.0], (3, 1))
    force = np.zeros((3, 3))
    runs = []
    for tr in (trainee(p), trainee(p), trainee(p.take([1]), keys=[(7, 1)])):
        hands = []
        tool = start[: tr.n].copy()
        for _ in range(400):
            hand = tr.step(DT, tool, force[: tr.n]).position
            tool = start[: tr.n] + 0.6 * hand
            hands.append(hand)
        runs.append(np.array(hands))
    np.testing.assert_array_equal(runs[0], runs[1])
    np.testing.assert_array_equal(runs[2][:, 0], runs[0][:, 1])
    other = trainee(p, keys=[(8, i) for i in range(3)])
    tool = start.copy()
    for _ in range(400):
        hand = other.step(DT, tool, force).position
        tool = start + 0.6 * hand
    assert not np.allclose(hand, runs[0][-1])
    with pytest.raises(ValueError, match="dt"):
        other.step(0.002, tool, force)


def test_tracks_the_path_without_noise_or_force():
    """Noise and tremor off, no force: the tool reaches point 1, follows the path within a
    few µm (the minimum-jerk strokes are smooth and the feed-forward exact), finishes in
    about the planned time, on a path as long as the reference."""
    p = subjects(2, speed=0.04, crossover=4.0)
    tr = trainee(p, motor_noise=False, tremor=False)
    start = np.tile(PATH.point_at(0.0) + [-0.01, 0.005, 0.0], (2, 1))
    run = ideal(tr, start, duration=15.0)
    assert run.finished.all()
    m = run.metrics
    assert np.all(m.deviation_error < 1e-5)
    # Planned time between leaving the start sphere and entering the finish sphere.
    t = np.arange(0.0, 10.0, DT)
    for i in range(2):
        _, _, s = path_plan(
            PATH, TASK.marker_arc_lengths, np.repeat(tr.durations[i : i + 1], len(t), 0), t
        )
        leave = t[np.argmax(np.linalg.norm(PATH.point_at(s) - PATH.point_at(0.0), axis=1) > 0.003)]
        reach = t[
            np.argmax(
                np.linalg.norm(PATH.point_at(s) - PATH.point_at(PATH.length), axis=1) <= 0.003
            )
        ]
        assert m.completion_time[i] == pytest.approx(reach - leave, abs=0.02)
    assert np.all(np.abs(m.path_length - (PATH.length - 2 * TASK.start_tolerance)) < 0.004)
    assert np.all(m.peak_force == 0.0)
    assert set(tr.phase.tolist()) <= {TraineePhase.FOLLOWING, TraineePhase.DONE}


def test_force_moves_the_hand_through_the_limb_impedance():
    """Before the trainee first sees the tool (the first τ) there is no voluntary
    correction: a step force on the hand gives exactly the step response of the limb's
    mass-spring-damper (analytic, scipy), ending near F/K."""
    p = subjects(1, delay=0.8, mass=1.0, stiffness=300.0, damping=15.0)
    tr = trainee(p, motor_noise=False, tremor=False)
    F = np.array([[2.0, 0.0, 0.0]])
    xs = [tr.step(DT, np.zeros((1, 3)), F).position[0, 0] for _ in range(700)]
    t = DT * np.arange(1, 701)
    _, y = signal.step(signal.lti([1.0], [1.0, 15.0, 300.0]), T=t)
    np.testing.assert_allclose(xs, 2.0 * y, atol=2e-4)
    assert xs[-1] == pytest.approx(2.0 / 300.0, rel=0.02)


def test_visual_correction_cancels_a_constant_force():
    """Following the path, a constant 1 N push sideways moves the tool by ~F/K·scale at
    first; the delayed visual correction (an integrator) takes it back: late in the run the
    deviation is a fraction of that."""
    p = subjects(1, speed=0.04, stiffness=300.0, damping=15.0)
    tr = trainee(p, motor_noise=False, tremor=False)
    start = PATH.point_at(0.0)[None]
    push = np.cross(PATH.tangent_at(0.001), PATH.tangent_at(PATH.length - 0.001))
    push = push / np.linalg.norm(push)

    class Push:
        def force(self, position, velocity):
            return np.broadcast_to(push, np.shape(position))

    run = ideal(tr, start, fixture=Push(), duration=8.0, record=True)
    d = PATH.closest_point(run.tool[0]).distance
    static = 0.6 / 300.0
    assert d[:100].max() > 0.4 * static  # the push acts before the eyes see it
    assert np.median(d[-2000:]) < 0.15 * static


def test_tremor_spectrum_peaks_in_the_physiological_band():
    """With the trainee waiting (long delay) and no motor noise, the hand's motion is the
    tremor: its spectrum peaks at the subject's frequency (8-12 Hz) and its 3-D rms is the
    subject's amplitude."""
    p = subjects(3, delay=6.0)
    tr = trainee(p, motor_noise=False)
    hands = np.array(
        [tr.step(DT, np.zeros((3, 3)), np.zeros((3, 3))).position for _ in range(6000)]
    )
    x = hands[1000:] - hands[1000:].mean(axis=0)
    f, pxx = signal.welch(x, fs=1 / DT, nperseg=2048, axis=0)
    for i in range(3):
        peak = f[np.argmax(pxx[:, i].sum(axis=1))]
        assert 8.0 <= peak <= 12.5
        assert peak == pytest.approx(p.tremor_frequency[i], abs=1.0)
        rms = np.sqrt(np.mean(np.sum(x[:, i] ** 2, axis=1)))
        assert rms == pytest.approx(p.tremor_amplitude[i], rel=0.35)


def test_practice_reduces_error_and_time_on_average():
    """Eight subjects, first vs tenth repetition on the ideal teleop: mean deviation error
    and completion time are lower at the tenth (practised speed 3 cm/s for a short test)."""
    n = 8
    p = dataclasses.replace(sample_subjects(n, seed=5), speed=np.full(n, 0.03))
    both = p.take(np.r_[np.arange(n), np.arange(n)])
    reps = np.r_[np.ones(n), np.full(n, 10)]
    tr = SyntheticTrainee(
        both,
        repetition=reps,
        path=PATH,
        knots=TASK.marker_arc_lengths,
        hand_start=np.zeros((2 * n, 3)),
        scale=0.6,
        start_tolerance=TASK.start_tolerance,
        noise_keys=[(11, i % n, r) for i, r in enumerate(reps)],
    )
    run = ideal(tr, np.tile(PATH.point_at(0.0), (2 * n, 1)), duration=40.0)
    assert run.finished.all()
    e, T = run.metrics.deviation_error, run.metrics.completion_time
    assert e[n:].mean() < e[:n].mean()
    assert T[n:].mean() < 0.8 * T[:n].mean()


def test_invalid_construction():
    p = subjects(2)
    with pytest.raises(ValueError):
        trainee(p, keys=[(1,)])
    with pytest.raises(ValueError):
        SyntheticTrainee(
            p,
            repetition=[1, 1],
            path=Polyline([[0, 0, 0], [0.01, 0, 0]]),
            knots=[0.0, 0.0],
            hand_start=np.zeros((2, 3)),
            scale=0.6,
            start_tolerance=0.003,
            noise_keys=[(1,), (2,)],
        )


def test_a_trials_pace_scales_its_speed_and_leaves_its_noise_as_it_was():
    """The pace multiplies the practised speed of each trial (its durations shrink by it);
    the motor noise and tremor streams of the same keys draw what they drew without it."""
    p = subjects(4)
    keys = [(7, i, 0, 3) for i in range(4)]
    plain = trainee(p, repetition=3, keys=keys)
    paced = trainee(dataclasses.replace(p, pace_spread=np.full(4, 1.3)), repetition=3, keys=keys)
    np.testing.assert_array_equal(plain.pace, 1.0)
    np.testing.assert_array_equal(plain.speed, p.speed / p.practice_factor(np.full(4, 3)))
    assert np.all(paced.pace != 1.0)
    np.testing.assert_allclose(paced.speed, plain.speed * paced.pace, rtol=1e-15)
    np.testing.assert_allclose(paced.durations, plain.durations / paced.pace[:, None], rtol=1e-12)
    for _ in range(3):
        np.testing.assert_array_equal(paced._noise.next(), plain._noise.next())
