"""An attempt's overall score (0-100 %) and pass/fail, as the training simulators give them.

Each kind declares which of its metrics it scores (``SCORING``, a mapping in the task
file's ``scoring:`` format; a task file's ``scoring:`` entries update it metric by metric):

.. code-block:: yaml

    scoring:
      pass_score: 70          # optional: the overall score must also reach this, %
      force_threshold: 2.0    # N, of the excessive-force metric
      reference: seed_path    # expert reference data set (default: the task's name)
      metrics:                # metric: weight, fail (0 %) and optionally expert (100 %), pass_mark
        deviation_error: {weight: 2, fail: 0.005}
        completion_time: {weight: 1, fail: 120, pass_mark: 60}
        drops: {weight: 0}    # weight 0: not scored

**Score rule.** Metric i's value x_i maps linearly to a sub-score between its expert value
e_i (100 %) and its failing threshold f_i (0 %), clipped: s_i = 100·clip((f_i − x_i) /
(f_i − e_i), 0, 1) for a lower-is-better metric, (x_i − f_i) / (e_i − f_i) for a
higher-is-better one (f_i = e_i: 100 % at or better than e_i, else 0). The overall score is
the weighted mean Σ w_i·s_i / Σ w_i over the scored metrics that are available (a metric
the engine could not sample, nan, is left out and the weights renormalised; none
available: nan). e_i is the ``expert`` given, else the reference's mean.

**Pass mark.** Metric i's pass mark is its ``pass_mark`` if given (a programme sets it in
the task file), else the expert reference's mean + 1 SD (mean − 1 SD when higher is
better): Hugo RAS's rule (training.md §1). An attempt *passes* when it finished, every
scored metric with a mark is at or better than it (the dV-Trainer's "pass every metric"),
and the score reaches ``pass_score`` when one is set. With no mark and no ``pass_score``
there is nothing to pass: ``passed`` is None.

**Expert reference.** ``tasks/data/reference/<name>.json``: the mean, SD (n − 1) and n of
each metric over every attempt of a group of expert-parameter synthetic trainees
(:func:`davinci_sim.operators.params.sample_experts`) doing the task unassisted in the
study's batch engine; made by ``scripts/expert_reference.py``
(:func:`davinci_sim.study.reference.expert_reference`), which records how in the file. A
reference holds the digest of the task it was made on (:func:`task_digest`): a task whose
geometry or tolerances changed since does not use it (the marks would not be its).
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from davinci_sim.tasks.trainer import DEFAULT_FORCE_THRESHOLD

if TYPE_CHECKING:
    from davinci_sim.tasks.base import Task
    from davinci_sim.tasks.metrics import Metric

#: Columns a scored row adds after the metrics.
SCORE_COLUMNS = ("score", "passed")
_ITEM_KEYS = {"weight", "fail", "expert", "pass_mark"}
_KEYS = {"metrics", "pass_score", "force_threshold", "reference"}
#: Task-file keys that do not change what an attempt measures (left out of the digest).
_PRESENTATION = ("description", "fixture", "conditions", "visual", "scoring")


@dataclass(frozen=True)
class ScoreItem:
    """One scored metric: its weight, and its values scoring 0 % and 100 % (SI units)."""

    metric: str
    weight: float
    fail: float
    expert: float | None = None
    """Value scoring 100 % (None: the reference's mean)."""
    pass_mark: float | None = None
    """The programme's pass mark (None: the reference's mean ± 1 SD)."""
    better: str = "lower"


@dataclass(frozen=True)
class ReferenceValue:
    mean: float
    sd: float
    n: int


@dataclass(frozen=True)
class Reference:
    """An expert reference data set (see the module docstring)."""

    task: str
    digest: str
    metrics: dict[str, ReferenceValue]
    meta: dict = field(default_factory=dict)


@dataclass(frozen=True)
class AttemptScore:
    score: float
    """Overall score, % (nan: no scored metric available)."""
    passed: bool | None
    parts: dict[str, float]
    """Sub-score of each scored, available metric, %."""
    marks: dict[str, float]
    """Pass mark of each scored metric that has one (SI unit)."""


def metric_score(value: float, expert: float, fail: float, better: str = "lower") -> float:
    """Sub-score of one metric, % (see the module docstring); nan for a nan value."""
    if not math.isfinite(value):
        return math.nan
    if fail == expert:
        ok = value <= expert if better == "lower" else value >= expert
        return 100.0 if ok else 0.0
    frac = (fail - value) / (fail - expert)
    return 100.0 * min(max(frac, 0.0), 1.0)


def meets(value: float, mark: float, better: str = "lower") -> bool:
    """``value`` is at or better than ``mark``."""
    return value <= mark if better == "lower" else value >= mark


@dataclass(frozen=True)
class Scoring:
    """A task's scoring: items, pass rule, force threshold and reference."""

    items: tuple[ScoreItem, ...] = ()
    pass_score: float | None = None
    force_threshold: float = DEFAULT_FORCE_THRESHOLD
    reference_name: str | None = None
    reference: Reference | None = None
    note: str = ""
    """Why no reference is used, if none is."""

    def expert_value(self, item: ScoreItem) -> float:
        if item.expert is not None:
            return float(item.expert)
        ref = None if self.reference is None else self.reference.metrics.get(item.metric)
        return math.nan if ref is None else ref.mean

    def pass_mark(self, item: ScoreItem) -> float | None:
        if item.pass_mark is not None:
            return float(item.pass_mark)
        ref = None if self.reference is None else self.reference.metrics.get(item.metric)
        if ref is None or not math.isfinite(ref.mean):
            return None
        sd = ref.sd if math.isfinite(ref.sd) else 0.0
        return ref.mean + sd if item.better == "lower" else ref.mean - sd

    def score(self, values: dict[str, Any], finished: bool = True) -> AttemptScore:
        """The score of an attempt's metric ``values`` (name → SI value)."""
        parts: dict[str, float] = {}
        marks: dict[str, float] = {}
        total = weights = 0.0
        passed = True
        judged = False
        for item in self.items:
            x = float(values.get(item.metric, math.nan))
            mark = self.pass_mark(item)
            if mark is not None:
                marks[item.metric] = mark
                if math.isfinite(x):
                    judged = True
                    passed &= meets(x, mark, item.better)
            s = metric_score(x, self.expert_value(item), item.fail, item.better)
            if math.isfinite(s) and item.weight > 0:
                parts[item.metric] = s
                total += item.weight * s
                weights += item.weight
        score = total / weights if weights > 0 else math.nan
        if self.pass_score is not None:
            judged = True
            passed &= math.isfinite(score) and score >= self.pass_score
        return AttemptScore(score, (passed and bool(finished)) if judged else None, parts, marks)

    def row(self, values: dict[str, Any], finished: bool = True) -> dict[str, Any]:
        """The :data:`SCORE_COLUMNS` of an attempt: ``score`` (%, float; None when nothing
        is scored) and ``passed`` (bool; None without a pass mark)."""
        s = self.score(values, finished)
        return {"score": s.score if math.isfinite(s.score) else None, "passed": s.passed}


def parse_scoring(spec: dict, metrics: tuple[Metric, ...], task: str = "?") -> Scoring:
    """The :class:`Scoring` of a merged ``scoring`` mapping (without its reference);
    raises ValueError on a key, metric or number it cannot use."""
    if not isinstance(spec, dict):
        raise ValueError(f"scoring must be a mapping, got {spec!r}")
    unknown = set(spec) - _KEYS
    if unknown:
        raise ValueError(f"unknown scoring keys {sorted(unknown)}; keys: {sorted(_KEYS)}")
    declared = {m.name: m for m in metrics}
    items = []
    for name, entry in (spec.get("metrics") or {}).items():
        if name not in declared:
            raise ValueError(f"scoring: no metric {name!r}; metrics: {list(declared)}")
        if declared[name].better not in ("lower", "higher"):
            raise ValueError(f"scoring: {name} has no better direction, it cannot be scored")
        if not isinstance(entry, dict) or set(entry) - _ITEM_KEYS:
            raise ValueError(f"scoring: {name}: a mapping of {sorted(_ITEM_KEYS)}, got {entry!r}")
        for key, value in entry.items():
            if not (isinstance(value, int | float) and math.isfinite(value)):
                raise ValueError(f"scoring: {name}.{key} must be a finite number, got {value!r}")
        weight = float(entry.get("weight", 1.0))
        if weight < 0:
            raise ValueError(f"scoring: {name}.weight must be >= 0")
        if weight == 0:
            continue
        if "fail" not in entry:
            raise ValueError(f"scoring: {name} needs 'fail', the value scoring 0 %")
        items.append(
            ScoreItem(name, weight, float(entry["fail"]), _opt(entry.get("expert")),
                      _opt(entry.get("pass_mark")), declared[name].better)
        )  # fmt: skip
    pass_score = spec.get("pass_score")
    if pass_score is not None and not (
        isinstance(pass_score, int | float) and 0 <= pass_score <= 100
    ):
        raise ValueError(f"scoring: pass_score must be in [0, 100] %, got {pass_score!r}")
    threshold = spec.get("force_threshold", DEFAULT_FORCE_THRESHOLD)
    if not (isinstance(threshold, int | float) and math.isfinite(threshold) and threshold >= 0):
        raise ValueError(f"scoring: force_threshold must be a number >= 0 (N), got {threshold!r}")
    ref = spec.get("reference")
    if ref is not None and not isinstance(ref, str):
        raise ValueError(f"scoring: reference must be a name or a file, got {ref!r}")
    return Scoring(tuple(items), _opt(pass_score), float(threshold), ref)


def merge_scoring(default: dict, override: dict) -> dict:
    """A kind's ``SCORING`` updated by a task file's ``scoring`` (metric entries merged
    key by key)."""
    out = {k: v for k, v in default.items() if k != "metrics"}
    out.update({k: v for k, v in override.items() if k != "metrics"})
    metrics = {k: dict(v) for k, v in (default.get("metrics") or {}).items()}
    for name, entry in (override.get("metrics") or {}).items():
        # (an entry that is not a mapping is kept as it is: parse_scoring says what is wrong)
        metrics[name] = {**metrics.get(name, {}), **entry} if isinstance(entry, dict) else entry
    if metrics:
        out["metrics"] = metrics
    return out


def task_scoring(task: Task) -> Scoring:
    """``task``'s :class:`Scoring` with its reference (if one matches the task)."""
    spec = merge_scoring(getattr(task, "SCORING", {}), getattr(task, "scoring_spec", {}) or {})
    scoring = parse_scoring(spec, task.METRICS, task.name)
    name = scoring.reference_name or task.name
    try:
        ref = load_reference(name)
    except FileNotFoundError:
        return _replace(scoring, note=f"no expert reference {name!r}")
    digest = task_digest(task)
    if ref.digest != digest:
        return _replace(scoring, note=f"the reference {name!r} was made on another task")
    return _replace(scoring, reference=ref)


def _replace(scoring: Scoring, **kw) -> Scoring:
    from dataclasses import replace

    return replace(scoring, **kw)


def _opt(x) -> float | None:
    return None if x is None else float(x)


# ---------------------------------------------------------------- reference data
def task_digest(task: Task) -> str:
    """A digest of what ``task`` measures (its file mapping without description, fixtures,
    look and scoring), 16 hex digits."""
    from davinci_sim.tasks.base import task_to_dict

    data = {k: v for k, v in task_to_dict(task).items() if k not in _PRESENTATION}
    text = json.dumps(data, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def reference_dir():
    return resources.files("davinci_sim.tasks") / "data" / "reference"


def load_reference(name_or_path: str | Path) -> Reference:
    """A reference data set: a shipped one by name or a ``.json`` file (FileNotFoundError
    if there is none)."""
    path = Path(str(name_or_path))
    if path.suffix == ".json" and path.is_file():
        text = path.read_text()
    else:
        candidate = reference_dir() / f"{name_or_path}.json"
        if not candidate.is_file():
            raise FileNotFoundError(f"no expert reference {str(name_or_path)!r}")
        text = candidate.read_text()
    data = json.loads(text)
    metrics = {
        k: ReferenceValue(_nan(v["mean"]), _nan(v["sd"]), int(v["n"]))
        for k, v in data["metrics"].items()
    }
    meta = {k: v for k, v in data.items() if k not in ("task", "task_digest", "metrics")}
    return Reference(data["task"], data["task_digest"], metrics, meta)


def _nan(x) -> float:
    return math.nan if x is None else float(x)


def reference_from_rows(task: Task, rows: list[dict], **meta) -> dict:
    """The reference mapping (JSON-ready) of attempts ``rows`` of ``task``: per metric the
    mean, sample SD (n − 1) and n over the finite values of finished attempts; ``meta``
    says how they were made."""
    done = [r for r in rows if r.get("finished", True)]
    metrics = {}
    for m in task.METRICS:
        x = np.array([float(r[m.name]) for r in done], dtype=float)
        x = x[np.isfinite(x)]
        mean = float(x.mean()) if len(x) else None
        sd = float(x.std(ddof=1)) if len(x) > 1 else (0.0 if len(x) else None)
        metrics[m.name] = {"mean": mean, "sd": sd, "n": len(x), "unit": m.unit}
    return {
        "task": task.name,
        "task_digest": task_digest(task),
        **meta,
        "attempts": len(rows),
        "finished": len(done),
        "metrics": metrics,
    }
