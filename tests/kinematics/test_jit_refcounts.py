"""The pruning of the reference counting of compiled functions' array arguments
(:mod:`davinci_sim.kinematics.jit_refcounts`): what it removes from LLVM's text and what it
leaves, and, on functions numba compiles with it installed, that arguments lose their
counting while arrays that escape (returned, put in a tuple or a list) stay alive and
nothing leaks."""

from __future__ import annotations

import gc

import numpy as np
import pytest

from davinci_sim.kinematics import jit, jit_refcounts
from davinci_sim.kinematics.jit_refcounts import install, prune_argument_refcounts

numba = pytest.importorskip("numba")

pytestmark = pytest.mark.skipif(not jit.ENABLED, reason="numba compiles nothing here")

# One function of the shape numba gives a row law: the array's count raised on entry,
# lowered on each of two exits, a loop between, the array passed to another compiled
# function and to a C helper under a different name.
_LAW = """\
define i32 @"_ZN5tests3lawB2v1E"(ptr %.ret, ptr %arg.a.0, ptr %arg.a.4, ptr %arg.b.0) {
entry:
  tail call void @NRT_incref(ptr %arg.a.0)
  tail call void @NRT_incref(ptr %arg.b.0)
  br label %loop
loop:
  %.5 = tail call i32 @"_ZN5tests5innerB2v2E"(ptr %.r, ptr %arg.a.0, ptr %arg.a.4)
  %.6 = icmp eq i32 %.5, 0
  br i1 %.6, label %loop, label %early
early:
  tail call void @NRT_decref(ptr %arg.a.0)
  tail call void @NRT_decref(ptr %arg.b.0)
  ret i32 1
done:
  tail call void @NRT_decref(ptr nonnull %arg.a.0)
  {USE}
  tail call void @NRT_decref(ptr %arg.b.0)
  ret i32 0
}
"""


def _pruned(use: str) -> str:
    text, _ = prune_argument_refcounts(_LAW.replace("{USE}", use))
    return text


def _counted(text: str, name: str) -> int:
    return sum(f" {name})" in line and "@NRT_" in line for line in text.splitlines())


def test_an_argument_used_only_by_compiled_calls_loses_its_counting():
    text, removed = prune_argument_refcounts(_LAW.replace("{USE}", ""))
    assert removed == 6
    assert _counted(text, "%arg.a.0") == 0 and _counted(text, "%arg.b.0") == 0
    assert '@"_ZN5tests5innerB2v2E"(ptr %.r, ptr %arg.a.0' in text  # (the call stays)
    assert prune_argument_refcounts(text) == (text, 0)


@pytest.mark.parametrize(
    "use",
    [
        "store ptr %arg.b.0, ptr %.ret, align 8",  # returned (or kept) through memory
        "%.9 = insertvalue { ptr, ptr } undef, ptr %arg.b.0, 0",  # put in a tuple
        "%.9 = phi ptr [ %arg.b.0, %loop ], [ %.local, %early ]",  # merged with another value
        "%.9 = select i1 %.6, ptr %.local, ptr %arg.b.0",
        "%.9 = icmp eq ptr %arg.b.0, null",
        "tail call void @numba_list_append(ptr %.l, ptr %arg.b.0)",  # a C helper
        'tail call void %.f(ptr %arg.b.0, ptr @"_ZN5tests1fE")',  # a call through a pointer
    ],
)
def test_an_argument_that_may_escape_keeps_its_counting(use):
    text = _pruned(use)
    assert _counted(text, "%arg.b.0") == 3  # numba's, as it made it
    assert _counted(text, "%arg.a.0") == 0


def test_a_choice_among_arguments_is_counted_with_them():
    """A ``phi`` or ``select`` among arguments (and null) is always one of them: its
    counting goes with theirs, or stays with theirs where it escapes."""
    choose = (
        "%.9 = phi ptr [ %arg.b.0, %loop ], [ %.10, %early ], [ null, %done ]\n"
        "  %.10 = select i1 %.6, ptr %arg.a.0, ptr %.9\n"
        "  tail call void @NRT_incref(ptr %.10)\n"
        '  %.11 = call i32 @"_ZN5tests5innerB2v2E"(ptr %.r, ptr %.10, ptr %arg.a.4)\n'
        "  tail call void @NRT_decref(ptr %.10)"
    )
    text = _pruned(choose)
    assert sum("@NRT_" in line for line in text.splitlines()) == 0
    text = _pruned(choose + "\n  store ptr %.9, ptr %.ret, align 8")
    assert _counted(text, "%arg.a.0") == 3 and _counted(text, "%arg.b.0") == 3
    assert _counted(text, "%.10") == 2


