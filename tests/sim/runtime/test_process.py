"""The loop in its own process behind the SimHandle protocol: calls, snapshots, events,
deterministic scheduled inputs, statistics and the stereo render process."""

import functools
import time

import numpy as np
import pytest

from davinci_sim.console import SIMULATED_SYSTEM
from davinci_sim.sim.runtime import LoopProcessError, ProcessSimulation
from davinci_sim.sim.simulation import Simulation
from davinci_sim.system import (
    ConsoleDescription,
    SystemDescription,
    TaskDescription,
    build_simulation,
)
from davinci_sim.tasks.session import VIEW_DISTANCE

FACTORY = functools.partial(
    build_simulation,
    SystemDescription(
        "psm1_ecm_mtmr",
        console=ConsoleDescription(teleop=SIMULATED_SYSTEM.replace(align_mtm=False)),
    ),
)


def scripted(real_time: bool):
    """Inputs at given ticks; the loop stops by itself before tick 400."""
    handle = ProcessSimulation(
        FACTORY, real_time=real_time, stop_at_tick=400, start_paused=True
    ).start()
    try:
        futures = [
            handle.call_at(2, "console", "emulate_operator_present", [1]),
            handle.call_at(2, "console", "teleop_enable", True),
            handle.call_at(30, "MTMR/device", "grasp"),
            handle.call_at(60, "MTMR/device", "push", [0.0, 0.5, 0.0]),
            handle.call_at(200, "console", "emulate_clutch", [1]),
        ]
        handle.resume()
        assert handle.wait_stopped(60)
        assert all(f.result(5) is None or bool(f.result(5)) for f in futures)
        return handle.snapshot(), handle.period_statistics()
    finally:
        handle.stop()


def test_real_time_and_fast_processes_give_identical_results():
    fast, fast_stats = scripted(real_time=False)
    paced, paced_stats = scripted(real_time=True)
    assert fast.tick == paced.tick == 400
    assert paced_stats.real_time and not fast_stats.real_time and paced_stats.ticks == 400
    for name, arm in fast.arms.items():
        np.testing.assert_array_equal(
            arm.measured_js.position, paced.arms[name].measured_js.position
        )
        np.testing.assert_array_equal(
            arm.setpoint_js.position, paced.arms[name].setpoint_js.position
        )
    teleop = paced.extras["MTMR_PSM1"]
    assert teleop.current_state == "ENABLED" and teleop.clutched and not teleop.following
    assert paced.extras["console"].buttons["clutch"]


def test_calls_snapshots_events_and_errors():
    with ProcessSimulation(FACTORY, real_time=False, snapshot_period=0.002) as handle:
        events = []
        handle.subscribe(lambda source, event, payload: events.append((source, event)))
        assert handle.call("console", "emulate_operator_present", [1]).result(10)
        assert handle.call("console", "teleop_enable", True).result(10)
        snap = handle.snapshot()
        assert handle.wait_for_tick(snap.tick + 300, 30)
        snap = handle.snapshot()
        assert snap.extras["MTMR_PSM1"].following
        assert snap.arms["PSM1"].measured_cp.reference_frame == "ECM"
        assert snap.arms["PSM1"].operating_state.is_homed
        q = handle.call("PSM1", "measured_jp").result(10)
        assert q.shape == (6,)
        with pytest.raises(KeyError, match="unknown target"):
            handle.call("PSM9", "hold").result(10)
        with pytest.raises(AttributeError, match="public"):
            handle.call("console", "_handle", "clutch", 1).result(10)
        assert not handle.call("MTMR_PSM1", "set_scale", 7.0).result(10)  # refused, no raise
        with pytest.raises(ValueError, match="already run"):
            handle.call_at(1, "console", "teleop_enable", False).result(10)
        stats = handle.period_statistics()
        assert stats.ticks > 0 and stats.period_p50 <= stats.period_p99 <= stats.period_max
        with pytest.raises(LoopProcessError, match="render_hz"):
            handle.stereo_frame()
    sources = {s for s, _ in events}
    assert {"MTMR_PSM1", "console", "PSM1"} <= sources
    assert ("MTMR_PSM1", "following") in events
    assert handle.stop().ticks == stats.ticks or handle.stop().ticks >= stats.ticks
    # After stop() the shared memory is gone: a reader (a web view's thread) gets an error.
    with pytest.raises(LoopProcessError, match="not running"):
        handle.snapshot()


def test_a_failing_factory_reports_its_traceback():
    handle = ProcessSimulation(functools.partial(Simulation, "no_such_scene"))
    with pytest.raises(LoopProcessError, match="unknown scene"):
        handle.start()
    handle.stop()


