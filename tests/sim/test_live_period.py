"""The compiled control period of the live simulation (``sim/live_period.py``) against the
Python ticks it replaces, its oracle: from the same state, the same state after — bit for
bit — including when a tick of the period is refused, faults an arm or diverges."""

import numpy as np
import pytest

from davinci_sim.sim import live_period, simulation
from davinci_sim.sim import operating_state as ops
from davinci_sim.sim.live_period import ArmPeriod, run_period

pytestmark = pytest.mark.skipif(not live_period.COMPILED, reason="numba does not compile here")

K = 20  # ticks per period (the environments' 50 Hz actions)


def _snapshot(sim) -> dict:
    """What the two paths must leave the same (arrays copied)."""
    servo = sim.servo
    return {
        "qpos": sim.data.qpos.copy(),
        "qvel": sim.data.qvel.copy(),
        "ctrl": sim.data.ctrl.copy(),
        "time": sim.data.time,
        "ticks": sim.tick_count,
        "q_ref": servo.q_ref.copy(),
        "qd_ref": servo.qd_ref.copy(),
        "effort": servo.effort_mode.copy(),
        "since": [a._tracking_bad_since for a in sim.arms.values()],
        "states": [a.operating_state().state for a in sim.arms.values()],
        # What the next reader sees (the compiled period leaves them computed at the joints
        # now, a Python tick at its start's): the frames and each arm's kinematics.
        **_readings(sim),
    }


def _readings(sim) -> dict:
    """The base frames and the arms' measured kinematics at the joints now, as the
    simulation's readers get them (its caches or computed)."""
    out = {}
    if sim._frame_plan is not None:
        frames = sim._frames()
        out["frames_key"] = sim._base_frames["frames"][0]
        out["frame_camera"] = frames["camera"].copy()
        for name in sim._frame_plan.arms:
            out[f"frame_{name}"] = frames[name][0].copy()
    for name, arm in sim.arms.items():
        _, T, J = arm._measured_kinematics()
        out[f"T_{name}"], out[f"J_{name}"] = T.copy(), J.copy()
    return out


def _assert_same(a: dict, b: dict) -> None:
    for key in a:
        if isinstance(a[key], np.ndarray):
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)
        else:
            np.testing.assert_equal(a[key], b[key], err_msg=key)


def _messages(sim, run) -> list:
    """The arms' messages (level, text, time) ``run()`` posts."""
    channels = [a.channels for a in sim.arms.values()]
    seen = [len(c.messages) for c in channels]
    run()
    return [(m.level, m.text, m.timestamp)
            for c, n in zip(channels, seen, strict=True) for m in list(c.messages)[n:]]  # fmt: skip


def _both(sim, arm, period, setup=lambda: None, ticks=K, **ramp):
    """Run the period compiled and in Python from the same state (after ``setup()``):
    (compiled, python) snapshots with the messages posted; the simulation is left as the
    Python path left it. ``period.compiled_ticks`` counts the ticks the kernel ran."""
    state = sim.get_state()
    out = []
    run = period.run
    period.compiled_ticks = 0

    def counted(*args, **kwargs):
        before = sim.tick_count
        stop = run(*args, **kwargs)
        period.compiled_ticks += sim.tick_count - before
        return stop

    period.run = counted
    try:
        for p in (period, None):
            sim.set_state(state)
            setup()
            recoveries = sim.recoveries  # (cumulative: not part of the state)
            said = _messages(sim, lambda p=p: run_period(sim, arm, ticks, period=p, **ramp))
            out.append({**_snapshot(sim), "messages": said,
                        "recoveries": sim.recoveries - recoveries})  # fmt: skip
    finally:
        period.run = run
    return out[0], out[1]


def _cartesian_ramp(psm, delta) -> dict:
    T = psm.measured_cp().T
    delta = np.asarray(delta, dtype=float)
    twist = np.concatenate([delta / (K * 0.001), np.zeros(3)])
    return {"cartesian": True, "start": T[:3, 3].copy(), "delta": delta,
            "R_ref_goal": T[:3, :3].copy(), "twist_ref": twist}  # fmt: skip


