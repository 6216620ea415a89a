"""The simulation state: ``set_state(get_state())`` resumes bit-identically, whatever happened
in between; ``reset()`` is a new simulation; a state only fits its own scene."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from davinci_sim.console import SIMULATED_SYSTEM, install_console
from davinci_sim.console.setup import add_scripted_hands
from davinci_sim.haptics.fixture import FixtureField
from davinci_sim.sim.handle import ThreadedSimulation
from davinci_sim.sim.simulation import Simulation
from davinci_sim.sim.state import SimState
from davinci_sim.tasks import install_task, load_task

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "console"))
from console_helpers import teleop_sim  # noqa: E402

from bits import assert_same_bits  # noqa: E402

NO_ALIGN = SIMULATED_SYSTEM.replace(align_mtm=False)
GUIDANCE = {"type": "viscous", "B": 40.0, "G_max": 5.0}


def _system():
    """Console following (MTMR_PSM1), contact feedback and the seed task's viscous guidance
    (a FixtureField with its velocity filter) in the haptic loop, a task session, a scripted
    hand drawing circles on the MTM, and the ECM moving (a trajectory moving the camera)."""
    sim, console = teleop_sim(teleop_config=NO_ALIGN, contact_feedback=True)
    install_task(sim, load_task("seed_path"), condition=GUIDANCE)
    add_scripted_hands(sim, console, radius=0.03, frequency=1.0)
    ecm = sim.arms["ECM"]
    ecm.state_command("enable")
    ecm.state_command("home")
    sim.run_for(0.02)
    assert ecm.move_jp(ecm.setpoint_jp() + [0.3, 0.1, 0.03, 0.2])
    sim.run_for(0.3)
    assert ecm.is_busy() and console.psm_teleops["MTMR_PSM1"].is_following()
    return sim, console


def _record(sim: Simulation, console, n: int) -> dict:
    """What the system does over ``n`` ticks: joints, controls, the MTM's wrench, the fields'
    requested wrench, teleop and task states."""
    device, teleop = sim.components["MTMR/device"], console.psm_teleops["MTMR_PSM1"]
    task = sim.components["task"]
    out: dict[str, list] = {k: [] for k in ("qpos", "qvel", "ctrl", "wrench", "requested")}
    out.update(teleop=[], task=[], time=[])
    for _ in range(n):
        sim.tick()
        out["qpos"].append(sim.data.qpos.copy())
        out["qvel"].append(sim.data.qvel.copy())
        out["ctrl"].append(sim.data.ctrl.copy())
        out["wrench"].append(device.wrench())
        out["requested"].append(console.haptics.snapshot().requested["MTMR"].copy())
        out["teleop"].append((teleop.current_state(), teleop.is_following()))
        snap = task.snapshot()
        out["task"].append((snap.phase, snap.distance_to_path))
        out["time"].append((sim.time, sim.tick_count))
    return {k: np.array(v) if k in ("qpos", "qvel", "ctrl", "wrench", "requested") else v
            for k, v in out.items()}  # fmt: skip


def _assert_same(a: dict, b: dict) -> None:
    for key in a:
        if isinstance(a[key], np.ndarray):
            assert np.array_equal(a[key], b[key]), f"{key} differs"
        else:
            assert a[key] == b[key], f"{key} differs"


def _diverge(sim: Simulation, console) -> None:
    """Commands, a trajectory, the clutch and a new scale: the system goes elsewhere."""
    console.emulate_clutch([1])
    sim.components["MTMR/device"].move_hand([0.02, -0.03, 0.01])
    console.psm_teleops["MTMR_PSM1"].set_scale(0.5)
    sim.components["task"].reset()
    sim.run_for(0.1)
    console.emulate_clutch([0])
    sim.arms["ECM"].move_jp(sim.arms["ECM"].setpoint_jp() + [0.05, 0.0, 0.01, 0.0])
    sim.run_for(0.15)


def test_set_state_of_get_state_resumes_bit_identically():
    sim, console = _system()
    state = sim.get_state()
    first = _record(sim, console, 400)
    assert np.abs(first["wrench"]).max() > 0.05  # the haptic loop is pushing (N)
    assert np.ptp(first["qpos"][:, 0], axis=0) > 0  # and things move
    sim.set_state(state)
    _assert_same(first, _record(sim, console, 400))


def test_a_diverged_simulation_restored_gives_the_same_run():
    sim, console = _system()
    state = sim.get_state()
    first = _record(sim, console, 300)
    _diverge(sim, console)
    sim.set_state(state)
    _assert_same(first, _record(sim, console, 300))
    _diverge(sim, console)  # the saved state was not changed by the ticks since
    sim.set_state(state)
    _assert_same(first, _record(sim, console, 300))


def test_the_fixture_filter_is_part_of_the_state(monkeypatch):
    """The resume test can fail: without the guidance's velocity filter the run differs."""
    sim, console = _system()
    state = sim.get_state()
    first = _record(sim, console, 100)
    _diverge(sim, console)
    monkeypatch.setattr(FixtureField, "set_state", lambda self, state: None)
    sim.set_state(state)
    again = _record(sim, console, 100)
    assert not np.array_equal(first["requested"], again["requested"])