def test_stereo_rendering_in_its_own_process():
    with ProcessSimulation(FACTORY, real_time=True, render_hz=30) as handle:
        frame = None
        deadline = time.monotonic() + 120.0  # (the render process's EGL start on a busy machine)
        while time.monotonic() < deadline:
            handle.wait_for_tick(handle.snapshot().tick + 10, 5)
            frame = handle.stereo_frame()
            if frame is not None and frame.frame >= 2:
                break
        assert frame is not None and frame.frame >= 2
        assert frame.left.shape == frame.right.shape == (480, 640, 3)
        assert frame.left.std() > 10 and not np.array_equal(frame.left, frame.right)
        assert 0 <= frame.tick <= handle.snapshot().tick
        rs = handle.render_statistics()
        assert rs.frames >= 2 and rs.render_mean > 0


def test_the_readers_snapshot_is_the_loops_own():
    """The reader computes an arm's fields on its mirror when they are read: every field
    equals what ``take_snapshot`` gives in a simulation at the same tick, and a snapshot
    sent elsewhere (pickled) is complete."""
    import pickle

    from davinci_sim.sim.handle import take_snapshot

    with ProcessSimulation(FACTORY, real_time=False, stop_at_tick=60) as handle:
        assert handle.wait_stopped(60)
        snap = handle.snapshot()
    local = FACTORY()
    while local.tick_count < snap.tick:
        local.tick()
    reference = take_snapshot(local)
    assert snap.tick == reference.tick == 60 and set(snap.arms) == set(reference.arms)
    fields = ("measured_js", "setpoint_js", "jaw_measured_js", "jaw_setpoint_js",
              "gripper_measured_js")  # fmt: skip
    for name, ref in reference.arms.items():
        a = snap.arms[name]
        assert a.operating_state.state == ref.operating_state.state and a.arm_type == ref.arm_type
        for f in fields:
            mine, theirs = getattr(a, f), getattr(ref, f)
            assert (mine is None) == (theirs is None), (name, f)
            if mine is not None:
                assert mine.name == theirs.name and mine.timestamp == theirs.timestamp
                for v in ("position", "velocity", "effort"):
                    x, y = getattr(mine, v), getattr(theirs, v)
                    assert (x is None and y is None) or np.array_equal(x, y), (name, f, v)
        np.testing.assert_array_equal(a.measured_cp.T, ref.measured_cp.T)
        assert a.measured_cp.reference_frame == ref.measured_cp.reference_frame
    sent = pickle.loads(pickle.dumps(snap))
    np.testing.assert_array_equal(
        sent.arms["PSM1"].setpoint_js.position, reference.arms["PSM1"].setpoint_js.position
    )
    local.close()


def test_the_latest_joints_are_the_loops_own_after_every_tick():
    """``latest_qpos``: the joints the loop wrote after its last tick (every tick, where
    the published state comes every snapshot period), equal to a simulation's at that
    tick; none once stopped."""
    with ProcessSimulation(FACTORY, real_time=False, stop_at_tick=73, snapshot_period=0.05,
                           start_paused=True) as handle:  # fmt: skip
        assert handle.latest_qpos()[0] == 0  # (written before the first tick)
        handle.resume()
        assert handle.wait_stopped(60)
        tick, t, qpos = handle.latest_qpos()
    assert handle.latest_qpos() is None
    local = FACTORY()
    while local.tick_count < tick:
        local.tick()
    assert tick == 73 and t == local.time
    np.testing.assert_array_equal(qpos, local.data.qpos)


def test_a_state_taken_in_one_loop_process_resumes_bit_identically_in_another():
    """A GUI's "restart" or a saved session: the state crosses the pipe (pickled, MjData
    included) and a fresh loop process restored with it runs on exactly as the first did."""
    first = ProcessSimulation(FACTORY, real_time=False, start_paused=True, stop_at_tick=401)
    first.start()
    try:
        first.call_at(2, "console", "emulate_operator_present", [1])
        first.call_at(2, "console", "teleop_enable", True)
        first.call_at(30, "MTMR/device", "grasp")
        first.call_at(60, "MTMR/device", "push", [0.0, 0.5, 0.0])
        saved = first.call_at(300, "sim", "get_state")
        q_first = first.call_at(400, "sim", "measured_qpos")
        first.resume()
        saved, q_first = saved.result(60), q_first.result(60)
    finally:
        first.stop()
    assert saved.tick_count == 300

    second = ProcessSimulation(FACTORY, real_time=False, start_paused=True, stop_at_tick=401)
    second.start()
    try:
        restored = second.call_at(0, "sim", "set_state", saved)
        q_second = second.call_at(400, "sim", "measured_qpos")
        second.resume()
        restored.result(60)
        q_second = q_second.result(60)
        snap = second.snapshot()
    finally:
        second.stop()
    np.testing.assert_array_equal(q_second, q_first)
    assert snap.extras["MTMR_PSM1"].following  # the console's state came along


