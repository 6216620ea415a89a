"""Period statistics: histogram percentiles, maxima, overruns; shared storage."""

import math

import pytest

from davinci_sim.sim.runtime import PeriodRecorder
from davinci_sim.sim.runtime.shm import SharedBuffer
from davinci_sim.sim.runtime.stats import BIN_WIDTH, layout_size, period_statistics


def record(recorder, periods, compute=0.0003):
    t = 10.0
    recorder.tick(t, t + compute)
    for p in periods:
        t += p
        recorder.tick(t, t + (0.0015 if p > 0.004 else compute))


def test_statistics_of_known_periods():
    recorder = PeriodRecorder(0.001)
    periods = [0.001] * 989 + [0.0018] * 10 + [0.007]
    record(recorder, periods)
    s = recorder.statistics()
    assert s.ticks == 1001 and s.real_time and s.nominal_period == 0.001
    assert s.elapsed == pytest.approx(sum(periods))
    assert s.achieved_rate_hz == pytest.approx(1000 / sum(periods))
    assert s.period_mean == pytest.approx(sum(periods) / 1000)
    assert abs(s.period_p50 - 0.001) <= BIN_WIDTH + 1e-12
    assert abs(s.period_p99 - 0.0018) <= BIN_WIDTH + 1e-12  # the 990th of 1000
    assert s.period_max == pytest.approx(0.007)
    assert s.late_periods == 11 and s.overruns == 1  # 1.5 ms of compute > 1 ms
    assert s.periods_over == {0.002: 1, 0.005: 1}
    assert s.compute_max == pytest.approx(0.0015)
    assert s.period_p50 <= s.period_p99 <= s.period_max
    d = s.as_dict()
    assert d["period_max_ms"] == pytest.approx(7.0) and d["periods_over_5ms"] == 1


def test_ticks_in_passes_share_the_time_to_the_next_pass():
    """Passes of 4, 4 and 2 ticks paced at 1 kHz (a snapshot every 10 ticks): every period
    is 1 ms, not 2 ms for the ticks of a short pass after a long one."""
    recorder = PeriodRecorder(0.001)
    t, sizes = 5.0, [4, 4, 2] * 30
    for k in sizes:
        recorder.tick(t, t + 0.0002 * k, k)
        t += 0.001 * k
    s = recorder.statistics()
    assert s.ticks == sum(sizes)
    assert s.period_max == pytest.approx(0.001) and s.periods_over[0.002] == 0
    assert s.period_p99 <= 0.001 + BIN_WIDTH and s.late_periods == 0
    assert s.achieved_rate_hz == pytest.approx(1000.0)  # (the last pass's ticks: no period yet)
    assert s.compute_max == pytest.approx(0.0002) and s.overruns == 0
    late = PeriodRecorder(0.001)
    late.tick(0.0, 0.001, 4)
    late.tick(0.010, 0.011, 4)  # 6 ms late: each of the first pass's ticks took 2.5 ms
    assert late.statistics().period_max == pytest.approx(0.0025)
    assert late.statistics().late_periods == 4


def test_empty_and_overflow():
    recorder = PeriodRecorder(0.001, real_time=False)
    s = recorder.statistics()
    assert s.ticks == 0 and math.isnan(s.period_p99) and not s.real_time
    record(recorder, [0.2])  # beyond the 50 ms histogram: the exact maximum bounds it
    s = recorder.statistics()
    assert s.period_p99 == pytest.approx(0.2) and s.period_max == pytest.approx(0.2)
    with pytest.raises(ValueError):
        PeriodRecorder(0.0)


def test_shared_storage_is_read_by_another_reader():
    buffer = SharedBuffer(layout_size())
    try:
        writer = PeriodRecorder(0.001, buffer=buffer.mm)
        record(writer, [0.001] * 50)
        reader = PeriodRecorder(buffer=buffer.mm, clear=False)
        assert reader.statistics() == writer.statistics()
        s = period_statistics(reader.header, reader.period_hist, reader.compute_hist)
        assert s.ticks == 51
    finally:
        del writer, reader
        buffer.close()
