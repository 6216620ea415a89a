"""Metrics of task repetitions: declared once, computed from the sample records.

**The declaration.** Each kind of task lists its metrics as :class:`Metric` values (name,
SI unit, which direction is better, description, how it reduces the samples, how reports
show it), in order: the task's ``METRICS``. Everything that shows a metric reads that list:
the session's rows and CSV log and the bridge's ``/task/results`` (:meth:`MetricValues.row`),
the study's ``trials.csv`` columns and its report's summary table. Adding a metric to a
kind is one more entry in its list.

**The computation.** A metric reduces the :class:`~davinci_sim.tasks.base.Sample` records of
a repetition (one per tick while the task is RUNNING, up to the one where it is FINISHED)
and the task's per-sample observations (e.g. ``distance``, the tip's distance to the path)
with one of the reducers :class:`Mean`, :class:`RootMeanSquare`, :class:`Peak`,
:class:`PairSum`, :class:`Elapsed`, :class:`Count` or :class:`Ratio`.
:class:`MetricsAccumulator` runs the reducers of a list of metrics for n trials, sample by
sample, without storing the trajectories (O(n) memory whatever the duration); its
:meth:`~MetricsAccumulator.result` is a :class:`MetricValues`.
Reducers: ``init(n, task)``, ``add``, ``final``; a metric reading an optional sample field
(``Metric.needs``) is nan when a sample lacks it (:mod:`davinci_sim.tasks.trainer`).

**The path-following metrics** (:data:`PATH_METRICS`, the seed's task): over the samples
i = 1..K of a repetition at times t_i (s), with tip positions p_i (m, task frame), distances
to the path ‖φ_i‖ (m), forces on the hand F_i (N) and the clutch pedal c_i:

* **deviation error** e_jn = (1/K)·Σ ‖φ_i‖, m — equation (8) of the seed: the mean over the
  time steps of the distance to the path (a time average when the rate is constant, as the
  1 kHz haptic loop's is);
* **RMS deviation** √((1/K)·Σ ‖φ_i‖²), m — the metric of Rota's dVRK-console study
  (training.md §4: the RMS over their 30 Hz frames of the distance to the nearest vertex of
  a trajectory whose vertices are 44 µm apart; here over the 1 kHz samples, to the polyline);
* **maximum deviation** max ‖φ_i‖, m — Enayati et al. 2016's Table II (0 without samples);
* **completion time** T = t_K − t_1, s;
* **path length** of the tip Σ_{i≥2} ‖p_i − p_{i−1}‖, m — economy of motion, as commercial
  trainers score it (the shortest possible is about the path's length). It depends on the
  sampling: at 1 kHz it includes the tremor's back-and-forth (tens of µm at ~10 Hz add a few
  mm per second), which a camera-rate tracker would not see;
* **mean speed** = path length / T, m/s (nan if T = 0);
* **peak force** max ‖F_i‖ and **mean force** (1/K)·Σ ‖F_i‖, N — of the guidance the hand
  feels;
* **time outside** the tolerance tube Σ_{i≥2} (t_i − t_{i−1})·[‖φ_i‖ > r], s — each interval
  counted by its end sample, r the task's ``tube_radius``;
* **clutch count**: presses of the clutch, the samples where it goes from released to
  pressed (i ≥ 2; a clutch already pressed at the first sample is not a press);
* **samples**: K.

The array functions below (:func:`repetition_metrics` and one per metric) compute the same
numbers from recorded arrays with a leading trial axis, (n, K[, 3]), and a mask (n, K) of the
samples of each repetition (one contiguous run per trial; a 1-D (K,) input is one trial);
sums over pairs use the pairs of consecutive samples that are both in the mask. They are
the independent reference the accumulator is tested against.

Size: about 600 lines because the declaration, the reducers and the accumulator that
runs them are one contract (each reducer also says whether a sample no trial measures
leaves it unchanged, which the live session's every tick relies on); the path task's
reference functions are the tests' oracle for the same metrics.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

if TYPE_CHECKING:
    from davinci_sim.tasks.base import Sample


class RepetitionMetrics(NamedTuple):
    """The path-following metrics of a batch of recorded repetitions, each (n,), as
    :func:`repetition_metrics` computes them (the reference of :data:`PATH_METRICS`)."""

    deviation_error: np.ndarray
    deviation_rms: np.ndarray
    deviation_max: np.ndarray
    completion_time: np.ndarray
    path_length: np.ndarray
    mean_speed: np.ndarray
    peak_force: np.ndarray
    mean_force: np.ndarray
    time_outside: np.ndarray
    clutch_count: np.ndarray
    samples: np.ndarray
    """K, the number of samples of each repetition."""


def _2d(x, mask, trailing: int = 0):
    a = np.asarray(x)
    m = np.asarray(mask, dtype=bool)
    if m.ndim == 1:
        m = m[None]
        a = a[None]
    if a.shape[: a.ndim - trailing] != m.shape:
        raise ValueError(f"data of shape {np.shape(x)} does not match the mask {np.shape(mask)}")
    return a, m


def _pairs(m: np.ndarray) -> np.ndarray:
    """(n, K−1): sample i and i−1 both in the repetition."""
    return m[:, 1:] & m[:, :-1]


def _mean(values: np.ndarray, m: np.ndarray) -> np.ndarray:
    k = m.sum(axis=1)
    total = np.where(m, values, 0.0).sum(axis=1)
    return np.where(k > 0, total / np.maximum(k, 1), np.nan)


def deviation_error(distance, mask) -> np.ndarray:
    """e_jn of equation (8): mean distance to the path over the samples, m."""
    d, m = _2d(distance, mask)
    return _mean(d.astype(float), m)


def deviation_rms(distance, mask) -> np.ndarray:
    """Root mean square of the distance to the path over the samples, m."""
    d, m = _2d(distance, mask)
    return np.sqrt(_mean(d.astype(float) ** 2, m))


def deviation_max(distance, mask) -> np.ndarray:
    """Largest distance to the path over the samples, m (0 without samples)."""
    d, m = _2d(distance, mask)
    return np.where(m, d.astype(float), 0.0).max(axis=1, initial=0.0)


def completion_time(time, mask) -> np.ndarray:
    """t_K − t_1, s (nan without samples)."""
    t, m = _2d(np.broadcast_to(time, np.shape(mask)), mask)
    has = m.any(axis=1)
    first = np.argmax(m, axis=1)
    last = m.shape[1] - 1 - np.argmax(m[:, ::-1], axis=1)
    rows = np.arange(len(m))
    return np.where(has, t[rows, last] - t[rows, first], np.nan)


def path_length(position, mask) -> np.ndarray:
    """Length of the tip's trajectory, m."""
    p, m = _2d(position, mask, trailing=1)
    step = np.linalg.norm(np.diff(p, axis=1), axis=2)
    return np.where(_pairs(m), step, 0.0).sum(axis=1)