def test_values_that_are_not_arguments_keep_their_counting():
    ir = _LAW.replace("{USE}", "tail call void @NRT_incref(ptr %.local)").replace(
        "ret i32 0", "tail call void @NRT_decref(ptr %.local)\n  ret i32 0"
    )
    text, _ = prune_argument_refcounts(ir)
    assert _counted(text, "%.local") == 2


@numba.njit
def _watch(q, q_ref, tolerance, since, kept):
    """A row law's shape (the tracking watch's): loops, a rewind, two exits."""
    for i in range(since.shape[0]):
        kept[i] = since[i]
    bad = False
    for i in range(q.shape[0]):
        if abs(q[i] - q_ref[i]) > tolerance[i]:
            since[i] += 1.0
            bad = bad or since[i] > 3.0
        else:
            since[i] = 0.0
    if bad:
        for i in range(since.shape[0]):
            since[i] = kept[i]
        return False
    return True


@numba.njit
def _ticks(q, q_ref, tolerance, since, kept, k):
    """``k`` ticks of :func:`_watch`: without the pruning, numba's code counts the five
    arrays' references at every tick (5 increments in the loop, measured with numba 0.68)."""
    passed = 0
    for _ in range(k):
        if _watch(q, q_ref, tolerance, since, kept):
            passed += 1
    return passed


@numba.njit
def _returned(a):
    return a


@numba.njit
def _paired(a, b):
    return (a, b)


@numba.njit
def _listed(a, b):
    kept = [a]
    kept.append(b)
    return kept


@numba.njit
def _view(a):
    return a[1:]


def _arguments_counted(dispatcher) -> int:
    ir = dispatcher.inspect_llvm(dispatcher.signatures[0])
    return sum("@NRT_incref(ptr" in line and "%arg." in line for line in ir.splitlines())


@pytest.fixture
def pruned_here(monkeypatch):
    """This module's functions pruned as the package's are (the installed pruning's scope
    is the package's: a user's numba code keeps numba's counting)."""
    assert install()  # (installed already by the jit module; idempotent)
    monkeypatch.setattr(jit_refcounts, "SCOPE", (*jit_refcounts.SCOPE, __name__.split(".")[0]))


def test_the_installed_pruning_keeps_to_its_scope():
    ir = _LAW.replace("{USE}", "")
    assert prune_argument_refcounts(ir, ("davinci_sim",)) == (ir, 0)
    assert prune_argument_refcounts(ir, ("tests",))[1] == 6  # (_ZN5tests...)


def test_compiled_laws_lose_their_arguments_counting_and_compute_the_same(pruned_here):
    q, q_ref, tolerance = np.array([0.0, 0.5, 2.0]), np.zeros(3), np.ones(3)
    results = []
    for ticks in (_ticks, _ticks.py_func):
        since, kept = np.zeros(3), np.zeros(3)
        results.append((ticks(q, q_ref, tolerance, since, kept, 6), since))
    assert results[0][0] == results[1][0] == 3  # (the fourth tick over 3 rewinds)
    np.testing.assert_array_equal(results[0][1], results[1][1])
    assert _arguments_counted(_ticks) == 0


@pytest.fixture
def allocations():
    """numba's live allocations (mi_alloc − mi_free) as a function, its counters switched
    on for the test (they are off unless ``NUMBA_NRT_STATS``)."""
    from numba.core.runtime import _nrt_python, rtsys

    was_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()

    def live() -> int:
        stats = rtsys.get_allocation_stats()
        return stats.mi_alloc - stats.mi_free

    yield live
    if not was_on:
        _nrt_python.memsys_disable_stats()


def test_arrays_that_escape_stay_alive_and_nothing_leaks(pruned_here, allocations):
    gc.collect()
    before = allocations()
    returned = _returned(np.arange(4.0))
    pair = _paired(np.arange(3.0), np.ones(2))
    listed = _listed(np.full(3, 7.0), np.full(2, 5.0))
    view = _view(np.arange(6.0))
    gc.collect()
    for _ in range(50):  # (freed memory would be reused by these)
        np.full(6, -1.0)
    np.testing.assert_array_equal(returned, np.arange(4.0))
    np.testing.assert_array_equal(pair[0], np.arange(3.0))
    np.testing.assert_array_equal(pair[1], np.ones(2))
    np.testing.assert_array_equal(listed[0], np.full(3, 7.0))
    np.testing.assert_array_equal(listed[1], np.full(2, 5.0))
    np.testing.assert_array_equal(view, np.arange(1.0, 6.0))
    del returned, pair, listed, view
    gc.collect()
    assert allocations() == before
