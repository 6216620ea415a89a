"""The study batch a chunk of ticks at a time (study/batch_chunk.py, study/chunk_rows.py)
against its compiled tick one tick at a time, the oracle: the same state, bit for bit,
after every chunk; the same rows; and a tick that needs Python in the middle of a chunk
(restored, run again up to it, then that tick alone) changes nothing."""

from __future__ import annotations

import dataclasses

import pytest
from tests.bits import assert_same_bits
from tests.study.test_batch_compiled import _specs

from davinci_sim.operators.params import MECHANISMS
from davinci_sim.study import batch_chunk, batch_compiled
from davinci_sim.study.batch import TrialBatch

pytestmark = pytest.mark.skipif(batch_compiled.CHUNK is None, reason="needs numba")

#: What a chunk writes that the tick's laws read again (rows still running).
ROWS = ("Q", "V", "bias", "q_ref", "qd_ref", "tau_ff", "T_psm", "J_psm", "T_mtm", "J_mtm",
        "twist_mtm", "ghost", "jaw_sent", "requested", "wrench_sent", "T_hand",
        "xipos")  # fmt: skip


def assert_same_batches(a: TrialBatch, b: TrialBatch, where: str) -> None:
    assert_same_bits(a.active, b.active, f"{where}: active")
    assert_same_bits(a.fault, b.fault, f"{where}: fault")
    assert_same_bits(a.ticks, b.ticks, f"{where}: ticks")
    assert a.time == b.time, where
    rows = a.active
    for name in ROWS:
        assert_same_bits(getattr(a, name)[rows], getattr(b, name)[rows], f"{where}: {name}")
    for name in ("x_eq", "v_eq", "co_contraction", "_obs"):
        assert_same_bits(getattr(a.trainee, name)[rows], getattr(b.trainee, name)[rows], name)
    assert a.trainee.k == b.trainee.k
    assert_same_bits(tuple(a.state), tuple(b.state), f"{where}: task state")
    assert_same_bits(a.metrics.result(), b.metrics.result(), f"{where}: metrics")


@pytest.mark.parametrize(
    ("compiled_task", "mechanisms", "carried"),
    [(True, (), False), (False, (), False), (True, MECHANISMS, False), (True, (), True)],
    ids=["task compiled", "task Python", "trainee mechanisms on", "wrist turning"],
)
def test_chunks_are_the_ticks_bit_for_bit(
    short_task, carry_task, monkeypatch, compiled_task, mechanisms, carried
):
    """After every chunk the state equals the ticks', the task's samples run by its
    compiled call (``chunk_rows.task_rows``) or by ``advance`` tick by tick; with the
    trainees' reactions to guidance on (the force they feel, their own practice); with a
    carried object's wrist turns (the hands' targets turning, operators.wrist)."""
    chosen = batch_chunk._tasks_python if compiled_task else batch_chunk._tasks_compiled

    def unexpected(*args):
        raise AssertionError(f"{chosen.__name__} ran")

    if not compiled_task:
        monkeypatch.setattr(batch_chunk, "_tasks_compiled", lambda *args: False)
    else:
        monkeypatch.setattr(batch_chunk, "_tasks_python", unexpected)
    task = carry_task if carried else short_task
    specs = [dataclasses.replace(s, mechanisms=mechanisms) for s in _specs(task)]
    chunked, ticked = TrialBatch(specs), TrialBatch(specs)
    try:
        assert batch_chunk.can_chunk(chunked)
        assert chunked.trainee.mechanisms.stiffening_gain > 0 or not mechanisms
        sizes = []
        while chunked.active.any() and len(sizes) < 120:
            k = batch_chunk.advance(chunked)
            sizes.append(k)
            for _ in range(k):
                ticked.tick()
            assert_same_batches(chunked, ticked, f"after {sum(sizes)} ticks")
        assert max(sizes) == batch_chunk.CHUNK_TICKS
        assert (chunked.state.phase > 0).any()  # (the task ran: trials started)
    finally:
        chunked._setup.sim.close()
        ticked._setup.sim.close()


def test_whole_trials_give_the_same_rows(short_task):
    """A run in chunks and a run tick by tick (``on_tick`` keeps the ticks one by one) give
    the same rows, timings aside, bit for bit: trials that finish inside a chunk included."""
    from davinci_sim.study.report import COLUMNS, TIMING_COLUMNS

    rows = []
    for on_tick in (None, lambda batch: None):
        batch = TrialBatch(_specs(short_task))
        try:
            rows.append(batch.run(on_tick=on_tick))
        finally:
            batch._setup.sim.close()
    keys = [k for k in COLUMNS if k not in TIMING_COLUMNS]
    for a, b in zip(*rows, strict=True):
        assert a["finished"] and b["finished"]
        assert_same_bits({k: a[k] for k in keys}, {k: b[k] for k in keys})
        assert a["sim_time"] == b["sim_time"]


def test_a_tick_needing_python_inside_a_chunk_changes_nothing(short_task, monkeypatch):
    """Row 0's contact count read where the velocity filter marks its first sample: zero
    at the chunk's first tick, not at its second. The chunk stops there, is restored and
    runs one tick again, then that tick runs alone; from then on each chunk stops at once
    and the ticks run one by one. Every state equals the ticks' throughout."""
    specs = _specs(short_task) + _specs(short_task)[:1]  # (4 rows: an int32's 4 bytes)
    chunked, ticked = TrialBatch(specs), TrialBatch(specs)
    real = batch_chunk._ncon_addresses
    stops = []

    def fake(batch):
        out = real(batch)
        assert not batch.velocity._started[:4].any() or stops
        out[0] = batch.velocity._started.ctypes.data
        return out

    restore = batch_chunk._restore

    def counting(batch, saved):
        stops.append(int(batch.ticks.max()))
        restore(batch, saved)

    monkeypatch.setattr(batch_chunk, "_ncon_addresses", fake)
    monkeypatch.setattr(batch_chunk, "_restore", counting)
    try:
        done = []
        for _ in range(5):
            k = batch_chunk.advance(chunked)
            done.append(k)
            for _ in range(k):
                ticked.tick()
            assert_same_batches(chunked, ticked, f"after {sum(done)} ticks")
        assert done == [1, 1, 1, 1, 1]
        assert len(stops) == 5  # (the first chunk stopped at its second tick, then at once)
    finally:
        chunked._setup.sim.close()
        ticked._setup.sim.close()


def test_the_chunk_compiles_one_signature(short_task):
    batch = TrialBatch(_specs(short_task, timeout=0.2))
    try:
        batch.run()
    finally:
        batch._setup.sim.close()
    assert len(batch_compiled.CHUNK.chunk_rows.signatures) == 1
    assert len(batch_compiled.CHUNK.task_rows.signatures) == 1