def mean_speed(position, time, mask) -> np.ndarray:
    """Path length over completion time, m/s (nan if the time is 0)."""
    T = completion_time(time, mask)
    L = path_length(position, mask)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(T > 0, L / np.where(T > 0, T, 1.0), np.nan)


def force_peak(force, mask) -> np.ndarray:
    """max ‖F_i‖, N (0 without samples)."""
    f, m = _2d(force, mask, trailing=1)
    return np.where(m, np.linalg.norm(f, axis=2), 0.0).max(axis=1, initial=0.0)


def force_mean(force, mask) -> np.ndarray:
    """(1/K)·Σ ‖F_i‖, N."""
    f, m = _2d(force, mask, trailing=1)
    return _mean(np.linalg.norm(f, axis=2), m)


def time_outside(distance, time, mask, *, tube_radius: float) -> np.ndarray:
    """Time spent farther than ``tube_radius`` from the path, s."""
    d, m = _2d(distance, mask)
    t, _ = _2d(np.broadcast_to(time, np.shape(mask)), mask)
    dt = np.diff(t.astype(float), axis=1)
    return np.where(_pairs(m) & (d[:, 1:] > tube_radius), dt, 0.0).sum(axis=1)


def clutch_count(clutch, mask) -> np.ndarray:
    """Number of clutch presses (released → pressed transitions) during the repetition."""
    c, m = _2d(clutch, mask)
    c = c.astype(bool)
    return (_pairs(m) & c[:, 1:] & ~c[:, :-1]).sum(axis=1)


