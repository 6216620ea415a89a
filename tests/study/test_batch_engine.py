"""The batch engine against the live simulator: the same trials give the same results."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import davinci_sim.sim.simulation as simulation
import davinci_sim.study.trial as trial
from davinci_sim.geometry.so3 import rotation_vector
from davinci_sim.operators.params import Mechanisms
from davinci_sim.study import TrialSpec, run_trial
from davinci_sim.study.batch import TrialBatch, run_batch
from davinci_sim.study.report import COLUMNS, TIMING_COLUMNS

METRICS = ("deviation_error", "completion_time", "path_length", "peak_force", "samples")


def _specs(task: str, timeout: float = 60.0) -> list[TrialSpec]:
    return [
        TrialSpec(task, subject=s, condition=c, B=B, G_max=G, repetition=1, order=1,
                  practice=p, seed=5, timeout=timeout)
        for s, c, B, G, p in ((0, 0, 0.0, 0.0, 1), (1, 3, 60.0, 8.0, 4), (1, 1, 20.0, 2.0, 7))
    ]  # fmt: skip


@pytest.mark.parametrize(
    ("carried", "mechanisms"),
    [(False, ()), (False, ("reliance", "stiffening")), (True, ())],
    ids=["plain", "mechanisms", "wrist turning"],
)
def test_batch_is_the_live_simulation_to_machine_precision(
    short_task, carry_task, monkeypatch, carried, mechanisms
):
    """With the base frames held (the live simulation follows every change of the ECM and
    setup joints; the batch holds them, see study.batch), every joint of every trial
    follows the live simulation's to ~1e-12 over a whole second of assisted following;
    with the trainee mechanisms on too (the co-contraction is a law both engines share:
    the force felt is the wrench the MTM renders, the limb's impedance the trainee's); with
    a carried object's wrist turns (the hand's target turning: operators.wrist)."""
    monkeypatch.setattr(simulation, "BASE_FRAME_TOLERANCE", np.inf)
    # Set-ups built here start under the patched tolerance: keep them out of later tests.
    monkeypatch.setattr(trial, "_SETUPS", {})
    spec = _specs(carry_task if carried else short_task)[1]
    if mechanisms:
        spec = dataclasses.replace(spec, mechanisms=mechanisms, own_practice=2.44)
        # A low threshold, so that the short run's guidance (~1 N) makes the arm co-contract.
        low = Mechanisms(reliance=0.8, stiffening_gain=2.0, stiffening_threshold=0.2)
        monkeypatch.setattr(Mechanisms, "named", classmethod(lambda cls, names: low))
    batch = TrialBatch([spec])
    from davinci_sim.haptics.fixture import FixtureField
    from davinci_sim.operators.console import TraineeHand, hand_impedance
    from davinci_sim.study.trial import condition_spec, load_spec_task, setup_trial, trial_inputs

    task = load_spec_task(spec)
    setup = setup_trial(task)
    sim = setup.sim
    params, trainee = trial_inputs([spec], task, setup.T_world_camera, np.zeros(3))
    setup.device.hand = hand_impedance(params)
    hand = TraineeHand(trainee, setup.device, sim.arms["PSM1"])
    sim.add_component(hand, before=next(iter(sim.components)))
    fixture = FixtureField(task.fixture(condition_spec(spec.B, spec.G_max)), frame="world")
    setup.console.haptics.add_field(fixture, mtm="MTMR")
    peak = 0.0
    for _ in range(1000):
        sim.tick()
        batch.tick()
        np.testing.assert_allclose(batch.Q[0], sim.data.qpos, atol=1e-12)
        np.testing.assert_allclose(batch.V[0], sim.data.qvel, atol=1e-9)
        peak = max(peak, np.linalg.norm(setup.device.wrench()))
    np.testing.assert_allclose(batch.wrench_sent[0], setup.device.wrench(), atol=1e-9)
    assert peak > 0.2  # the guidance was really pushing (N)
    co = batch.trainee.co_contraction
    np.testing.assert_allclose(co, hand.trainee.co_contraction, atol=1e-9)
    assert (co[0] > 0.1) == bool(mechanisms)
    if mechanisms:
        assert setup.device.hand.stiffness > params.stiffness[0]
    # the hands' targets: the same turn in both engines (none without a carried object)
    turned = np.linalg.norm(rotation_vector(batch.T_hand[0, :3, :3] @ batch.R_hand0[0].T))
    assert (turned > 0.01) == carried
    np.testing.assert_allclose(batch.T_hand[0, :3, :3], hand.device._hand_target[:3, :3],
                               atol=1e-12)  # fmt: skip
    sim.close()


def test_batch_rows_match_live_trials(short_task):
    """Whole trials, with the live simulation's own frame handling: the same metrics within
    the µm-level differences of the held frames. (Trials that stay near the path: one that
    falls into the guidance's lateral oscillation amplifies any difference.)"""
    specs = _specs(short_task)
    rows = run_batch(specs)
    for spec, row in zip(specs, rows, strict=True):
        live = run_trial(spec)
        assert row["finished"] and live["finished"]
        assert row["samples"] == pytest.approx(live["samples"], abs=30)
        assert row["completion_time"] == pytest.approx(live["completion_time"], abs=0.03)
        assert row["deviation_error"] == pytest.approx(live["deviation_error"], rel=0.1)
        assert row["path_length"] == pytest.approx(live["path_length"], rel=0.05)
        assert row["peak_force"] == pytest.approx(live["peak_force"], rel=0.1, abs=1e-9)


def test_a_trial_does_not_depend_on_its_batch(short_task):
    specs = _specs(short_task, timeout=2.0)
    together = run_batch(specs)
    alone = run_batch([specs[1]])[0]
    keys = [k for k in COLUMNS if k not in TIMING_COLUMNS]
    assert {k: together[1][k] for k in keys} == {k: alone[k] for k in keys}


def test_batch_refuses_mixed_tasks_and_seeds(short_task):
    a = _specs(short_task)[0]
    with pytest.raises(ValueError, match="one task"):
        TrialBatch([a, TrialSpec(**{**a.__dict__, "task": "seed_path"})])
    with pytest.raises(ValueError, match="one seed"):
        TrialBatch([a, TrialSpec(**{**a.__dict__, "seed": 9})])
    with pytest.raises(ValueError, match="at least one"):
        TrialBatch([])


def test_compacting_a_batch_keeps_every_trial_result(short_task):
    """Trials that end early are dropped from the arrays (the batch halves itself): the
    trials still running, and the ended ones' rows, are what they are on their own."""
    base = _specs(short_task)[1]
    specs = [
        TrialSpec(**{**base.__dict__, "subject": i % 2, "timeout": 0.15 * (i + 1)})
        for i in range(10)
    ]
    batch = TrialBatch(specs)
    sizes = []
    original = batch._compact

    def compact():
        original()
        sizes.append(batch.n)

    batch._compact = compact
    rows = batch.run()
    assert sizes and sizes[0] < 10  # it did compact
    keys = [k for k in COLUMNS if k not in TIMING_COLUMNS]
    assert np.isnan(rows[0]["deviation_error"]) and rows[9]["samples"] > 0
    for i in (2, 5, 9):
        alone = run_batch([specs[i]])[0]
        assert {k: repr(rows[i][k]) for k in keys} == {k: repr(alone[k]) for k in keys}
        assert rows[i]["sim_time"] == pytest.approx(specs[i].timeout, abs=0.0015)
