"""The carried objects' law (``tasks/handling.py``): the compiled rows are its numpy form bit
for bit, on random states and samples of many trials and objects, with the cases its rules
turn on (jaws on and off, slow and fast, NaN times of a first sample, placed or not)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bits import assert_same_bits
from davinci_sim.tasks.handling import (
    Handling,
    handling_rows,
    handling_step,
    handling_step_arrays,
)


def _case(seed: int, n: int, k: int):
    rng = np.random.default_rng(seed)
    t_prev = rng.choice([np.nan, 1.0, 1.0 - 1e-3], size=n)
    t = np.full(n, 1.001)
    still = rng.choice([np.nan, 0.5, 0.95], size=(n, k))
    state = Handling(still, rng.integers(0, 3, (n, k)), rng.random((n, k)) < 0.5,
                     rng.random((n, k)) < 0.5, rng.random((n, k)) < 0.5)  # fmt: skip
    p_prev = rng.normal(size=(n, k, 3)) * 0.01
    # slow (under 1 cm/s over the 1 ms), fast, or not moved at all
    step = rng.normal(size=(n, k, 3)) * rng.choice([1e-6, 1e-5, 1e-3, 0.0], size=(n, k, 1))
    grasp = rng.choice([0, 0b0011, 0b1100, 0b1111, 0b0001, 0b0110], size=(n, k))
    kw = dict(grasp=grasp, p=p_prev + step, p_prev=p_prev, t=t, t_prev=t_prev,
              placed=rng.random((n, k)) < 0.5, instruments=2, rest_speed=0.01,
              rest_time=0.1)  # fmt: skip
    return state, kw


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 6), k=st.integers(1, 4))
def test_the_compiled_law_is_the_numpy_law_bit_for_bit(seed, n, k):
    state, kw = _case(seed, n, k)
    new, events = handling_step(state, **kw)
    ref_new, ref_events = handling_step_arrays(state, **kw)
    for a, b, name in zip((*new, *events), (*ref_new, *ref_events),
                          (*Handling._fields, *events._fields), strict=True):  # fmt: skip
        assert_same_bits(np.asarray(a), np.asarray(b), name)


def test_the_python_form_of_the_rows_is_the_compiled_one():
    """Without numba the rows run as plain Python: the same bits."""
    state, kw = _case(7, 5, 3)
    new, events = handling_step(state, **kw)
    args = [np.ascontiguousarray(a) for a in state]
    args += [kw["grasp"], kw["p"], kw["p_prev"], kw["t"], kw["t_prev"], kw["placed"], 2, 0.01,
             0.1]  # fmt: skip
    outs = [np.empty_like(a) for a in (*new, *events)]
    handling_rows.py_func(*args, *outs)
    for a, b in zip(outs, (*new, *events), strict=True):
        assert_same_bits(a, b, "row")


def test_a_carried_object_handed_over_then_let_go_to_rest_lands_once():
    """One object: held by instrument 1 alone, then by 2 alone (a hand-off), then let go,
    still for the rest time: it lands there, and a drop counts where it is not placed."""
    off = np.zeros((1, 1), bool)
    state = Handling(np.full((1, 1), np.nan), np.zeros((1, 1), np.int64), off, off, off)
    p = np.zeros((1, 1, 3))
    seen = []
    t = 0.0
    for grasp in [0b0011] * 3 + [0b1100] * 3 + [0] * 120:
        t += 1e-3
        state, e = handling_step(state, grasp=np.array([[grasp]]), p=p, p_prev=p,
                                 t=np.array([t]), t_prev=np.array([t - 1e-3]),
                                 placed=np.zeros((1, 1), bool), instruments=2,
                                 rest_speed=0.01, rest_time=0.1)  # fmt: skip
        seen.append((int(e.handoff[0, 0]), int(e.land[0, 0]), int(e.drop[0, 0])))
    assert sum(s[0] for s in seen) == 1
    assert sum(s[1] for s in seen) == 1
    assert sum(s[2] for s in seen) == 1
