"""The simulated MTM's compiled read (devices/device_row.py) against the Python read it
replaces: the same twist, hand wrench and external force, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from device_helpers import free_mtmr

from davinci_sim.devices import simulated
from davinci_sim.geometry import so3
from davinci_sim.kinematics import jit

pytestmark = pytest.mark.skipif(not jit.ENABLED, reason="numba is off: nothing is compiled")


@pytest.fixture(scope="module")
def homed():
    """MTMR enabled, homed and free (effort mode), with its device; and that state."""
    sim, device = free_mtmr()
    sim.run_for(0.01)
    return sim, device, sim.get_state()


def _target(device) -> np.ndarray:
    T = device.input().T_hrsv_tip.copy()
    T[:3, 3] += (0.02, -0.01, 0.015)
    T[:3, :3] = so3.rotation_from_vector([0.2, -0.3, 0.1]) @ T[:3, :3]
    return T


HANDS = {
    "hand pulling and holding the orientation": lambda d: d.grasp(_target(d)),
    "hand pulling, orientation free": lambda d: d.grasp(_target(d), hold_orientation=False),
    "hand resting on the handle": lambda d: d.grasp(),
    "a push, no hand": lambda d: d.push([0.5, -0.2, 1.0, 0.01, 0.0, -0.02]),
    "a hand and a push": lambda d: (d.grasp(_target(d)), d.push([0.0, 0.0, 2.0])),
    "the hand let go after holding": lambda d: (d.grasp(_target(d)), d.release()),
}


@pytest.mark.parametrize("hand", list(HANDS))
def test_the_compiled_read_is_the_python_read_bit_for_bit(monkeypatch, homed, hand):
    sim, device, start = homed
    runs = []
    for row in (simulated._ROW, None):
        sim.set_state(start)
        monkeypatch.setattr(simulated, "_ROW", row)
        HANDS[hand](device)
        if hand.startswith("the hand let go"):
            sim.run_for(0.02)  # (held first: the wrench applied at the last tick is cleared)
            device.release()
        inputs = []
        for _ in range(150):
            sim.tick()
            inp = device.input()
            inputs.append((inp.T_hrsv_tip.copy(), inp.twist_hrsv_tip.copy(), inp.gripper))
        runs.append(
            (inputs, device.hand_wrench(), device._hand_applied,
             sim.data.xfrc_applied.copy(), sim.data.qpos.copy(), sim.data.qvel.copy())
        )  # fmt: skip
    compiled, python = runs
    for (T_a, tw_a, g_a), (T_b, tw_b, g_b) in zip(compiled[0], python[0], strict=True):
        np.testing.assert_array_equal(T_a, T_b)
        np.testing.assert_array_equal(tw_a, tw_b)
        assert g_a == g_b
    np.testing.assert_array_equal(compiled[1], python[1])
    assert compiled[2] == python[2]
    for a, b in zip(compiled[3:], python[3:], strict=True):
        np.testing.assert_array_equal(a, b)
    assert np.abs(compiled[3]).sum() > 0 or hand.startswith("the hand let go")


def test_the_read_compiles_no_new_signature_in_the_loop(homed):
    from davinci_sim.devices import device_row

    sim, device, start = homed
    sim.set_state(start)
    before = len(device_row.hand_read_row.signatures)
    device.grasp(_target(device))
    device.push([0.0, 0.0, 1.0])
    sim.run_for(0.05)
    device.release()
    device.push(np.zeros(6))
    sim.run_for(0.05)
    assert len(device_row.hand_read_row.signatures) == before


WRENCHES = {
    "within the limits": lambda k: np.array([0.3, -0.2, 0.5, 0.01, -0.02, 0.005]) * (k % 7),
    "over the force limit, clamped": lambda k: np.array([3.0, 2.0, -4.0, 0.0, 0.0, 0.0]),
    "rate limited, changing sign": lambda k: np.array([0.0, 0.0, 3.0 * (-1) ** (k // 10)]
                                                      + [0.0, 0.1, 0.0]),
}  # fmt: skip


@pytest.mark.parametrize("wrench", list(WRENCHES))
def test_the_compiled_render_is_the_python_render_bit_for_bit(monkeypatch, homed, wrench):
    """``_render_wrench`` (the haptic loop's way in) through ``render_row`` and through the
    device's limiter and the arm's ``servo_cf``: the same wrench let through, the same
    limiter state and joint efforts, the same motion."""
    from davinci_sim.devices import device_row

    sim, device, start = homed
    arm = device.arm
    runs = []
    for row in (simulated._ROW, None):
        sim.set_state(start)
        monkeypatch.setattr(simulated, "_ROW", row)
        calls = len(device_row.render_row.signatures)  # (touched: the kernel is loaded)
        device.grasp()
        ticks = []
        for k in range(120):
            assert device._render_wrench(WRENCHES[wrench](k))
            sent = (device.wrench(), device._limiter.previous.copy(), device._limiter.active,
                    arm.wrench_setpoint()[1])  # fmt: skip
            sim.tick()
            # The efforts the step used. (Between two ticks the Python path may still hold
            # the last tick's: it skips a wrench equal to the one the arm renders, which the
            # arm's pre-step then recomputes at the new joints.)
            ticks.append((*sent, sim.servo.tau_ff.copy()))
        runs.append((ticks, sim.data.qpos.copy(), sim.data.qvel.copy()))
        assert len(device_row.render_row.signatures) == calls
    (compiled, q_a, qd_a), (python, q_b, qd_b) = runs
    for a, b in zip(compiled, python, strict=True):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(q_a, q_b)
    np.testing.assert_array_equal(qd_a, qd_b)
    actives = [t[2] for t in compiled]
    assert any(actives)  # (the clamp's branches were taken)
    assert all(actives) or not wrench.startswith("over")
    assert np.abs(compiled[-1][4][arm._idx]).sum() > 0


def test_the_study_hands_are_the_python_hands_bit_for_bit():
    """``device_row.hand_rows`` (the study's hands, every row) equals ``hand_wrenches`` with
    the orientation held, plus the push, through ``handle_xfrc``: the same bits, rows
    clamped and not."""
    from davinci_sim.devices import device_row
    from davinci_sim.devices.hand import HandImpedance, hand_wrenches, handle_xfrc

    rng = np.random.default_rng(11)
    n = 64
    tip = np.tile(np.eye(4), (n, 1, 1))
    target = tip.copy()
    for i in range(n):
        tip[i, :3, :3] = so3.rotation_from_vector(rng.normal(0, 0.5, 3))
        target[i, :3, :3] = so3.rotation_from_vector(rng.normal(0, 0.5, 3))
    tip[:, :3, 3] = rng.normal(0, 0.1, (n, 3))
    target[:, :3, 3] = tip[:, :3, 3] + rng.normal(0, 0.03 * rng.uniform(0, 4, (n, 1)), (n, 3))
    twist, push = rng.normal(0, 0.2, (n, 6)), rng.normal(0, 1.0, (n, 3))
    K, D = rng.uniform(100, 400, n), rng.uniform(2, 20, n)
    h = HandImpedance(max_force=8.0, max_torque=0.2)
    R = so3.rotation_from_vector([0.3, -0.2, 1.1])
    p, com = rng.normal(0, 1, 3), rng.normal(0, 1, (n, 3))
    w = hand_wrenches(target, tip, twist, K, D, h)
    w[:, :3] += push
    expected = handle_xfrc(w, tip[:, :3, 3], R, p, com)
    out = np.empty((n, 6))
    device_row.hand_rows(target, tip, twist, K, D, np.array([h.rotational_stiffness,
                         h.rotational_damping, h.max_force, h.max_torque]), push, R, p, com,
                         out)  # fmt: skip
    assert np.array_equal(out, expected)
    assert (np.linalg.norm(w[:, :3] - push, axis=1) >= 8.0 - 1e-9).any()  # (some clamped)