@pytest.mark.parametrize("frames", ["exact", "held within 1e-6", "set by the user"])
def test_cartesian_periods_are_the_python_ticks_bit_for_bit(psm_sim, monkeypatch, frames):
    sim, psm = psm_sim, psm_sim.arms["PSM1"]
    if frames == "held within 1e-6":
        monkeypatch.setattr(simulation, "BASE_FRAME_TOLERANCE", 1e-6)
    elif frames == "set by the user":
        assert psm.set_base_frame(psm.base_frame()[0].copy(), "ECM")
    period = ArmPeriod(sim, psm)
    assert period.ready(cartesian=True)
    rng = np.random.default_rng(3)
    compiled_ticks = 0
    for _ in range(12):
        compiled, python = _both(sim, psm, period, **_cartesian_ramp(psm, rng.normal(0, 0.004, 3)))
        _assert_same(compiled, python)
        compiled_ticks += period.compiled_ticks
    assert compiled_ticks >= 12 * K * 0.9  # (nearly all compiled: the test compares something)
    assert python["ticks"] > 0 and psm.operating_state().state == ops.ENABLED
    if frames == "exact":  # the frames followed the setup joints' yield in both
        assert python["frames_key"] != b""


@pytest.mark.parametrize("name", ["PSM1", "ECM"])
def test_joint_periods_are_the_python_ticks_bit_for_bit(psm_sim, name):
    sim, arm = psm_sim, psm_sim.arms[name]
    period = ArmPeriod(sim, arm)
    rng = np.random.default_rng(4)
    for _ in range(6):
        q = arm.setpoint_js().position
        delta = rng.normal(0.0, 0.003, arm.dof)  # (feed-forwards within the bounds)
        ramp = {"cartesian": False, "start": q, "delta": delta, "velocity": delta / (K * 0.001)}
        compiled, python = _both(sim, arm, period, **ramp)
        _assert_same(compiled, python)
        assert period.compiled_ticks == K


def test_a_refused_tick_runs_in_python_with_its_refusal(psm_sim):
    """A ramp whose last goal is on the RCM: servo_cp refuses it (the Python path's
    message); the ticks before ran compiled; the same state after."""
    sim, psm = psm_sim, psm_sim.arms["PSM1"]
    period = ArmPeriod(sim, psm)
    T = psm.measured_cp().T
    p_rcm = psm.base_frame()[0][:3, 3]
    ramp = {**_cartesian_ramp(psm, p_rcm - T[:3, 3]), "twist_ref": None}
    calls = []
    run = period.run
    period.run = lambda *a, **k: calls.append(run(*a, **k)) or calls[-1]
    compiled, python = _both(sim, psm, period, **ramp)
    _assert_same(compiled, python)
    assert calls[0] > 1, "the first ticks ran compiled"
    assert any(k > 0 for k in calls), "a tick went to the Python path"
    assert any("servo_cp" in text for _, text, _ in python["messages"])


def test_a_tracking_fault_in_a_period_is_the_python_ticks_fault(psm_sim):
    sim, psm = psm_sim, psm_sim.arms["PSM1"]
    period = ArmPeriod(sim, psm)
    sim._watch._tol[:] = 1e-9  # (every arm is out of tolerance at once)
    ramp = _cartesian_ramp(psm, [0.002, 0.0, 0.0])
    compiled, python = _both(sim, psm, period, ticks=400, **ramp)
    _assert_same(compiled, python)
    assert period.compiled_ticks > 0
    assert ops.FAULT in python["states"]
    assert any("tracking error" in text for _, text, _ in python["messages"])


def test_a_diverging_step_in_a_period_is_undone_as_the_python_tick_undoes_it(psm_sim):
    sim, psm = psm_sim, psm_sim.arms["PSM1"]
    period = ArmPeriod(sim, psm)
    ecm = sim.arms["ECM"]

    def bad_setpoint():  # written between ticks: a bad ctrl in the period's first step
        sim.servo.q_ref[ecm._idx[0]] = 1e12

    ramp = _cartesian_ramp(psm, [0.0, 0.002, 0.0])
    compiled, python = _both(sim, psm, period, setup=bad_setpoint, **ramp)
    _assert_same(compiled, python)
    assert period.compiled_ticks > 0  # (the ticks after the recovery)
    assert python["recoveries"] == 1
    assert ecm.operating_state().state == ops.FAULT
    assert psm.operating_state().state == ops.ENABLED
    assert any("diverged" in text for _, text, _ in python["messages"])


