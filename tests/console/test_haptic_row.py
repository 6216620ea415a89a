"""The haptic loop's compiled tick of an MTM whose one field is the seed's viscous fixture
(``console/haptic_row.py``) gives the Python loop's bits: two identical consoles with a
trainee doing the short path task, one ticking compiled and one in Python, agree after every
tick on the physics, the wrench requested and let through, the limiter, the velocity filter
and the efforts the next step uses; a force that is not finite is refused the same way."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bits import assert_same_bits
from davinci_sim.console import haptic_loop, haptic_row
from davinci_sim.operators.console import TraineeHand, hand_impedance
from davinci_sim.study.trial import TrialSpec, build_setup, trial_inputs
from davinci_sim.tasks import install_task, load_task

SHORT_TASK = str(Path(__file__).resolve().parents[1] / "study" / "short_path.yaml")

pytestmark = pytest.mark.skipif(not haptic_row.COMPILED, reason="numba is off")


def _console():
    """A console with the short path task's viscous fixture on MTMR and a trainee's hand."""
    task = load_task(SHORT_TASK)
    setup = build_setup(task)  # (its own: setup_trial shares one per process)
    sim = setup.sim
    session = install_task(sim, task, condition={"type": "viscous", "B": 40.0, "G_max": 5.0})
    spec = TrialSpec(SHORT_TASK, subject=0, condition=2, B=40.0, G_max=5.0, repetition=1,
                     order=1, practice=3, seed=1)  # fmt: skip
    params, trainee = trial_inputs([spec], task, setup.T_world_camera, np.zeros(3))
    setup.device.hand = hand_impedance(params)
    sim.add_component(TraineeHand(trainee, setup.device, sim.arms["PSM1"]),
                      before=next(iter(sim.components)))  # fmt: skip
    haptics = sim.components["haptics"]
    return sim, haptics, haptics.field(session.field_name), setup.device


def _bits(sim, haptics, field, device) -> dict:
    """What the haptic tick leaves behind, as arrays."""
    arm = device.arm
    out = {
        "qpos": sim.data.qpos, "qvel": sim.data.qvel, "ctrl": sim.data.ctrl,
        "tau_ff": sim.servo.tau_ff, "sent": device.wrench(),
        "previous": device._limiter.previous, "active": np.array(device._limiter.active),
        "requested": haptics.requested("MTMR"), "wrench": arm.wrench_setpoint()[1],
    }  # fmt: skip
    for psm, f in field.get_state().items():
        out.update({f"{psm}/{k}": np.asarray(v) for k, v in f.items()})
    return {k: np.array(v, copy=True) for k, v in out.items() if v is not None}


def test_the_compiled_haptic_tick_is_the_python_loop_bit_for_bit(monkeypatch):
    compiled, python = _console(), _console()
    kernel = haptic_row.fixture_render
    signatures = len(kernel.signatures)  # (compiled at import)
    calls = []
    original = haptic_row.fixture_render

    def counted(*args):
        calls.append(1)
        return original(*args)

    monkeypatch.setattr(haptic_row, "fixture_render", counted)
    errors = {True: [], False: []}
    for flag, (_, haptics, *_) in ((True, compiled), (False, python)):
        haptics.channels.subscribe(lambda event, m, flag=flag: errors[flag].append(m.text))
    for k in range(3000):
        for flag, (sim, *_) in ((True, compiled), (False, python)):
            monkeypatch.setattr(haptic_loop, "ENABLED", flag)
            if k == 2000:  # a filter gone bad: the force is not finite for a tick
                state = sim.components["haptics"].get_state()
                name = next(iter(state["fields"]))
                filters = state["fields"][name][1]
                for f in filters.values():
                    f["v"] = np.full(3, np.nan)
                sim.components["haptics"].set_state(state)
            sim.tick()
        assert_same_bits(_bits(*compiled), _bits(*python), f"tick {k}")
        if k == 2000:
            assert errors[True] and errors[True] == errors[False]
            assert "finite" in errors[True][-1]
    assert len(calls) > 2500  # the compiled tick ran (following, the field in the loop)
    assert len(kernel.signatures) == signatures  # none compiled in the loop


def test_another_field_beside_the_fixture_keeps_the_python_loop(monkeypatch):
    sim, haptics, field, device = _console()
    haptics.add_field(lambda state: np.array([0.0, 0.0, 0.1]), mtm="MTMR", name="push")
    calls = []
    monkeypatch.setattr(haptic_row, "fixture_render", lambda *a: calls.append(1))
    sim.run_for(0.5)
    assert not calls
    requested = haptics.requested("MTMR")
    assert requested is not None and np.isfinite(requested).all()