def repetition_metrics(
    time, position, distance, force, clutch, mask, *, tube_radius: float
) -> RepetitionMetrics:
    """All the metrics of a batch of recorded repetitions (see the module docstring)."""
    m = np.asarray(mask, dtype=bool)
    return RepetitionMetrics(
        deviation_error(distance, m),
        deviation_rms(distance, m),
        deviation_max(distance, m),
        completion_time(time, m),
        path_length(position, m),
        mean_speed(position, time, m),
        force_peak(force, m),
        force_mean(force, m),
        time_outside(distance, time, m, tube_radius=tube_radius),
        clutch_count(clutch, m),
        np.atleast_2d(m).sum(axis=1),
    )


# ---------------------------------------------------------------- declaration
#: A per-sample value: ``value(task, sample, obs) -> (n,)``, with ``obs`` the task's
#: observations of the sample (:meth:`davinci_sim.tasks.base.Task.step`).
Value = Callable[[Any, "Sample", dict], np.ndarray]
#: A value of two consecutive samples: ``value(task, previous, sample, obs) -> (n,)``.
PairValue = Callable[[Any, "Sample", "Sample", dict], np.ndarray]


def observed(key: str, dtype=np.int64) -> Value:
    """The value a kind's step observes under ``key`` (its ``obs``) as (n,) ``dtype``; zeros
    where a kind observes no such thing (a kind without objects has no drops)."""

    def value(task, s, obs):
        v = obs.get(key)
        return np.zeros(s.n, dtype=dtype) if v is None else np.asarray(v, dtype=dtype)

    value.__name__ = f"observed_{key}"
    return value


def _float_acc(acc) -> bool:
    """``acc + where(False, value, 0)`` is ``acc`` whatever the value's type: float64 (an
    integer running sum would turn float with a float value)."""
    return isinstance(acc, np.ndarray) and acc.dtype == np.float64


def _always(acc) -> bool:
    """A reducer whose ``add`` with an all-false mask gives its running value back as it is
    (``unchanged_unmeasured``: :meth:`MetricsAccumulator.update` then skips it)."""
    return True


@dataclass(frozen=True)
class Mean:
    """(1/K)·Σ value_i over the repetition's samples (nan without samples)."""

    value: Value

    unchanged_unmeasured = staticmethod(_always)  # (MetricsAccumulator.update)

    def init(self, n: int, task=None):
        return np.zeros(n)

    def add(self, acc, m, pair, task, prev, s, obs):
        return acc + np.where(m, self.value(task, s, obs), 0.0)

    def final(self, acc, k, done):
        return np.where(k > 0, acc / np.maximum(k, 1), np.nan)


@dataclass(frozen=True)
class RootMeanSquare(Mean):
    """√((1/K)·Σ value_i²) over the repetition's samples (nan without samples): the
    :class:`Mean` of the squared value, its root."""

    def add(self, acc, m, pair, task, prev, s, obs):
        v = self.value(task, s, obs)
        return acc + np.where(m, v * v, 0.0)

    def final(self, acc, k, done):
        return np.sqrt(super().final(acc, k, done))


@dataclass(frozen=True)
class Peak:
    """max value_i over the repetition's samples (0 without samples)."""

    value: Value

    unchanged_unmeasured = staticmethod(_always)  # (MetricsAccumulator.update)

    def init(self, n: int, task=None):
        return np.zeros(n)

    def add(self, acc, m, pair, task, prev, s, obs):
        return np.where(m, np.maximum(acc, self.value(task, s, obs)), acc)

    def final(self, acc, k, done):
        return acc.copy()


