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


def test_real_time_pacing_keeps_sim_time_behind_wall_time():
    """On a virtual clock (moved only by the loop's sleeps and its readings): one tick per
    period, sim time never ahead of the wall clock, and ``call_at`` runs at its tick."""
    now = [0.0]
    slept = []

    def clock():
        now[0] += 1e-6
        return now[0]

    def sleep(s):
        slept.append(s)
        now[0] += s
        time.sleep(0)  # let the other threads run

    sim = Simulation("psm1")
    handle = ThreadedSimulation(sim, real_time=True, snapshot_period=0.001, clock=clock,
                                sleep=sleep)  # fmt: skip
    at = handle.call_at(50, "sim", "measured_qpos")
    with handle:
        assert wait_for(lambda: handle.snapshot().tick >= 300)
        start = now[0]
        tick0 = handle.snapshot().tick
        assert wait_for(lambda: handle.snapshot().tick >= tick0 + 100)
        ticks, wall = handle.snapshot().tick - tick0, now[0] - start
    assert ticks * sim.dt <= wall + 2 * sim.dt  # paced: sim time does not run ahead
    assert slept and max(slept) <= sim.dt
    assert at.result(5) is not None
    stats = handle.period_statistics()
    assert stats.real_time and stats.ticks >= 400 and stats.late_periods == 0
    late = handle.call_at(0, "sim", "measured_qpos")
    with handle:
        with pytest.raises(ValueError, match="already run"):
            late.result(5)


@pytest.mark.parametrize("noise", [0.0, 1e-4])
def test_snapshot_poses_are_the_arms_own(noise):
    """The snapshot computes its Cartesian fields lazily from the copied joints: they equal,
    to the bit, what each arm's methods return at that tick (every arm kind, moving arms,
    setpoints away from the measured joints, encoder noise)."""
    import numpy as np

    from davinci_sim.sim.handle import take_snapshot

    sim = Simulation("full", keyframe="surgical", encoder_noise_std=noise, seed=3)
    for name in ("PSM1", "ECM", "MTMR"):
        arm = sim.arms[name]
        arm.state_command("enable")
        arm.state_command("home")
    sim.run_until(lambda: all(sim.arms[n].is_homed() for n in ("PSM1", "ECM", "MTMR")), 30)
    assert sim.arms["PSM1"].move_jr([0.3, -0.2, 0.02, 0.5, 0.3, 0.3])
    sim.run_for(0.2)  # a trajectory under way: moving, setpoint ≠ measured
    snap = take_snapshot(sim)
    assert set(snap.arms) == set(sim.arms)
    for name, arm in sim.arms.items():
        s = snap.arms[name]
        pairs = (
            (s.measured_cp, arm.measured_cp()),
            (s.setpoint_cp, arm.setpoint_cp()),
            (s.local_measured_cp, arm.local.measured_cp()),
            (s.local_setpoint_cp, arm.local.setpoint_cp()),
        )
        for got, want in pairs:
            assert np.array_equal(got.T, want.T), name
            assert (got.reference_frame, got.moving_frame) == (
                want.reference_frame,
                want.moving_frame,
            )
        assert np.array_equal(s.measured_cv.twist, arm.measured_cv().twist), name
    assert np.linalg.norm(snap.arms["PSM1"].measured_cv.twist) > 1e-4
    # Read after the simulation moved on, a snapshot's fields are still those of its tick.
    later = take_snapshot(sim)
    psm = sim.arms["PSM1"]
    q, cp, cv = psm.measured_jp().copy(), psm.measured_cp().T, psm.measured_cv().twist
    sim.step(5)
    assert not np.array_equal(psm.measured_jp(), q)
    assert np.array_equal(later.arms["PSM1"].measured_js.position, q)
    assert np.array_equal(later.arms["PSM1"].measured_cp.T, cp)
    assert np.array_equal(later.arms["PSM1"].measured_cv.twist, cv)
    sim.close()
