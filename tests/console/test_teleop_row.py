"""The teleoperation's compiled following tick (console/teleop_row.py) against the Python
laws it compiles (teleop_math) and the live Python tick it replaces."""

from __future__ import annotations

import math
import types

import numpy as np
import pytest
from console_helpers import rotation_about, teleop_sim

from davinci_sim.console import teleop_math as tm
from davinci_sim.console import teleop_psm
from davinci_sim.geometry import so3
from davinci_sim.kinematics import jit

pytestmark = pytest.mark.skipif(not jit.ENABLED, reason="numba is off: nothing is compiled")

#: The compiled module the teleoperation calls (the tests below swap it for a counting one).
ROW = teleop_psm._ROW


def random_pose(rng) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = so3.rotation_from_vector(rng.normal(size=3))
    T[:3, 3] = rng.normal(scale=0.1, size=3)
    return T


@pytest.mark.parametrize("locks", [(False, False), (True, False), (False, True), (True, True)])
def test_the_goal_and_twist_rows_are_the_python_laws(locks):
    from davinci_sim.console import teleop_row

    rng = np.random.default_rng(7)
    t_locked, r_locked = locks
    for _ in range(50):
        psm0, mtm0, mtm = random_pose(rng), random_pose(rng), random_pose(rng)
        R_offset = so3.rotation_from_vector(rng.normal(size=3))
        scale = float(rng.uniform(0.1, 1.0))
        twist = rng.normal(size=6)
        use_linear, use_angular = bool(rng.integers(2)), bool(rng.integers(2))
        goal = np.empty((4, 4))
        teleop_row.follow_pose_row(psm0, mtm0, mtm, R_offset, scale, t_locked, r_locked, goal)
        expected = tm.follow_pose(psm0, mtm0, mtm, R_offset, scale, translation_locked=t_locked,
                                  rotation_locked=r_locked)  # fmt: skip
        # (the translation: the same operations; the rotation's sums may differ by an ulp
        # from numpy's matrix product)
        np.testing.assert_array_equal(goal[:, 3], expected[:, 3])
        np.testing.assert_array_equal(goal[3], expected[3])
        np.testing.assert_allclose(goal[:3, :3], expected[:3, :3], rtol=0, atol=1e-15)
        out = np.empty(6)
        teleop_row.follow_twist_row(twist, scale, use_linear, use_angular, t_locked, r_locked,
                                    out)  # fmt: skip
        np.testing.assert_array_equal(
            out,
            tm.follow_twist(twist, scale, use_linear=use_linear, use_angular=use_angular,
                            translation_locked=t_locked, rotation_locked=r_locked),
        )  # fmt: skip


@pytest.mark.parametrize(
    "ghost, gripper, catching_up",
    [(0.1, 0.5, False), (0.1, 0.5, True), (0.5, 0.49, True), (0.3, -0.2, False),
     (0.2, math.nan, False), (math.nan, 0.2, True), (0.0, 2.0, False)],
)  # fmt: skip
def test_the_jaw_row_is_the_python_law_nan_included(ghost, gripper, catching_up):
    from davinci_sim.console import teleop_row

    args = dict(rate=2.0, rate_after_clutch=0.5, dt=0.001, jaw_scale=4 / 3, jaw_offset=0.0,
                jaw_min=0.0, jaw_max=math.radians(80))  # fmt: skip
    got = teleop_row.follow_jaw_row(ghost, gripper, catching_up, *args.values(),
                                    tm.JAW_CATCH_UP_TOLERANCE)  # fmt: skip
    want = tm.follow_jaw(ghost, gripper, catching_up, **args)
    np.testing.assert_array_equal(np.array(got, dtype=float), np.array(want, dtype=float))


class _Counting:
    """teleop_psm's compiled module with its follow_tick calls and answers counted."""

    def __init__(self, module) -> None:
        self.module, self.answers = module, []

    def follow_tick(self, *args):
        answer = self.module.follow_tick(*args)
        self.answers.append(answer)
        return answer


def _tick_both_ways(monkeypatch, sim, ticks: int):
    """From the simulation's state now: ``ticks`` ticks with the compiled following tick,
    then the same ticks from the same state with the Python one; each path's servo
    references and the teleoperation's jaw state, and the compiled answers."""
    teleop = sim.components["console"].psm_teleops["MTMR_PSM1"]
    sim.set_chunker(None)  # (each tick in Python: the teleoperation's own compiled call)
    start = sim.get_state()
    counting = _Counting(ROW)
    out = []
    for row in (types.SimpleNamespace(follow_tick=counting.follow_tick), None):
        sim.set_state(start)
        monkeypatch.setattr(teleop_psm, "_ROW", row)
        sim.step(ticks)
        out.append(
            (sim.servo.q_ref.copy(), sim.servo.qd_ref.copy(), teleop._ghost,
             teleop._jaw_catching_up, teleop._jaw_sent, sim.data.qpos.copy())
        )  # fmt: skip
    return out, counting.answers


def test_the_live_following_tick_compiled_is_the_python_tick(monkeypatch):
    sim, console = teleop_sim()
    device = sim.components["MTMR/device"]
    # The hand moves the handle and turns it, the fingers open the gripper: the goal, the
    # feed-forward and the jaw all change every tick.
    T = device.input().T_hrsv_tip.copy()
    T[:3, 3] += (0.02, -0.01, 0.015)
    T[:3, :3] = rotation_about((0.3, 1.0, 0.2), 0.4) @ T[:3, :3]
    device.move_hand(T)
    device.squeeze(math.radians(40))
    sim.run_for(0.05)
    (compiled, python), answers = _tick_both_ways(monkeypatch, sim, 1)
    assert answers == [True]
    for a, b in zip(compiled[:2], python[:2], strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
    assert compiled[2:5] == pytest.approx(python[2:5], abs=1e-12)
    # Over many ticks (the physics between them), the two stay together.
    (compiled, python), answers = _tick_both_ways(monkeypatch, sim, 300)
    assert len(answers) == 300 and all(answers)
    np.testing.assert_allclose(compiled[5], python[5], rtol=0, atol=1e-9)
    assert compiled[2] == pytest.approx(python[2], abs=1e-9)


def test_a_goal_with_no_compiled_answer_takes_the_python_path_and_its_message(monkeypatch):
    sim, console = teleop_sim()
    teleop, device = console.psm_teleops["MTMR_PSM1"], sim.components["MTMR/device"]
    errors: list = []
    teleop.psm.channels.subscribe(
        lambda ev, payload: errors.append(str(payload)) if ev == "error" else None
    )
    # The handle shoved away at scale 1: the tool asked to move faster than its feed-forward
    # bound allows, a refusal with its message, then more.
    assert teleop.set_scale(1.0)
    device.move_hand(device.input().position + np.array([0.0, 0.0, 0.4]))
    sim.set_chunker(None)  # (each tick in Python: the teleoperation's own compiled call)
    start = sim.get_state()
    counting = _Counting(ROW)
    seen = []
    for row in (types.SimpleNamespace(follow_tick=counting.follow_tick), None):
        sim.set_state(start)
        errors.clear()
        monkeypatch.setattr(teleop_psm, "_ROW", row)
        sim.run_for(0.5)
        seen.append(list(errors))
    assert True in counting.answers and False in counting.answers
    assert any("servo_cp" in e for e in seen[0]), seen[0]
    assert seen[0] == seen[1]  # the same refusals, at the same times, as the Python tick
