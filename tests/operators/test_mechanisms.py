"""The trainees' reactions to guidance (operators.params.Mechanisms): reliance on guidance
and arm stiffening, each on constructed cases with known answers."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from davinci_sim.operators import SyntheticTrainee, run_ideal, sample_subjects
from davinci_sim.operators.params import MECHANISMS, Mechanisms, guidance_strength
from davinci_sim.tasks import load_task

TASK = load_task("seed_path")
PATH = TASK.path  # (the trainee works in any frame: the task's is enough here)


def subjects(n, seed=1, **overrides):
    p = sample_subjects(n, seed=seed)
    return dataclasses.replace(p, **{k: np.full(n, v, dtype=float) for k, v in overrides.items()})


def trainee(params, *, repetition=1, **kw):
    n = len(params)
    return SyntheticTrainee(
        params, repetition=np.full(n, repetition), path=PATH, knots=TASK.marker_arc_lengths,
        hand_start=np.zeros((n, 3)), scale=0.6, start_tolerance=TASK.start_tolerance,
        noise_keys=[(7, i) for i in range(n)], **kw,
    )  # fmt: skip


def ideal(tr, tool_start):
    return run_ideal(
        tr, tool_start=tool_start, fixture=None, start_tolerance=TASK.start_tolerance,
        finish_tolerance=TASK.finish_tolerance, tube_radius=TASK.tube_radius, duration=40.0,
    )  # fmt: skip


def test_named_switches_each_mechanism_on_alone():
    assert Mechanisms.named(()) == Mechanisms()
    assert Mechanisms.named(["reliance"]).reliance > 0
    assert Mechanisms.named(["reliance"]).stiffening_gain == 0
    assert Mechanisms.named(["stiffening"]).stiffening_gain > 0
    assert Mechanisms.named(["stiffening"]).reliance == 0
    assert set(MECHANISMS) == {"reliance", "stiffening"}
    with pytest.raises(ValueError, match="unknown mechanisms"):
        Mechanisms.named(["grip"])
    with pytest.raises(ValueError, match="reliance"):
        Mechanisms(reliance=1.5)
    with pytest.raises(ValueError, match="stiffening_threshold"):
        Mechanisms(stiffening_threshold=-1.0)


def test_guidance_strength_of_fixture_entries():
    assert guidance_strength({"type": "none"}) == 0
    assert guidance_strength({"type": "viscous", "B": 0.0, "G_max": 0.0}) == 0
    assert guidance_strength({"type": "viscous", "B": 0.0, "G_max": 5.0}) == 0  # no force
    assert guidance_strength({"type": "viscous", "B": 40.0, "G_max": 5.0}) == 5.0
    assert guidance_strength({"type": "spring", "stiffness": 200.0, "max_force": 3.0}) == 3.0
    assert guidance_strength({"type": "spring", "stiffness": 0.0, "max_force": 3.0}) == 0
    assert guidance_strength({"type": "mine:Law", "k": 1.0}) == math.inf
    # Rota's fixture: the capped sum scaled by the day's assistance
    rota = {"type": "viscous_elastic", "B": 15.0, "elastic_gain": 0.8, "max_force": 3.0}
    assert guidance_strength(rota) == 3.0
    assert guidance_strength({**rota, "assistance": 0.25}) == 0.75


def test_own_practice_step_known_values():
    """1 − 0.8·G/(G + 2): Table I's bounds 0, 2, 5, 8 N count 1, 0.6, 3/7, 0.36."""
    m = Mechanisms.named(["reliance"])
    got = [m.own_practice_step(g) for g in (0.0, 2.0, 5.0, 8.0, math.inf)]
    assert got == pytest.approx([1.0, 0.6, 1 - 0.8 * 5 / 7, 0.36, 0.2])
    assert Mechanisms().own_practice_step(8.0) == 1.0  # off: every trial counts whole