def test_the_loop_gets_sched_fifo_once_its_simulation_is_built():
    """``realtime_priority``: the loop process runs on SCHED_FIFO (where the privilege is
    granted; otherwise ``info`` says why not) and still ticks; the policy is set after the
    build, so the build's seconds do not use up Linux's real-time share."""
    import os

    if not hasattr(os, "sched_getscheduler"):
        pytest.skip("no POSIX scheduling policies here")
    with ProcessSimulation(
        functools.partial(Simulation, "psm1"), real_time=True, realtime_priority=1
    ) as handle:
        info = handle.info
        if info.get("realtime_priority") is None:
            assert info["realtime_priority_error"]  # (said, not silently ignored)
            pytest.skip(f"SCHED_FIFO not granted here: {info['realtime_priority_error']}")
        assert info["realtime_priority"] == 1
        assert os.sched_getscheduler(info["pid"]) == os.SCHED_FIFO
        tick = handle.snapshot().tick
        deadline = time.monotonic() + 30
        while handle.snapshot().tick < tick + 200 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert handle.snapshot().tick >= tick + 200  # the real-time loop runs


def test_a_stepped_loop_ticks_what_it_is_asked_for_and_serves_calls_between():
    """``stepped``: no tick until ``advance``; each advance runs exactly its ticks after the
    ones asked for before, its future answered once the state there is published; a call
    sent before an advance is served before its ticks (the clutch pressed at the start of
    the third advance's ticks, not after them), and calls are served while the loop waits."""
    with pytest.raises(ValueError, match="real_time"):
        ProcessSimulation(FACTORY, stepped=True)
    with ProcessSimulation(FACTORY, real_time=False, stepped=True) as handle:
        assert handle.stepped
        start = handle.snapshot().tick
        time.sleep(0.3)  # (wall time passes; simulated time does not)
        assert handle.snapshot().tick == start
        assert handle.call("console", "emulate_operator_present", [1]).result(10)
        assert handle.call("console", "teleop_enable", True).result(10)
        first = handle.advance(0.031)  # 31 ticks: not a multiple of the snapshot period
        second = handle.advance(0.05)
        assert first.result(30) == start + 31
        assert second.result(30) == start + 81
        assert handle.snapshot().tick == start + 81  # (published where it stopped)
        clutch = handle.call("console", "emulate_clutch", [1])
        third = handle.advance(0.001)
        assert clutch.result(10) is None or clutch.result(10)
        assert third.result(30) == start + 82
        snap = handle.snapshot()
        assert snap.tick == start + 82 and snap.extras["console"].buttons["clutch"]
        with pytest.raises(ValueError, match="seconds"):
            handle.advance(0.0)
    with ProcessSimulation(FACTORY, real_time=False) as free:
        with pytest.raises(RuntimeError, match="not stepped"):
            free.advance(0.01)


def test_calls_a_stepped_loop_serves_while_it_waits_reach_its_compiled_ticks():
    """A console in its steady state runs its ticks in the compiled engine, which keeps its
    plan while no call is served: calls served while a stepped loop waits for an advance
    must count as served for its first ticks (the web console's person took control
    between two advances, and the teleoperation, told to enable, stayed DISABLED)."""
    task = TaskDescription("needle_targeting", frame_view=VIEW_DISTANCE)
    console = ConsoleDescription(hand_inputs=("MTMR",))
    description = SystemDescription("psm1_ecm_mtmr", console=console, task=task, home=True)
    factory = functools.partial(build_simulation, description)
    with ProcessSimulation(factory, real_time=False, stepped=True) as handle:
        handle.advance(0.5).result(60)
        while handle.snapshot().extras["task"].phase != "READY":  # (the tool at its start)
            assert handle.advance(0.5).result(60) < 30_000
        assert handle.snapshot().extras["MTMR_PSM1"].current_state == "DISABLED"
        for call in [("console", "press", "operator_present"), ("console", "teleop_enable", True)]:
            assert handle.call(*call).result(10)
        time.sleep(0.2)  # (served while the loop waits: the advance comes after)
        handle.advance(0.2).result(60)
        assert handle.snapshot().extras["MTMR_PSM1"].current_state != "DISABLED"
