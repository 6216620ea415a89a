"""The handle on a simulation running in its own thread."""

import time

import pytest

from davinci_sim.sim.handle import ThreadedSimulation
from davinci_sim.sim.simulation import Simulation


def wait_for(predicate, timeout=10.0):
    end = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > end:
            return False
        time.sleep(0.005)
    return True


def test_calls_run_in_the_loop_and_snapshots_follow():
    events = []
    with ThreadedSimulation(Simulation("psm1"), real_time=False) as handle:
        handle.subscribe(lambda src, ev, payload: events.append((src, ev)))
        assert handle.call("PSM1", "state_command", "enable").result(5)
        assert handle.call("PSM1", "state_command", "home").result(5)
        assert wait_for(lambda: handle.snapshot().arms["PSM1"].operating_state.is_homed)
        snap = handle.snapshot()
        assert snap.arms["PSM1"].measured_js.name[2] == "insertion"
        assert snap.arms["PSM1"].measured_cp.reference_frame == "ECM"
        assert handle.call("PSM1/jaw", "move_jp", 0.5).result(5)
        t0 = handle.snapshot().time
        assert wait_for(lambda: handle.snapshot().time > t0 + 0.01)
    assert ("PSM1", "operating_state") in events


def test_bad_calls_fail_their_future_and_the_loop_carries_on():
    with ThreadedSimulation(Simulation("psm1"), real_time=False) as handle:
        with pytest.raises(KeyError, match="unknown target"):
            handle.call("PSM9", "hold").result(5)
        with pytest.raises(AttributeError, match="public"):
            handle.call("PSM1", "_hold_here").result(5)
        with pytest.raises(AttributeError, match="no method"):
            handle.call("PSM1", "fly").result(5)
        refused = handle.call("PSM1", "servo_jp", [float("nan")] * 6).result(5)
        assert not refused
        t0 = handle.snapshot().time
        assert wait_for(lambda: handle.snapshot().time > t0)


def test_real_time_pacing_keeps_sim_time_near_wall_time():
    with ThreadedSimulation(Simulation("psm1"), real_time=True) as handle:
        start_wall, start_sim = time.monotonic(), handle.snapshot().time
        time.sleep(0.3)
        elapsed_sim = handle.snapshot().time - start_sim
    assert elapsed_sim <= time.monotonic() - start_wall + 0.01
