"""The simulated MTM device: the hand moves the handle, wrenches are limited, the MTM's
orientation lock, and bad inputs."""

import math
import pickle

import numpy as np
import pytest
from device_helpers import free_mtmr

from davinci_sim.devices import HandImpedance, SimulatedMTM, hand_wrenches
from davinci_sim.geometry import so3


@pytest.fixture
def mtm_sim():
    """MTMR enabled, homed and free (effort mode, gravity compensated), as when following."""
    sim, device = free_mtmr()
    sim.tick()
    return sim, device


def test_the_hand_moves_the_handle_to_its_target(mtm_sim):
    sim, device = mtm_sim
    p0 = device.input().position.copy()
    device.grasp(p0 + [0.04, -0.03, 0.02])
    sim.run_for(1.0)
    assert np.linalg.norm(device.input().position - (p0 + [0.04, -0.03, 0.02])) < 0.004
    assert device.input().T_hrsv_tip[:3, 3] @ [1, 0, 0] > p0[0]
    # Orientation target: the hand turns the handle too.
    target = device.input().T_hrsv_tip.copy()
    R_target = so3.rotation_from_vector([0.0, 0.0, 0.3]) @ target[:3, :3]
    target[:3, :3] = R_target
    device.grasp(target)
    sim.run_for(1.0)
    assert so3.angle_between(device.input().rotation, R_target) < math.radians(3)
    assert device.squeeze(math.radians(25))
    sim.run_for(0.3)
    assert device.input().gripper == pytest.approx(math.radians(25), abs=2e-3)
    device.release()
    assert device.hand_target() is None
    assert not np.any(sim.data.xfrc_applied)


def test_a_push_moves_the_handle_along_the_force(mtm_sim):
    sim, device = mtm_sim
    p0 = device.input().position.copy()
    device.push([0.0, 0.0, 1.5])  # 1.5 N away from the operator (HRSV z)
    sim.run_for(0.15)
    d = device.input().position - p0
    assert d[2] > 0.005 and abs(d[0]) < 0.5 * d[2]
    device.push(np.zeros(3))
    sim.tick()
    assert not np.any(sim.data.xfrc_applied)