@dataclass(frozen=True)
class PairSum:
    """Σ_{i≥2} value(sample_{i−1}, sample_i) over pairs of consecutive samples both in the
    repetition; integer when ``integer`` (counts)."""

    value: PairValue
    integer: bool = False

    unchanged_unmeasured = staticmethod(_float_acc)  # (MetricsAccumulator.update)

    def init(self, n: int, task=None):
        return np.zeros(n, dtype=np.int64 if self.integer else float)

    def add(self, acc, m, pair, task, prev, s, obs):
        return acc + np.where(pair, self.value(task, prev, s, obs), 0)

    def final(self, acc, k, done):
        return acc.copy()


@dataclass(frozen=True)
class Elapsed:
    """t_K − t_1, s (nan without samples)."""

    unchanged_unmeasured = staticmethod(_always)  # (MetricsAccumulator.update)

    def init(self, n: int, task=None):
        return (np.full(n, np.nan), np.full(n, np.nan))

    def add(self, acc, m, pair, task, prev, s, obs):
        t0, t1 = acc
        return (np.where(m & np.isnan(t0), s.time, t0), np.where(m, s.time, t1))

    def final(self, acc, k, done):
        return acc[1] - acc[0]


@dataclass(frozen=True)
class Count:
    """K, the number of samples of the repetition."""

    unchanged_unmeasured = staticmethod(_always)  # (MetricsAccumulator.update)

    def init(self, n: int, task=None):
        return None

    def add(self, acc, m, pair, task, prev, s, obs):
        return None

    def final(self, acc, k, done):
        return k.copy()


@dataclass(frozen=True)
class Ratio:
    """One metric over another, of metrics declared before it (nan where the divisor is
    not > 0)."""

    numerator: str
    denominator: str

    unchanged_unmeasured = staticmethod(_always)  # (MetricsAccumulator.update)

    def init(self, n: int, task=None):
        return None

    def add(self, acc, m, pair, task, prev, s, obs):
        return None

    def final(self, acc, k, done):
        a, b = done[self.numerator], done[self.denominator]
        return np.where(b > 0, a / np.where(b > 0, b, 1.0), np.nan)


Reducer = Mean | RootMeanSquare | Peak | PairSum | Elapsed | Count | Ratio


@dataclass(frozen=True)
class Metric:
    """One metric of a kind of task: what it is and how the samples make it."""

    name: str
    """Column and key name (snake case)."""
    unit: str
    """SI unit of the value (``1`` for counts)."""
    better: str
    """``lower``, ``higher`` or ``neither``: which way is the better performance."""
    description: str
    reduce: Reducer
    integer: bool = False
    """A count: rows hold an ``int``, else a ``float``."""
    label: str = ""
    """Short label in tables (default: the name with spaces)."""
    report: tuple[str, float] | None = None
    """(unit, scale) of the study report's summary table (None: not in the table)."""
    display: tuple[str, float] | None = None
    """(unit, scale) trainers read it in, e.g. ``("cm", 100.0)`` for a length in m (None:
    :attr:`unit`)."""
    needs: tuple[str, ...] = ()
    """Optional :class:`~davinci_sim.tasks.base.Sample` fields the value reads (``visible``,
    ``master``, ``contacts``, ``tool_force``): where a sample lacks one (None), the metric
    is *unavailable*, nan in the results."""

    def __post_init__(self) -> None:
        if self.better not in ("lower", "higher", "neither"):
            raise ValueError(f"metric {self.name!r}: better must be lower, higher or neither")
        if not self.label:
            object.__setattr__(self, "label", self.name.replace("_", " "))


class MetricValues:
    """The metrics of n repetitions: ``values.name`` or ``values["name"]`` is an (n,) array,
    in the declaration's order (:attr:`metrics`)."""

    def __init__(self, metrics: tuple[Metric, ...], values: dict[str, np.ndarray]) -> None:
        self.metrics = tuple(metrics)
        self._values = dict(values)

    @property
    def _fields(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.metrics)

    def __getattr__(self, name: str) -> np.ndarray:
        try:
            return self.__dict__["_values"][name]
        except KeyError:
            raise AttributeError(name) from None

    def __getitem__(self, name: str) -> np.ndarray:
        return self._values[name]

    def __iter__(self) -> Iterator[np.ndarray]:
        return (self._values[m.name] for m in self.metrics)

    def __len__(self) -> int:
        return len(self.metrics)

    def row(self, i: int = 0) -> dict[str, int | float]:
        """Trial ``i``'s metrics as a row: name → int (counts) or float, in order."""
        return metric_row(self.metrics, self, i)


