"""The in-process loop runner: pacing, statistics of a paced loop, scheduled inputs, and the
same results in real-time and as-fast-as-possible runs."""

import numpy as np
import pytest

from davinci_sim.console import SIMULATED_SYSTEM, install_console
from davinci_sim.sim.runtime import LoopRunner, Pacer
from davinci_sim.sim.runtime.loop import IDLE_WINDOW
from davinci_sim.sim.simulation import Simulation


class VirtualClock:
    """A wall clock that moves by ``step`` s per reading and by exactly what is slept: the
    pacing is tested on it, not on the machine's load."""

    def __init__(self, step: float = 2e-6) -> None:
        self.now = 0.0
        self.step = step
        self.sleeps: list[float] = []

    def clock(self) -> float:
        self.now += self.step
        return self.now

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.now += seconds


def test_paced_loop_statistics_are_consistent():
    sim = Simulation("psm1")
    v = VirtualClock()
    stats = LoopRunner(sim, real_time=True, spin=0.0, clock=v.clock, sleep=v.sleep).run(ticks=200)
    assert stats.ticks == 200 and stats.real_time
    assert sim.tick_count == 200 and sim.time == pytest.approx(0.2)
    # Paced: tick k starts at its deadline, k periods after the first one; the loop waits
    # (sleeps) for every tick and never longer than a period.
    assert len(v.sleeps) == 200 and max(v.sleeps) <= sim.dt
    assert stats.elapsed == pytest.approx(199 * sim.dt, abs=1e-5)
    assert stats.achieved_rate_hz == pytest.approx(199 / stats.elapsed)
    assert stats.period_mean == pytest.approx(stats.elapsed / 199)
    assert abs(stats.period_p50 - sim.dt) <= 2e-5 and stats.period_max < 1.5 * sim.dt
    assert stats.compute_p50 <= stats.compute_max < sim.dt
    assert stats.late_periods == 0 and stats.overruns == 0 and stats.resyncs == 0


def test_a_faster_pace_shortens_the_period():
    """``speed``: simulated seconds per wall second (a replay at 4x: a tick every 0.25 ms)."""
    sim = Simulation("psm1")
    v = VirtualClock()
    runner = LoopRunner(sim, real_time=True, speed=4.0, spin=0.0, clock=v.clock, sleep=v.sleep)
    stats = runner.run(ticks=100)
    assert sim.time == pytest.approx(0.1) and stats.elapsed == pytest.approx(99 * sim.dt / 4)
    with pytest.raises(ValueError, match="speed"):
        LoopRunner(sim, speed=0.0)


def test_fast_loop_and_until():
    sim = Simulation("psm1")
    runner = LoopRunner(sim, real_time=False)
    stats = runner.run(until=lambda: sim.tick_count >= 50)
    assert stats.ticks == 50 and not stats.real_time
    with pytest.raises(ValueError, match="ticks or until"):
        runner.run()


def test_pacer_resyncs_after_a_long_stall(monkeypatch):
    now = [0.0]
    monkeypatch.setattr(
        "davinci_sim.sim.runtime.loop.time.sleep", lambda s: now.__setitem__(0, now[0] + s)
    )

    def clock():
        now[0] += 1e-6
        return now[0]

    pacer = Pacer(0.001, spin=0.0, max_lag=0.05, clock=clock)
    pacer.start()
    assert not pacer.wait()
    assert now[0] >= 0.001
    now[0] += 0.2  # a 200 ms stall
    assert pacer.wait()  # the backlog is dropped
    assert not pacer.wait()  # and pacing goes on from now
    with pytest.raises(ValueError):
        Pacer(0.0)


def test_call_at_runs_before_the_given_tick():
    sim = Simulation("psm1")
    runner = LoopRunner(sim, real_time=False)
    seen = []
    runner.call_at(3, lambda: seen.append(sim.tick_count))
    runner.call_at(0, lambda: seen.append(sim.tick_count))
    runner.run(ticks=5)
    assert seen == [0, 3] and runner.pending() == 0
    with pytest.raises(ValueError, match="already run"):
        runner.call_at(2, print)