def test_ticks_stay_in_python_while_anything_else_needs_them(psm_sim):
    sim, psm = psm_sim, psm_sim.arms["PSM1"]
    period = ArmPeriod(sim, psm)
    assert period.ready(cartesian=True) and period.ready(cartesian=False)
    state = sim.get_state()
    sim.arms["ECM"].move_jr(np.array([0.01, 0.0, 0.0, 0.0]))  # a trajectory to sample
    assert not period.ready(cartesian=True)
    sim.set_state(state)
    psm.servo_jf(np.zeros(psm.dof))  # effort mode: a servo_cp would switch it off first
    assert not period.ready(cartesian=True)
    sim.set_state(state)
    sim.encoder_noise_std = 1e-6  # noise drawn every tick
    assert not period.ready(cartesian=True)
    sim.encoder_noise_std = 0.0
    psm.state_command("disable")
    assert not period.ready(cartesian=False)
    sim.set_state(state)
    assert period.ready(cartesian=True)


def test_the_kernel_keeps_its_one_compiled_signature(psm_sim):
    """A PSM's Cartesian period and the ECM's joint period (no IK, no frame plan of its
    own) bind arguments of one type: the kernel compiled once, at import."""
    sim, psm, ecm = psm_sim, psm_sim.arms["PSM1"], psm_sim.arms["ECM"]
    run_period(sim, psm, K, period=ArmPeriod(sim, psm),
               **_cartesian_ramp(psm, [0.001, 0.0, 0.0]))  # fmt: skip
    q, period = ecm.setpoint_js().position, ArmPeriod(sim, ecm)
    assert period.ready(cartesian=False)
    run_period(sim, ecm, K, period=period, cartesian=False, start=q,
               delta=np.full(4, 1e-4), velocity=np.full(4, 1e-4 / (K * 0.001)))  # fmt: skip
    assert len(live_period._BOUND_KERNEL.signatures) == 1


def test_the_warning_counters_are_found_and_left_unchanged(psm_sim):
    data = psm_sim.data
    before = [(w.lastinfo, w.number) for w in data.warning]
    assert live_period.warning_address(data) is not None
    assert [(w.lastinfo, w.number) for w in data.warning] == before


@pytest.mark.parametrize("contacts", [True, False])
def test_a_recorded_period_gives_each_ticks_sample_as_the_python_ticks(psm_sim, contacts):
    """A caller that samples the state after every tick gets the same samples, bit for bit,
    from a compiled period's records as from Python ticks: where steps leave contacts (the
    scene's bead) the kernel stops at each and the caller samples the state itself."""
    import mujoco

    sim, psm = psm_sim, psm_sim.arms["PSM1"]
    if not contacts:
        sim.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
        sim.tick()
    period = ArmPeriod(sim, psm)
    assert period.can_record(cartesian=True)
    state = sim.get_state()
    runs = []
    for p in (period, None):
        sim.set_state(state)
        seen, recorded_ticks = [], []

        def sample():  # what a sampler reads after a tick (the environment's task)
            return (sim.time, psm._q().copy(), sim.T_cart_camera().copy(),
                    psm.base_frame()[0].copy(), sim.data.ncon)  # fmt: skip

        def recorded(samples, ticks, seen=seen, counted=recorded_ticks):
            counted.append(len(ticks))
            for k in ticks:
                seen.append((samples.t[k], samples.q[k].copy(), samples.frames[k, 0].copy(),
                             samples.frames[k, 1].copy(), 0))  # fmt: skip

        rng = np.random.default_rng(4)
        for _ in range(6):
            ramp = _cartesian_ramp(psm, rng.uniform(-0.002, 0.002, 3))
            run_period(sim, psm, K, period=p, after_tick=lambda seen=seen: seen.append(sample()),
                       recorded=recorded, **ramp)  # fmt: skip
        runs.append((seen, _snapshot(sim), sum(recorded_ticks)))
    (compiled, after_c, from_records), (python, after_p, _) = runs
    assert len(compiled) == len(python) == 6 * K
    for k, (a, b) in enumerate(zip(compiled, python, strict=True)):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y, err_msg=f"tick {k}")
    _assert_same(after_c, after_p)
    if contacts:
        assert python[-1][4] > 0 and from_records == 0  # (each step left contacts)
    else:  # (every tick: each period's last one kept from the state it left, record_last)
        assert from_records == 6 * K
