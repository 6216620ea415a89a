"""Period statistics of a tick loop: achieved rate, period percentiles, overruns.

:class:`PeriodRecorder` records, per tick, the *period* (wall time between the starts of two
consecutive ticks) and the *compute time* (wall time the tick's work took) into fixed-bin
histograms (10 µs bins up to 50 ms, plus one overflow bin), exact maxima and counters. Its
storage is one flat ``int64``/``float64`` layout, so it can live in shared memory: the loop
process writes, any process reads with :func:`period_statistics` at any time. Recording costs
a few µs per tick, whatever the run length. Ticks run in passes (several ticks in one
compiled call, ``LoopRunner(chunk=)``) share the time from their pass's start to the next
pass's start: their periods.

Definitions (as the cisst/dVRK interval statistics): an *overrun* is a tick whose compute
time exceeded the nominal period (the loop could not keep up during that tick); a *late*
period is one longer than 1.5 nominal periods. Percentiles come from the histogram and are
given as the upper edge of their bin (never optimistic by more than 10 µs).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

BIN_WIDTH = 10e-6
"""Histogram bin width, s."""
N_BINS = 5000
"""Bins below the overflow bin: 0 … 50 ms."""
LATE_FACTOR = 1.5

# Layout of the float64 header.
_N_PERIODS, _SUM_PERIOD, _MAX_PERIOD, _N_COMPUTE, _SUM_COMPUTE, _MAX_COMPUTE = range(6)
_OVERRUNS, _LATE, _FIRST_WALL, _LAST_WALL, _NOMINAL, _TICKS, _RESYNCS, _REAL_TIME = range(6, 14)
HEADER = 16


def layout_size() -> int:
    """Bytes of a recorder's storage."""
    return 8 * (HEADER + 2 * (N_BINS + 1))


@dataclass(frozen=True)
class PeriodStatistics:
    """Timing of a tick loop (all times in s)."""

    ticks: int
    """Ticks run."""
    elapsed: float
    """Wall time from the first to the last tick start."""
    achieved_rate_hz: float
    """Periods per second of wall time."""
    nominal_period: float
    real_time: bool
    period_mean: float
    period_p50: float
    period_p99: float
    period_max: float
    compute_p50: float
    compute_p99: float
    compute_max: float
    overruns: int
    """Ticks whose computation took longer than the nominal period."""
    late_periods: int
    """Periods longer than 1.5 nominal periods."""
    resyncs: int
    """Times a real-time loop fell too far behind and dropped the backlog."""
    periods_over: dict
    """Threshold (s) -> number of periods at least that long (2 and 5 ms)."""

    def as_dict(self) -> dict:
        """Flat figures with units in the names (for JSON results)."""
        out = {
            "ticks": self.ticks,
            "elapsed_s": self.elapsed,
            "achieved_rate_hz": self.achieved_rate_hz,
            "period_mean_ms": 1e3 * self.period_mean,
            "period_p50_ms": 1e3 * self.period_p50,
            "period_p99_ms": 1e3 * self.period_p99,
            "period_max_ms": 1e3 * self.period_max,
            "compute_p50_us": 1e6 * self.compute_p50,
            "compute_p99_us": 1e6 * self.compute_p99,
            "compute_max_us": 1e6 * self.compute_max,
            "overruns": self.overruns,
            "late_periods": self.late_periods,
            "resyncs": self.resyncs,
        }
        for threshold, n in self.periods_over.items():
            out[f"periods_over_{1e3 * threshold:g}ms"] = n
        return out


