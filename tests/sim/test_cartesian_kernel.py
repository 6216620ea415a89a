"""``servo_cp``'s compiled law (``sim/cartesian_kernel.py``) against the arm's Python path,
its oracle: the same joint goal and feed-forward to rounding, and every answer it has no
compiled form of left to the Python path."""

import numpy as np
import pytest

from davinci_sim.geometry import so3
from davinci_sim.sim import arms as arm_types
from davinci_sim.sim.arm import Arm

pytestmark = pytest.mark.skipif(arm_types._CP is None, reason="numba does not compile here")


def _setpoints(sim, psm) -> tuple[np.ndarray, np.ndarray]:
    servo = sim.servo
    return servo.q_ref[psm._idx].copy(), servo.qd_ref[psm._idx].copy()


def _both(sim, psm, goal, twist):
    """(compiled answer?, its setpoints, the Python path's result and setpoints), from the
    same state."""
    state = sim.get_state()
    used = psm._servo_cp_compiled(goal, twist, checked=False)
    compiled = _setpoints(sim, psm)
    sim.set_state(state)
    result = Arm._servo_cp(psm, goal, twist, checked=False)
    python = _setpoints(sim, psm)
    sim.set_state(state)
    return used, compiled, result, python


def test_compiled_servo_cp_is_the_python_path(psm_sim):
    sim, psm = psm_sim, psm_sim.arms["PSM1"]
    rng = np.random.default_rng(7)
    T0 = psm.measured_cp().T
    used_count = 0
    for k in range(120):
        goal = T0.copy()
        goal[:3, 3] += rng.normal(0.0, 0.01, 3)
        goal[:3, :3] = so3.rotation_from_vector(rng.normal(0.0, 0.3, 3)) @ T0[:3, :3]
        twist = None if k % 4 == 0 else rng.normal(0.0, [0.02] * 3 + [0.2] * 3)
        used, (q_c, qd_c), result, (q_p, qd_p) = _both(sim, psm, goal, twist)
        if used:
            used_count += 1
            assert result, result.message
            np.testing.assert_allclose(q_c, q_p, rtol=0, atol=1e-12)
            np.testing.assert_allclose(qd_c, qd_p, rtol=0, atol=1e-9)
        sim.tick()  # (a new measured state for the next goal)
    assert used_count >= 100  # near the tool's pose, the common answer


def test_what_it_has_no_form_of_goes_to_the_python_path(psm_sim):
    sim, psm = psm_sim, psm_sim.arms["PSM1"]
    T0 = psm.measured_cp().T
    before = _setpoints(sim, psm)
    at_rcm = psm.base_frame()[0].copy()  # the goal on the RCM: refused (dvrk.md 1.8)
    assert not psm._servo_cp_compiled(at_rcm, None, checked=False)
    result = psm.servo_cp(at_rcm)
    assert not result and "from the RCM" in result.message
    assert not psm._servo_cp_compiled(T0, [1e300, 0, 0, 0, 0, 0], checked=False)
    assert not psm.servo_cp(T0, twist=[1e300, 0, 0, 0, 0, 0])
    assert not psm._servo_cp_compiled(np.full((4, 4), np.nan), None, checked=False)
    for q_ref, q_before in zip(_setpoints(sim, psm), before, strict=True):
        np.testing.assert_array_equal(q_ref, q_before)  # refused: nothing changed
    # A joint rate over the feed-forward bound: refused by the Python path with its reason.
    fast = np.array([9.0, 9.0, 9.0, 0.0, 0.0, 0.0])
    assert not psm._servo_cp_compiled(T0, fast, checked=False)
    assert "twist as joint velocity" in psm.servo_cp(T0, twist=fast).message
    # Past a joint limit: the Python path's answer (the IK reached it, the goal clipped).
    far = T0.copy()
    far[:3, 3] += [0.0, 0.0, 2.0]
    assert not psm._servo_cp_compiled(far, None, checked=False)
    assert psm.servo_cp(far)
    assert _setpoints(sim, psm)[0][2] == psm.chain.qmax[2]


def test_read_only_and_strided_goals_use_the_one_signature(psm_sim):
    psm = psm_sim.arms["PSM1"]
    T = np.asfortranarray(psm.measured_cp().T)
    T.setflags(write=False)
    assert psm._servo_cp_compiled(T, None, checked=False)
    assert len(arm_types._CP.servo_cp_row.signatures) == 1
