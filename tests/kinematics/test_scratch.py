"""Scratch arrays in a compiled kernel's stack frame (:mod:`davinci_sim.kinematics.scratch`):
the shapes and kinds asked for, the same results compiled and in plain Python, a frame's
space reused by a loop, the capacity's refusal, and no heap allocation by the per-tick laws
that use them."""

from __future__ import annotations

import numpy as np
import pytest

from davinci_sim.kinematics import jit
from davinci_sim.kinematics.scratch import local, local_bool, local_int, local_within

numba = pytest.importorskip("numba")
_nrt = pytest.importorskip("numba.core.runtime._nrt_python")


def _fill(n):
    """Each kind of scratch array written and read back; ``n`` a size known at run time."""
    a, b, c = local(5), local(2, 3), local(2, 3, 4)
    flags, counts, rows = local_bool(4), local_int(3), local_within(64, n, n)
    total = 0.0
    for i in range(5):
        a[i] = 0.5 * i
    for i in range(2):
        for j in range(3):
            b[i, j] = i - j
            for k in range(4):
                c[i, j, k] = i * j * k
    for i in range(4):
        flags[i] = i % 2 == 0
    for i in range(3):
        counts[i] = 7 * i
    for i in range(n):
        for j in range(n):
            rows[i, j] = i + 0.25 * j
    total += a.sum() + b.sum() + c.sum() + rows.sum()
    for i in range(4):
        total += 1.0 if flags[i] else 0.0
    for i in range(3):
        total += counts[i]
    return total, a.shape[0], b.shape, c.shape, rows.shape


_fill_compiled = numba.njit(cache=False)(_fill)


def test_plain_python_gets_new_arrays_of_the_shape_and_kind():
    assert local(4).shape == (4,) and local(4).dtype == np.float64
    assert local(2, 0).shape == (2, 0)
    assert local(1, 4, 4).shape == (1, 4, 4)
    assert local_bool(3).dtype == np.bool_ and local_int(3).dtype == np.int64
    assert local_within(16, 2, 5).shape == (2, 5)
    a, b = local(3), local(3)
    assert a is not b and not np.shares_memory(a, b)


@pytest.mark.skipif(not jit.ENABLED, reason="numba compiles nothing here")
def test_compiled_arrays_hold_what_is_written_as_python_arrays_do():
    for n in (0, 1, 6, 8):
        assert _fill_compiled(n) == _fill(n)


def test_a_shape_over_the_capacity_is_refused_both_ways():
    with pytest.raises(ValueError, match="over its"):
        local_within(8, 3, 3)

    @numba.njit(cache=False)
    def over(n):
        return local_within(8, n, n).shape[0]

    assert over(2) == 2
    with pytest.raises(ValueError, match="capacity"):
        over(3)


def test_a_call_in_a_loop_reuses_the_frames_space():
    """A million calls, each asking for 32 kB: reserved once, not once a call (that would be
    32 GB of stack)."""

    @numba.njit(cache=False)
    def inner(i):
        a = local(4096)
        a[i % 4096] = 1.0
        return a[i % 4096]

    @numba.njit(cache=False)
    def outer(n):
        s = 0.0
        for i in range(n):
            a = local(4096)
            a[0] = inner(i)
            s += a[0]
        return s

    assert outer(1_000_000) == 1_000_000.0


def test_a_size_that_is_not_a_constant_does_not_compile():
    @numba.njit(cache=False)
    def runtime_size(n):
        return local(n).shape[0]

    with pytest.raises(numba.core.errors.TypingError, match="constant"):
        runtime_size(3)


@pytest.fixture
def allocations():
    """Numba's count of heap allocations, switched on for the test."""
    was = _nrt.memsys_stats_enabled()
    _nrt.memsys_enable_stats()
    yield _nrt.memsys_get_stats_alloc
    if not was:
        _nrt.memsys_disable_stats()


def test_the_per_tick_laws_allocate_nothing_on_the_heap(allocations):
    """The PSM's ``servo_cp`` row (IK, Jacobian solve, clip) and the web console's rate input
    on a hand, called as a kernel's ticks call them: no allocation (they made 15 and 5 a
    tick). (A compiled driver calls them ``n`` times: its own call's argument handling is
    the same for any ``n``.)"""
    from davinci_sim.devices.hand_input_row import STATE_SIZE, hand_rate_row
    from davinci_sim.kinematics.arms import load_arm
    from davinci_sim.kinematics.fk import forward_kinematics_and_jacobian
    from davinci_sim.sim.cartesian_kernel import servo_cp_constants, servo_cp_row

    @numba.njit(cache=False)
    def ticks(n, args, hand, T_hrsv, target):
        ok = True
        for _ in range(n):
            ok = servo_cp_row(*args) and ok
            ok = hand_rate_row(hand, T_hrsv, target, 0.001) and ok
        return ok

    chain = load_arm("PSM1").chain
    q = np.array([0.1, -0.2, 0.12, 0.3, 0.2, -0.1])  # (a goal at the FK of a q with the tool out)
    T, J = forward_kinematics_and_jacobian(chain, q)
    q_measured, J = q.copy(), J.copy()
    q_measured.setflags(write=False)  # (read-only as the arm's: the warm-up's signature)
    J.setflags(write=False)
    args = (*servo_cp_constants(chain), np.eye(4), T, q_measured, J, True, np.zeros(6), chain.qmin,
            chain.qmax, np.ones(6), np.empty(6), np.empty(6))  # fmt: skip
    state, params = np.zeros(STATE_SIZE), np.array([0.01, 0.15, 1e9, 0.3, 1.0])
    state[6] = 0.02  # (the hand moving along x at 20 mm/s)
    state[12:21] = np.eye(3).ravel()
    hand = (np.ones(1, dtype=np.bool_), state, params)
    T_hrsv, target = np.eye(4), np.eye(4)
    assert ticks(1, args, hand, T_hrsv, target)
    counts = []
    for n in (0, 10):
        before = allocations()
        assert ticks(n, args, hand, T_hrsv, target)
        counts.append(allocations() - before)
    assert counts[1] == counts[0]
    np.testing.assert_allclose(args[-2], q, atol=1e-9)  # (the IK's answer: the q of the goal)
    assert target[0, 3] == pytest.approx(0.02 * 0.011)  # (the ticks did move the target)
