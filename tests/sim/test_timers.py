"""MuJoCo's stage timers: off once a simulation is built, the physics unchanged, and back
on where someone asks for them (sim/timers.py)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from davinci_sim.sim import timers
from davinci_sim.sim.simulation import Simulation

STEP = mujoco.mjtTimer.mjTIMER_STEP

if timers._callback() is None:  # pragma: no cover - a wheel without its library file
    pytest.skip("MuJoCo's library cannot be reached through ctypes", allow_module_level=True)


@pytest.fixture
def choice():
    """The process's timer state as it was, put back after the test."""
    kept = dict(timers._state)
    value = timers._callback().value
    yield
    timers._state.clear()
    timers._state.update(kept)
    timers._callback().value = value


def _stepped(model: mujoco.MjModel, start: mujoco.MjData, n: int) -> mujoco.MjData:
    data = mujoco.MjData(model)
    mujoco.mj_copyData(data, model, start)
    data.ctrl[:] = 0.05  # (something moves: the actuators push)
    for _ in range(n):
        mujoco.mj_step(model, data)
    return data


@pytest.mark.usefixtures("choice")
def test_a_built_simulation_leaves_mujoco_untimed_and_the_physics_the_same():
    timers._state.pop("chosen", None)
    timers.mujoco_timers(True)
    timers._state.pop("chosen", None)  # (as in a process that never chose)
    sim = Simulation("psm1_ecm_mtmr", keyframe="surgical")
    assert not timers.timers_on()
    off = _stepped(sim.model, sim.data, 50)
    assert off.timer[STEP].duration == 0.0

    assert timers.mujoco_timers(True)
    on = _stepped(sim.model, sim.data, 50)
    assert on.timer[STEP].duration > 0.0 and on.timer[STEP].number == 50
    for name in ("qpos", "qvel", "qacc", "act", "qfrc_constraint"):
        np.testing.assert_array_equal(getattr(on, name), getattr(off, name), err_msg=name)


@pytest.mark.usefixtures("choice")
def test_a_choice_for_the_timers_stands_for_later_simulations():
    assert timers.mujoco_timers(True)
    sim = Simulation("psm1_ecm_mtmr", keyframe="surgical")
    assert timers.timers_on()
    assert _stepped(sim.model, sim.data, 3).timer[STEP].number == 3
    assert not timers.mujoco_timers(False)
    Simulation("psm1_ecm_mtmr", keyframe="surgical")
    assert not timers.timers_on()