def scripted_teleop_run(real_time: bool) -> Simulation:
    sim = Simulation("psm1_ecm_mtmr", keyframe="surgical")
    console = install_console(sim, teleop_config=SIMULATED_SYSTEM.replace(align_mtm=False))
    device = sim.components["MTMR/device"]
    runner = LoopRunner(sim, real_time=real_time)
    runner.call_at(2, console.emulate_operator_present, [1])
    runner.call_at(2, console.teleop_enable, True)
    runner.call_at(20, device.grasp)
    runner.call_at(40, lambda: device.move_hand(device.input().position + [0.01, 0.0, 0.0]))
    runner.call_at(150, device.squeeze, 0.4)
    runner.call_at(200, console.emulate_clutch, [1])
    runner.run(ticks=300)
    return sim


def test_real_time_and_fast_runs_give_identical_results():
    paced = scripted_teleop_run(real_time=True)
    fast = scripted_teleop_run(real_time=False)
    assert paced.components["MTMR_PSM1"].current_state() == "ENABLED"
    assert np.linalg.norm(paced.arms["PSM1"].setpoint_jp() - paced.arms["PSM1"].kin.home) > 1e-3
    np.testing.assert_array_equal(paced.data.qpos, fast.data.qpos)
    np.testing.assert_array_equal(paced.data.qvel, fast.data.qvel)


@pytest.mark.parametrize("compute", [0.0015, 0.0009])  # behind real time; just keeping up
def test_a_real_time_loop_sleeps_its_idle_share_in_short_sleeps(compute):
    """A FIFO loop that never sleeps is stopped by Linux for 50 ms a second: with
    ``min_idle`` the pacer sleeps that share itself, at most one window's worth at a time."""
    v = VirtualClock(step=0.0)
    pacer = Pacer(0.001, spin=0.0, max_lag=10.0, clock=v.clock, sleep=v.sleep, min_idle=0.06)
    pacer.start()
    for _ in range(2000):
        pacer.wait()
        v.now += compute  # the tick's computation
    elapsed = v.now
    assert sum(v.sleeps) >= 0.06 * elapsed - IDLE_WINDOW  # the share, up to the last window
    assert max(v.sleeps) <= 0.06 * 2 * IDLE_WINDOW  # short sleeps, never a long stop
    # Without it, a loop behind real time never sleeps.
    v = VirtualClock(step=0.0)
    pacer = Pacer(0.001, spin=0.0, max_lag=10.0, clock=v.clock, sleep=v.sleep)
    pacer.start()
    for _ in range(200):
        pacer.wait()
        v.now += 0.0015
    assert v.sleeps == [pytest.approx(0.001)]  # (only the first period's wait)
    with pytest.raises(ValueError):
        Pacer(0.001, min_idle=1.0)


def test_realtime_idle_share_follows_the_kernels_limit(monkeypatch):
    import builtins
    import io

    from davinci_sim.sim.runtime.loop import realtime_idle_share

    files = {"/proc/sys/kernel/sched_rt_runtime_us": "950000\n",
             "/proc/sys/kernel/sched_rt_period_us": "1000000\n"}  # fmt: skip
    real_open = builtins.open
    monkeypatch.setattr(
        builtins,
        "open",
        lambda f, *a, **k: io.StringIO(files[f]) if f in files else real_open(f, *a, **k),
    )
    assert realtime_idle_share() == pytest.approx(0.06)  # Linux's default: 5 %, and 1 point
    files["/proc/sys/kernel/sched_rt_runtime_us"] = "-1\n"  # no limit
    assert realtime_idle_share() == 0.0


def test_frozen_heap_keeps_what_is_alive_out_of_collections_until_exit():
    """A long-running process freezes its start-up heap for its run: a full collection then
    scans only what was made since (one over ``serve``'s start-up heap stalled its topics)."""
    import gc

    from davinci_sim.sim.runtime.loop import frozen_heap

    kept = [[k] for k in range(1000)]  # tracked containers alive at "start-up"
    before = gc.get_freeze_count()
    with frozen_heap():
        assert gc.get_freeze_count() >= before + len(kept)
        made_later = [[k] for k in range(10)]
        tracked = {id(o) for o in gc.get_objects()}
        assert not any(id(o) in tracked for o in kept)  # out of the collector's reach
        assert all(id(o) in tracked for o in made_later)  # later objects are collected
    assert gc.get_freeze_count() == 0  # back in reach: garbage among them can be freed
    tracked = {id(o) for o in gc.get_objects()}
    assert all(id(o) in tracked for o in kept)