class PeriodRecorder:
    """Records periods and compute times (see the module docstring).

    Args:
        nominal_period: the loop's target period, s.
        real_time: whether the loop is paced (recorded in the statistics).
        buffer: storage to use (e.g. a shared-memory buffer of :func:`layout_size` bytes);
            default: private memory. A new recorder clears it.
        clear: False to attach to existing storage without clearing it (readers).
    """

    def __init__(
        self,
        nominal_period: float = 0.001,
        *,
        real_time: bool = True,
        buffer=None,
        clear: bool = True,
    ) -> None:
        if not (math.isfinite(nominal_period) and nominal_period > 0):
            raise ValueError(f"nominal_period must be > 0 s, got {nominal_period!r}")
        raw = bytearray(layout_size()) if buffer is None else buffer
        self.header = np.ndarray((HEADER,), dtype=np.float64, buffer=raw)
        self.period_hist = np.ndarray((N_BINS + 1,), dtype=np.int64, buffer=raw, offset=8 * HEADER)
        self.compute_hist = np.ndarray(
            (N_BINS + 1,), dtype=np.int64, buffer=raw, offset=8 * (HEADER + N_BINS + 1)
        )
        if clear:
            self.header[:] = 0.0
            self.period_hist[:] = 0
            self.compute_hist[:] = 0
            self.header[_NOMINAL] = nominal_period
            self.header[_REAL_TIME] = 1.0 if real_time else 0.0
            self.header[_FIRST_WALL] = math.nan
        self._last_start: float | None = None
        self._last_ticks = 1

    def tick(self, start: float, end: float, ticks: int = 1) -> None:
        """Record one tick that started at ``start`` and finished at ``end`` (wall s); or a
        pass of ``ticks`` run together then, each with its share of the compute time. A
        pass's ticks get their periods when the next pass starts: the time between the two
        starts shared by the ticks of the first (a pass of 2 ticks after one of 4 does not
        make the 4 ms between them two periods of 2 ms)."""
        h = self.header
        nominal = h[_NOMINAL]
        compute = (end - start) / ticks
        self.compute_hist[min(int(compute / BIN_WIDTH), N_BINS)] += ticks
        h[_N_COMPUTE] += ticks
        h[_SUM_COMPUTE] += end - start
        if compute > h[_MAX_COMPUTE]:
            h[_MAX_COMPUTE] = compute
        if compute > nominal:
            h[_OVERRUNS] += ticks
        last, n = self._last_start, self._last_ticks
        if last is None:
            h[_FIRST_WALL] = start
        else:
            period = (start - last) / n
            self.period_hist[min(int(period / BIN_WIDTH), N_BINS)] += n
            h[_N_PERIODS] += n
            h[_SUM_PERIOD] += start - last
            if period > h[_MAX_PERIOD]:
                h[_MAX_PERIOD] = period
            if period > LATE_FACTOR * nominal:
                h[_LATE] += n
        self._last_start, self._last_ticks = start, ticks
        h[_LAST_WALL] = start
        h[_TICKS] += ticks

    def resynced(self) -> None:
        """Count a real-time resynchronisation (the backlog was dropped)."""
        self.header[_RESYNCS] += 1

    def statistics(self) -> PeriodStatistics:
        return period_statistics(self.header, self.period_hist, self.compute_hist)


def _percentile(hist: np.ndarray, q: float, maximum: float) -> float:
    n = int(hist.sum())
    if n == 0:
        return math.nan
    rank = max(1, math.ceil(q * n))
    i = int(np.searchsorted(np.cumsum(hist), rank))
    if i >= N_BINS:
        return maximum  # in the overflow bin: the exact maximum bounds it
    return min((i + 1) * BIN_WIDTH, maximum)


def period_statistics(
    header: np.ndarray, period_hist: np.ndarray, compute_hist: np.ndarray
) -> PeriodStatistics:
    """:class:`PeriodStatistics` from a recorder's storage (copies it first: the writer
    may be running; the figures are then consistent within a tick or two)."""
    h = np.array(header)
    ph = np.array(period_hist)
    ch = np.array(compute_hist)
    n_periods = int(h[_N_PERIODS])
    elapsed = float(h[_LAST_WALL] - h[_FIRST_WALL]) if int(h[_TICKS]) > 1 else 0.0
    period_max = float(h[_MAX_PERIOD]) if n_periods else math.nan
    compute_max = float(h[_MAX_COMPUTE]) if h[_N_COMPUTE] else math.nan
    over = {}
    for threshold in (0.002, 0.005):
        edge = int(round(threshold / BIN_WIDTH))
        over[threshold] = int(ph[edge:].sum())
    return PeriodStatistics(
        ticks=int(h[_TICKS]),
        elapsed=elapsed,
        achieved_rate_hz=n_periods / elapsed if elapsed > 0 else math.nan,
        nominal_period=float(h[_NOMINAL]),
        real_time=bool(h[_REAL_TIME]),
        period_mean=float(h[_SUM_PERIOD] / n_periods) if n_periods else math.nan,
        period_p50=_percentile(ph, 0.50, period_max),
        period_p99=_percentile(ph, 0.99, period_max),
        period_max=period_max,
        compute_p50=_percentile(ch, 0.50, compute_max),
        compute_p99=_percentile(ch, 0.99, compute_max),
        compute_max=compute_max,
        overruns=int(h[_OVERRUNS]),
        late_periods=int(h[_LATE]),
        resyncs=int(h[_RESYNCS]),
        periods_over=over,
    )