def metric_row(metrics: tuple[Metric, ...], values, i: int = 0) -> dict[str, int | float]:
    """Row ``i`` of ``values`` (anything with an (n,) attribute per metric name) as
    name → int (counts) or float, in the declaration's order; an unavailable count is a
    float nan."""
    row: dict[str, int | float] = {}
    for m in metrics:
        v = float(getattr(values, m.name)[i])
        row[m.name] = int(v) if m.integer and math.isfinite(v) else v
    return row


class MetricsAccumulator:
    """The ``metrics`` of n trials, accumulated sample by sample (no trajectories stored).

    Args:
        metrics: the declaration (a task's ``METRICS``).
        n: trials.
        task: passed to the metrics' value functions (e.g. for a tolerance).
    """

    def __init__(self, metrics: tuple[Metric, ...], n: int, task: Any = None) -> None:
        self.metrics = tuple(metrics)
        self.n = n
        self.task = task
        self.unchanged_checks = tuple(
            getattr(m.reduce, "unchanged_unmeasured", None) for m in self.metrics
        )
        """Each metric's reducer's ``unchanged_unmeasured`` (None: always run its ``add``)."""
        from davinci_sim.tasks import metrics_one  # (it imports this module's declarations)

        self.floats = metrics_one.applies(self.metrics, 1)
        """Whether one trial's :meth:`update` runs on floats (:mod:`~davinci_sim.tasks.metrics_one`:
        the path kind's declaration)."""
        self.reset()

    def reset(self, mask=None) -> None:
        """Start over, all trials or those where ``mask`` (n,) is true."""
        fresh = [m.reduce.init(self.n, self.task) for m in self.metrics]
        if mask is None:
            self._acc = fresh
            self._missing: set[str] = set()
            self._k = np.zeros(self.n, dtype=np.int64)
            self._prev_in = np.zeros(self.n, dtype=bool)
            self._prev = None
            return
        m = np.asarray(mask, dtype=bool)
        self._acc = [_where(m, f, a) for f, a in zip(fresh, self._acc, strict=True)]
        self._k = np.where(m, 0, self._k)
        self._prev_in = self._prev_in & ~m

    def take(self, rows) -> MetricsAccumulator:
        """An accumulator of the trials ``rows`` (indices), with what they have so far."""
        rows = np.asarray(rows, dtype=int)
        out = copy.copy(self)
        out._acc = [_take(a, rows) for a in self._acc]
        out._k = self._k[rows]
        out._prev_in = self._prev_in[rows]
        out._missing = set(self._missing)
        out._prev = None if self._prev is None else self._prev.take(rows)
        out.n = len(rows)
        return out

    def update(self, mask, sample: Sample, obs: dict) -> None:
        """One sample of every trial; ``mask`` (n,) marks the trials whose repetition
        includes it; ``obs`` the task's observations of it."""
        if self.floats and self.n == 1 and _floats_update(self, mask, sample, obs):
            return
        m = np.asarray(mask, dtype=bool)
        pair = m & self._prev_in
        prev = sample if self._prev is None else self._prev
        # No trial measures this sample (the live session between repetitions, most of its
        # ticks): a reducer that declares it leaves its running value as it is skips the
        # arithmetic that would give back the same bits (x + 0.0, where(False, ...)).
        idle = not m.any()
        acc_new = []
        for metric, acc, unchanged in zip(
            self.metrics, self._acc, self.unchanged_checks, strict=True
        ):
            if metric.needs and any(getattr(sample, f) is None for f in metric.needs):
                self._missing.add(metric.name)  # the sample cannot tell: unavailable
                acc_new.append(acc)
                continue
            if idle and unchanged is not None and unchanged(acc):
                acc_new.append(acc)
                continue
            acc_new.append(metric.reduce.add(acc, m, pair, self.task, prev, sample, obs))
        self._acc = acc_new
        self._k = self._k + m
        self._prev_in = m.copy()
        if self._prev is None:
            self._prev = sample
        else:
            self._prev = self._prev.kept(sample) if idle else self._prev.where(m, sample)

    def result(self) -> MetricValues:
        done: dict[str, np.ndarray] = {}
        with np.errstate(invalid="ignore", divide="ignore"):
            for metric, acc in zip(self.metrics, self._acc, strict=True):
                value = metric.reduce.final(acc, self._k, done)
                if metric.name in self._missing:
                    value = np.full(self.n, np.nan)
                done[metric.name] = value
        return MetricValues(self.metrics, done)

    def get_state(self) -> dict:
        """The running reductions, the counts and the previous sample (copies)."""
        return copy.deepcopy({k: v for k, v in vars(self).items() if k.startswith("_")})

    def set_state(self, state: dict) -> None:
        for k, v in copy.deepcopy(state).items():
            setattr(self, k, v)


