"""The trainee's compiled step (operators/trainee_row.py) against its numpy step, the oracle:
the same hands, the same state, bit for bit, step after step."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from tests.bits import assert_same_bits
from tests.operators.test_trainee import DT, PATH, subjects, trainee

from davinci_sim.kinematics import jit
from davinci_sim.operators import trainee as trainee_module
from davinci_sim.operators.params import Mechanisms

pytestmark = pytest.mark.skipif(trainee_module._ROW is None, reason="numba is not enabled")

STATE = ("co_contraction", "x_eq", "v_eq", "_v_plan", "feedforward_force", "last_tremor_force",
         "_obs", "t_reach", "reach_from", "reach_time", "t_follow", "k")  # fmt: skip


def numpy_step(tr, *args):
    """``tr.command(*args)`` through the numpy step."""
    row, trainee_module._ROW = trainee_module._ROW, None
    try:
        return tr.command(*args)
    finally:
        trainee_module._ROW = row


def assert_same_trainees(a, b, where):
    for name in STATE:
        assert_same_bits(getattr(a, name), getattr(b, name), f"{where}.{name}")
    assert_same_bits(a._motor.state, b._motor.state, f"{where}.motor")
    for name in ("_x", "_y1", "_y2"):
        assert_same_bits(getattr(a._tremor, name), getattr(b._tremor, name), f"{where}.{name}")
    assert_same_bits(a.push_force(), b.push_force(), f"{where}.push_force")


@pytest.mark.parametrize(
    "options",
    [
        {},
        {"mechanisms": Mechanisms(stiffening_gain=0.5)},
        {"tremor": False, "motor_noise": False},
    ],
)
def test_the_compiled_step_equals_the_numpy_step_bit_for_bit(options):
    """A closed loop (the tool follows the hand, a force pushes it) from first sight through
    the reach, the wait at point 1 and every stroke to the end: each step's equilibrium and
    every array the step keeps hold the numpy step's bits, for a batch and for one of its
    rows alone (the same bits in any batch), with and without the force felt."""
    n = 4
    p = subjects(n, speed=0.08, reaction_time=0.05)
    compiled, oracle = trainee(p, **options), trainee(p, **options)
    alone = trainee(p.take([2]), keys=[(7, 2)], **options)
    start = np.tile(PATH.point_at(0.0) + [0.004, -0.002, 0.001], (n, 1))
    rng = np.random.default_rng(3)
    tool = start.copy()
    following = 0
    for k in range(6000):
        force = rng.normal(0.0, 4.0, (n, 3)) if k % 3 else None
        x = compiled.command(DT, tool, force)
        assert_same_bits(x, numpy_step(oracle, DT, tool, force), f"step {k}")
        y = alone.command(DT, tool[2:3], None if force is None else force[2:3])
        assert_same_bits(y[0], x[2], f"step {k}, row alone")
        if k % 500 == 0:
            assert_same_trainees(compiled, oracle, f"step {k}")
        following += int(np.isfinite(compiled.t_follow).sum())
        tool = start + 0.6 * x + 1e-4 * rng.standard_normal((n, 3))
    assert_same_trainees(compiled, oracle, "end")
    assert (compiled.phase == trainee_module.TraineePhase.DONE).any()  # the plan ran out
    assert following > 0


def test_a_copy_steps_on_its_own():
    """A deep copy (the live trainee's saved state) steps from the same state to the same bits
    as the original, and stepping it leaves the original's arrays unchanged."""
    p = subjects(2)
    tr = trainee(p)
    tool = np.tile(PATH.point_at(0.0), (2, 1))
    for _ in range(300):
        tr.command(DT, tool)
    saved = copy.deepcopy(tr)
    before = copy.deepcopy(tr)
    a = saved.command(DT, tool)
    assert_same_trainees(tr, before, "original")
    assert_same_bits(tr.command(DT, tool), a)


def test_compiled_at_import_with_the_one_signature_the_trainees_use():
    kernel = trainee_module._ROW.command_rows
    assert kernel in jit.KERNELS and kernel.ready()
    tr = trainee(subjects(2))
    tr.command(DT, np.zeros((2, 3)), np.zeros((2, 3)))
    assert len(kernel.dispatcher.signatures) == 1