def test_encoder_noise_and_the_random_generator_resume():
    sim = Simulation("psm1", seed=3, encoder_noise_std=1e-4)
    sim.step(20)
    state = sim.get_state()

    def run():
        out = []
        for _ in range(50):
            sim.tick()
            out.append(sim.measured_qpos().copy())
        return np.array(out), sim.rng.random(3)

    q1, r1 = run()
    np.testing.assert_array_equal(state.noisy_qpos, state.noisy_qpos)  # a copy, not None
    sim.set_state(state)
    q2, r2 = run()
    assert np.array_equal(q1, q2) and np.array_equal(r1, r2)


def _assert_states_equal(a: SimState, b: SimState) -> None:
    assert a.signature == b.signature
    assert_same_bits(np.asarray(a.physics), np.asarray(b.physics), "physics")
    for name in ("qfrc_bias", "xpos", "xipos", "actuator_force"):
        assert_same_bits(getattr(a.data, name), getattr(b.data, name), f"data.{name}")
    assert_same_bits(a.tick_count, b.tick_count, "tick_count")
    assert_same_bits(a.rng, b.rng, "rng")
    assert_same_bits(a.servo, b.servo, "servo")
    assert_same_bits(a.arms, b.arms, "arms")
    assert_same_bits(a.components, b.components, "components")


def test_reset_is_a_freshly_built_simulation():
    fresh, fresh_console = teleop_sim(start=False, teleop_config=NO_ALIGN)
    sim, console = teleop_sim(start=False, teleop_config=NO_ALIGN)
    sim.tick()  # (what is done before the first tick is part of the system as assembled)
    console.emulate_operator_present([1])
    console.teleop_enable(True)
    sim.arms["ECM"].state_command("enable")
    sim.arms["ECM"].state_command("home")
    sim.run_for(0.4)
    assert console.psm_teleops["MTMR_PSM1"].current_state() != "DISABLED"
    sim.reset()
    _assert_states_equal(sim.get_state(), fresh.get_state())
    runs = []
    for s, c in ((sim, console), (fresh, fresh_console)):
        c.emulate_operator_present([1])
        c.teleop_enable(True)
        s.run_for(0.2)
        runs.append((s.data.qpos.copy(), c.psm_teleops["MTMR_PSM1"].current_state()))
    assert np.array_equal(runs[0][0], runs[1][0]) and runs[0][1] == runs[1][1]


def test_reset_to_another_keyframe_is_a_new_simulation_there():
    sim = Simulation("psm1", keyframe="home")
    sim.arms["PSM1"].state_command("enable")
    sim.run_for(0.05)
    sim.reset("surgical")
    fresh = Simulation("psm1", keyframe="surgical")
    _assert_states_equal(sim.get_state(), fresh.get_state())
    with pytest.raises(ValueError, match="unknown keyframe 'nope'"):
        sim.reset("nope")


def test_a_state_of_another_scene_or_other_components_is_refused():
    psm1 = Simulation("psm1")
    other = Simulation("psm1_ecm_mtmr", keyframe="surgical")
    with pytest.raises(ValueError, match="another scene"):
        psm1.set_state(other.get_state())
    bare = other.get_state()
    install_console(other)
    with pytest.raises(ValueError, match="components"):
        other.set_state(bare)
    with pytest.raises(TypeError, match="SimState"):
        other.set_state({"qpos": other.data.qpos})


def test_a_refused_state_leaves_the_simulation_as_it_was():
    sim, console = teleop_sim(teleop_config=NO_ALIGN)
    state = sim.get_state()
    console.haptics.add_field(lambda s: [0.0, 0.0, 0.1], name="push")  # not in the state
    sim.run_for(0.05)
    before = sim.get_state()
    with pytest.raises(ValueError, match="force fields"):
        sim.set_state(state)
    _assert_states_equal(sim.get_state(), before)


def test_state_and_reset_through_the_handle():
    sim, _ = teleop_sim(teleop_config=NO_ALIGN)
    # 500 ticks before the runner starts: ``before`` is past them whatever the runner does
    # between two calls, so reset taking the count back shows whatever the tick's speed (it
    # ticks freely between calls: a fast tick fits tens of ticks into one thread switch).
    sim.run_for(0.5)
    with ThreadedSimulation(sim, real_time=False) as handle:
        saved = handle.call("sim", "get_state").result(timeout=30)
        handle.call("sim", "set_state", saved).result(timeout=30)
        before = handle.call("sim", "get_state").result(timeout=30)
        handle.call("sim", "reset").result(timeout=30)
        after = handle.call("sim", "get_state").result(timeout=30)
    assert isinstance(saved, SimState)
    assert after.tick_count < before.tick_count