def _floats_update(acc, mask, sample, obs) -> bool:
    from davinci_sim.tasks.metrics_one import update_one

    return update_one(acc, mask, sample, obs)


def _where(m, fresh, acc):
    if acc is None:
        return None
    if isinstance(acc, tuple):
        return tuple(_where(m, f, a) for f, a in zip(fresh, acc, strict=True))
    # (n,) mask against (n, ...) reductions (e.g. an (n, 3) extent)
    return np.where(m.reshape(-1, *([1] * (np.ndim(acc) - 1))), fresh, acc)


def _take(acc, rows):
    if acc is None:
        return None
    if isinstance(acc, tuple):
        return tuple(a[rows] for a in acc)
    return acc[rows]


# ---------------------------------------------------------------- the path task's metrics
def _distance(task, s, obs):
    return obs["distance"]


def _force_norm(task, s, obs):
    return s.force_magnitude


def _step_length(task, prev, s, obs):
    return np.linalg.norm(s.tip - prev.tip, axis=1)


def _outside(task, prev, s, obs):
    return np.where(obs["distance"] > task.tube_radius, s.time - prev.time, 0.0)


def _press(task, prev, s, obs):
    return s.clutch & ~prev.clutch


#: The metrics of a path-following repetition (see the module docstring), in the order of
#: the rows' columns. The value functions read the task's ``tube_radius`` and the
#: observation ``distance`` (the tip's distance to the path, m).
PATH_METRICS: tuple[Metric, ...] = (
    Metric("deviation_error", "m", "lower", "mean distance of the tool tip to the path "
           "(the seed's eq. 8)", Mean(_distance), label="deviation e", report=("mm", 1e3)),
    Metric("deviation_rms", "m", "lower", "root mean square distance of the tool tip to the "
           "path (Rota's metric)", RootMeanSquare(_distance), label="RMS deviation",
           report=("mm", 1e3)),
    Metric("deviation_max", "m", "lower", "largest distance of the tool tip to the path "
           "(Enayati 2016's)", Peak(_distance), label="max deviation", report=("mm", 1e3)),
    Metric("completion_time", "s", "lower", "time from leaving point 1 to reaching the last "
           "point", Elapsed(), report=("s", 1.0)),
    Metric("path_length", "m", "lower", "length of the tool tip's trajectory (economy of "
           "motion)", PairSum(_step_length), report=("mm", 1e3), display=("cm", 100.0)),
    Metric("mean_speed", "m/s", "higher", "path length over completion time",
           Ratio("path_length", "completion_time"), report=("mm/s", 1e3)),
    Metric("peak_force", "N", "neither", "largest guidance force on the hand",
           Peak(_force_norm), report=("N", 1.0)),
    Metric("mean_force", "N", "neither", "mean guidance force on the hand",
           Mean(_force_norm), report=("N", 1.0)),
    Metric("time_outside", "s", "lower", "time farther than tube_radius from the path",
           PairSum(_outside), report=("s", 1.0)),
    Metric("clutch_count", "1", "lower", "presses of the clutch", PairSum(_press, True),
           integer=True),
    Metric("samples", "1", "neither", "samples of the repetition (1 kHz ticks)", Count(),
           integer=True),
)  # fmt: skip