def test_wrenches_are_clamped_in_magnitude_and_rate(mtm_sim):
    sim, device = mtm_sim
    assert device.servo_cf([30.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(device.wrench(), [0.5, 0, 0, 0, 0, 0])  # 500 N/s x 1 ms
    kind, applied = sim.arms["MTMR"].wrench_setpoint()
    assert kind == "spatial"
    np.testing.assert_allclose(applied, device.wrench())
    for _ in range(20):
        device.servo_cf([30.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(device.wrench(), [4.0, 0, 0, 0, 0, 0])  # max_force
    assert device.snapshot().wrench_limited
    result = device.servo_cf([np.nan] * 6)
    assert not result and "finite" in result.message
    np.testing.assert_allclose(device.wrench(), [4.0, 0, 0, 0, 0, 0])  # unchanged
    device.zero_wrench()
    np.testing.assert_array_equal(device.wrench(), np.zeros(6))
    snap = pickle.loads(pickle.dumps(device.snapshot()))
    assert snap.kind == "simulated" and snap.ready and not snap.stale


def test_locked_orientation_holds_while_the_hand_moves_the_handle(mtm_sim):
    sim, device = mtm_sim
    arm = sim.arms["MTMR"]
    R0 = device.input().rotation.copy()
    device.lock_orientation(R0)
    assert arm.orientation_locked()
    device.grasp(device.input().position + [0.05, 0.03, -0.02], hold_orientation=False)
    sim.run_for(1.0)
    assert np.linalg.norm(device.input().position - device.hand_target()[:3, 3]) < 0.005
    assert so3.angle_between(device.input().rotation, R0) < math.radians(1.0)
    assert not arm.lock_orientation(np.eye(3) * 2)  # not a rotation: refused
    assert arm.orientation_locked()
    device.unlock_orientation()
    assert not arm.orientation_locked()


def test_bad_hand_inputs_raise_and_change_nothing(mtm_sim):
    sim, device = mtm_sim
    device.grasp()
    target = device.hand_target()
    with pytest.raises(ValueError, match="finite"):
        device.move_hand([np.nan, 0.0, 0.0])
    with pytest.raises(ValueError, match="rotation"):
        device.grasp(np.diag([1.0, 2.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="3 or 6"):
        device.push([1.0, 2.0])
    with pytest.raises(ValueError, match="6 finite"):
        device.move_hand(target[:3, 3] + 0.01, velocity=[0.1, 0.0, np.inf, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="6 finite"):
        device.move_hand(target[:3, 3] + 0.01, velocity=[0.1, 0.0, 0.0])
    np.testing.assert_array_equal(device.hand_target(), target)
    assert not device.get_state()["_hand_velocity"].any()
    with pytest.raises(KeyError, match="MTMs"):
        SimulatedMTM(sim, "MTML")
    with pytest.raises(ValueError, match="damping"):
        HandImpedance(damping=-1.0)


def hand_wrench(target, T, twist, imp, *, hold_orientation=True):
    """One hand: the law as a batch of one, as SimulatedMTM calls it."""
    target = None if target is None else target[None]
    return hand_wrenches(
        target, T[None], twist[None], (imp.stiffness,), (imp.damping,), imp,
        hold_orientation=hold_orientation,
    )[0]  # fmt: skip


def test_hand_law():
    T = np.eye(4)
    target = np.eye(4)
    target[:3, 3] = [0.01, 0.0, 0.0]
    imp = HandImpedance(stiffness=100.0, damping=2.0, max_force=5.0)
    w = hand_wrench(target, T, np.array([0.1, 0, 0, 0, 0, 0]), imp)
    np.testing.assert_allclose(w, [100 * 0.01 - 2 * 0.1, 0, 0, 0, 0, 0])
    far = np.eye(4)
    far[:3, 3] = [1.0, 0.0, 0.0]
    assert np.linalg.norm(hand_wrench(far, T, np.zeros(6), imp)[:3]) == pytest.approx(5.0)
    turned = np.eye(4)
    turned[:3, :3] = so3.rotation_from_vector([0, 0, 0.2])
    w = hand_wrench(turned, T, np.zeros(6), imp)
    np.testing.assert_allclose(w[3:], [0, 0, imp.rotational_stiffness * 0.2], atol=1e-12)
    assert not hand_wrench(turned, T, np.zeros(6), imp, hold_orientation=False)[3:].any()
    np.testing.assert_allclose(hand_wrench(None, T, np.array([1.0, 0, 0, 0, 0, 0]), imp)[0], -2.0)


def test_a_hand_moving_with_its_target_damps_the_handle_only_relative_to_itself(mtm_sim):
    """A target moved at the handle's own velocity (``move_hand``'s ``velocity``: a rate
    input's hand moving at its key's speed) pulls nothing and damps nothing: the law is
    ``K·(p_target − p) + D·(v_target − v)``; the velocity holds for one read, after which
    the same target at rest damps the handle's motion, ``−D·v``."""
    sim, device = mtm_sim
    device.grasp()
    device.push([0.0, 2.0, 0.0])  # (the handle moving, its wrist turning a little)
    sim.run_for(0.05)
    device.push(np.zeros(6))
    arm = device.arm
    T, twist = arm._measured_T().copy(), arm._measured_twist().copy()
    assert np.linalg.norm(twist[:3]) > 0.005  # m/s
    device.move_hand(T, velocity=twist)  # (the pose and twist the next read measures)
    sim.tick()
    np.testing.assert_allclose(device.hand_wrench(), np.zeros(6), atol=1e-9)
    assert not device.get_state()["_hand_velocity"].any()  # used up
    T, twist = arm._measured_T().copy(), arm._measured_twist().copy()
    device.move_hand(T)
    sim.tick()
    np.testing.assert_allclose(device.hand_wrench()[:3], -device.hand.damping * twist[:3],
                               rtol=1e-9)  # fmt: skip


def test_the_device_state_restores_the_hand_its_limiter_and_the_hand_mass(mtm_sim):
    sim, device = mtm_sim
    hand_mass = sim.model.body_mass[device.hand_body]
    state = device.get_state()
    device.hand = HandImpedance(mass=0.7)
    device.grasp(device.input().position + [0.0, 0.05, 0.0])
    device.servo_cf([3.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    sim.run_for(0.05)
    assert sim.model.body_mass[device.hand_body] == 0.7
    device.set_state(state)
    assert sim.model.body_mass[device.hand_body] == hand_mass
    assert device.hand == state["hand"] and not device.get_state()["_hand_on"]
    np.testing.assert_array_equal(device.get_state()["limiter"][0], state["limiter"][0])
    # (what the MTM renders is the arm's wrench setpoint: the arm's state, Simulation.set_state)
    np.testing.assert_array_equal(device.get_state()["_wrench"], state["_wrench"])