def test_reliance_slows_unassisted_improvement_after_guided_practice():
    """Two groups of the same subjects after 10 practice trials, tested unassisted (no
    fixture, noise on, the same noise streams): those whose practice was guided (own count
    1 + 10·0.36 = 4.6) correct more slowly, are noisier and deviate more than those whose
    practice was not (own count 11); with reliance off both would be the same trainee."""
    p = subjects(6, speed=0.02)
    start = np.tile(PATH.point_at(0.0) + [-0.004, 0.002, 0.0], (6, 1))
    step = Mechanisms.named(["reliance"]).own_practice_step(8.0)
    unguided = trainee(p, repetition=11, own_practice=np.full(6, 11.0))
    guided = trainee(p, repetition=11, own_practice=np.full(6, 1 + 10 * step))
    assert np.all(guided.crossover < unguided.crossover)
    assert np.all(guided.noise_k > unguided.noise_k)
    np.testing.assert_array_equal(guided.speed, unguided.speed)  # the plan still practised
    a, b = ideal(unguided, start), ideal(guided, start)
    assert a.finished.all() and b.finished.all()
    assert np.mean(b.metrics.deviation_error) > 1.1 * np.mean(a.metrics.deviation_error)
    with pytest.raises(ValueError, match="own_practice"):
        trainee(p, own_practice=np.full(6, 0.5))


def test_stiffening_raises_impedance_above_the_threshold_only():
    """A constant force on the hand: below the threshold (3 N) the co-contraction stays 0
    and the limb keeps its relaxed stiffness; above it, c follows the first-order lag
    c_k = c*·(1 − (1 − dt/τ)^k) towards c* = 0.5/N · (‖F‖ − 3 N), capped at 2."""
    m = Mechanisms.named(["stiffening"])
    p = subjects(3)
    tr = trainee(p, mechanisms=m)
    force = np.array([[2.9, 0.0, 0.0], [0.0, 5.0, 0.0], [0.0, 0.0, 20.0]])  # N
    k = 300
    for _ in range(k):
        tr.feel(tr.dt, force)
    lag = 1 - (1 - tr.dt / m.stiffening_time) ** k
    expected = np.array([0.0, 0.5 * 2.0, 2.0]) * lag
    np.testing.assert_allclose(tr.co_contraction, expected, rtol=1e-12)
    np.testing.assert_array_equal(tr.stiffness[0], p.stiffness[0])
    np.testing.assert_allclose(tr.stiffness, p.stiffness * (1 + expected))
    np.testing.assert_allclose(tr.damping, p.damping * (1 + expected))
    # The guidance moves a stiffened hand less: the spring's pull back for a displaced
    # handle is (1 + c) times the relaxed one's.
    dx = np.tile([0.002, 0.0, 0.0], (3, 1))
    pull = tr.hand_force(tr.x_eq + dx, np.zeros((3, 3))) - tr.push_force()
    np.testing.assert_allclose(pull[:, 0], -p.stiffness * (1 + expected) * 0.002)
    # Off: the same force leaves the limb as it is.
    off = trainee(p)
    for _ in range(k):
        off.feel(off.dt, force)
    assert np.all(off.co_contraction == 0)


def test_a_stiffened_hand_yields_less_to_a_steady_force():
    """A hand (noise off, the tool held still where it is seen) pushed by a constant 6 N:
    the stiffening trainee co-contracts (c → 0.5·(6 − 3) = 1.5) and its hand is deflected
    from its equilibrium 1/2.5 as far as the relaxed one's (static deflection F/K)."""
    p = subjects(2, speed=0.02)
    start = np.tile(PATH.point_at(0.0), (2, 1))
    force = np.array([0.0, 6.0, 0.0])
    relaxed = trainee(p, motor_noise=False, tremor=False)
    stiff = trainee(p, motor_noise=False, tremor=False,
                    mechanisms=Mechanisms.named(["stiffening"]))  # fmt: skip
    tool = start.copy()
    for tr in (relaxed, stiff):
        hand = None
        for _ in range(2000):
            hand = tr.step(tr.dt, tool, np.tile(force, (2, 1))).position
        tr.deflection = hand - tr.x_eq
    np.testing.assert_allclose(stiff.co_contraction, 1.5, rtol=1e-3)
    ratio = stiff.deflection[:, 1] / relaxed.deflection[:, 1]
    np.testing.assert_allclose(ratio, 1 / 2.5, rtol=0.05)
