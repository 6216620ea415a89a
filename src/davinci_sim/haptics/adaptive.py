"""Adaptive guidance: the seed's viscous fixture with a strength B that follows the trainee
between repetitions (fixture entry ``type: adaptive``, :mod:`davinci_sim.haptics.kinds`).

Within a repetition the fixture *is* the seed's viscous law
(:class:`~davinci_sim.haptics.viscous.ViscousGuidance`) with the current ``B`` and a fixed
``G_max``: B never changes inside a repetition. Between repetitions an update rule, a pure
function of the history of the trainee's errors in this condition, gives the next B:

* ``mode: assist_as_needed`` — assistance as needed: with ē the mean of the task's error
  metric (``metric``, default ``deviation_error``, m) over the last ``window`` repetitions,
  ``B' = clip(B + clip(gain·(ē − target), −max_step, max_step), B_min, B_max)``: B rises
  when the recent error is above ``target`` and falls after good repetitions, by at most
  ``max_step`` per repetition, and stays in [B_min, B_max]. Repetitions without a finite
  error (none yet) leave B as it is. The idea — the robot assists only as much as the
  error says is needed, and withdraws otherwise — is the assist-as-needed principle of
  robot-aided motor training (Emken, Bobrow & Reinkensmeyer, "Robotic movement training as
  an optimization problem: designing a controller that assists only as needed", ICORR 2005:
  an error-based update with a forgetting term; reviewed in Marchal-Crespo & Reinkensmeyer
  2009, "Review of control strategies for robotic movement training after neurologic
  injury", J NeuroEng Rehabil 6:20). This linear, target-error form with a step limit is
  ours.
* ``mode: fading`` — guidance withdrawn over practice: at repetition j (1-based, in this
  condition) ``B_j = B0·max(0, 1 − (j − 1)/(zero_at − 1))``: B0 at the first repetition,
  linearly down to 0 at repetition ``zero_at`` and after. The reason to fade is the guidance
  hypothesis (Salmoni, Schmidt & Walter 1984, Psychol Bull 95:355): feedback that guides
  every trial helps while it is there and can harm retention once it is removed; the
  guidance literature in ``training.md`` §3 (Oquendo et al. 2023) found the same for haptic
  guidance. The linear schedule is ours.

The default parameters (B0 = 40 N·s/m and G_max = 5 N, the seed's Table I middle row;
target 1.5 mm; gain 10 N·s/m per mm; max_step 10 N·s/m; [B_min, B_max] = [0, 60] N·s/m, the
range of Table I; window 3; zero_at 8) are our choices, not values from the sources.

The live session (:class:`~davinci_sim.tasks.session.TaskSession`) applies :func:`next_B`
after each finished repetition; the study resolves each trial's B with :func:`B_at` from the
subject's earlier rows in the condition (:mod:`davinci_sim.study.adaptive`): the same rule.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from davinci_sim.haptics.viscous import DEFAULT_TRANSITION, ViscousGuidance

MODES = ("assist_as_needed", "fading")

#: The parameters of an adaptive entry and their defaults (our choices, see the module
#: docstring). ``B`` (the current B, N·s/m) is set by whoever runs the fixture; absent, B0.
DEFAULTS: dict[str, Any] = {
    "mode": "assist_as_needed",
    "B0": 40.0,
    "G_max": 5.0,
    "transition": DEFAULT_TRANSITION,
    "metric": "deviation_error",
    "target": 0.0015,
    "gain": 10000.0,
    "max_step": 10.0,
    "B_min": 0.0,
    "B_max": 60.0,
    "window": 3.0,
    "zero_at": 8.0,
}
PARAMS = frozenset(DEFAULTS) | {"B"}


@dataclass(frozen=True)
class AdaptiveRule:
    """An adaptive entry's update rule (see the module docstring); units: B in N·s/m,
    G_max in N, target in the metric's unit (m for ``deviation_error``), gain in N·s/m per
    unit of the metric."""

    mode: str = "assist_as_needed"
    B0: float = 40.0
    G_max: float = 5.0
    metric: str = "deviation_error"
    target: float = 0.0015
    gain: float = 10000.0
    max_step: float = 10.0
    B_min: float = 0.0
    B_max: float = 60.0
    window: int = 3
    zero_at: int = 8

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"adaptive mode must be one of {MODES}, got {self.mode!r}")
        if not isinstance(self.metric, str) or not self.metric:
            raise ValueError(f"adaptive metric must be a metric name, got {self.metric!r}")
        for name in ("B0", "G_max", "target", "gain", "max_step", "B_min", "B_max"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise ValueError(f"adaptive {name} must be a finite number >= 0, got {v!r}")
            object.__setattr__(self, name, float(v))
        for name, low in (("window", 1), ("zero_at", 2)):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and float(v).is_integer() and v >= low):
                raise ValueError(f"adaptive {name} must be a whole number >= {low}, got {v!r}")
            object.__setattr__(self, name, int(v))
        if self.B_min > self.B_max:
            raise ValueError(f"adaptive B_min {self.B_min} > B_max {self.B_max}")
        if self.mode == "assist_as_needed" and not self.B_min <= self.B0 <= self.B_max:
            raise ValueError(f"adaptive B0 {self.B0} not in [B_min, B_max] = "
                             f"[{self.B_min}, {self.B_max}]")  # fmt: skip

    @classmethod
    def of(cls, params: Mapping[str, Any]) -> AdaptiveRule:
        """The rule of an adaptive entry's parameters (defaults for those left out; the
        entry's ``type``, ``name``, ``B`` and ``transition`` are not the rule's)."""
        fields = set(cls.__dataclass_fields__)
        return cls(**{k: v for k, v in {**DEFAULTS, **params}.items() if k in fields})

    @property
    def uses_history(self) -> bool:
        """Whether B depends on the trainee's errors (assist-as-needed) or only on the
        repetition number (fading)."""
        return self.mode == "assist_as_needed"


def assist_as_needed_B(B: float, recent_errors: Sequence[float], rule: AdaptiveRule) -> float:
    """The assist-as-needed update: B (N·s/m) after repetitions with ``recent_errors``
    (the last ``rule.window`` are used; non-finite ones ignored; none: B unchanged)."""
    recent = [float(e) for e in list(recent_errors)[-rule.window :] if math.isfinite(e)]
    if not recent:
        return float(B)
    step = rule.gain * (sum(recent) / len(recent) - rule.target)
    step = min(rule.max_step, max(-rule.max_step, step))
    return min(rule.B_max, max(rule.B_min, float(B) + step))


def fading_B(repetition: int, rule: AdaptiveRule) -> float:
    """The fading schedule: B (N·s/m) of repetition ``repetition`` (1-based)."""
    if repetition < 1:
        raise ValueError(f"repetitions are numbered from 1, got {repetition!r}")
    return rule.B0 * max(0.0, 1.0 - (repetition - 1) / (rule.zero_at - 1))


def next_B(B: float, errors: Sequence[float], rule: AdaptiveRule) -> float:
    """B for the next repetition, given the current ``B`` and the ``errors`` of every
    repetition so far in this condition (in order): the live session's update."""
    if rule.mode == "fading":
        return fading_B(len(errors) + 1, rule)
    return assist_as_needed_B(B, errors, rule)


def B_schedule(errors: Sequence[float], rule: AdaptiveRule) -> list[float]:
    """B of repetitions 1 .. len(errors) + 1, starting at B0 (fading: its schedule)
    and applying :func:`next_B` after each error."""
    Bs = [fading_B(1, rule) if rule.mode == "fading" else rule.B0]
    for k in range(len(errors)):
        Bs.append(next_B(Bs[-1], errors[: k + 1], rule))
    return Bs


def B_at(repetition: int, errors: Sequence[float], rule: AdaptiveRule) -> float:
    """B of repetition ``repetition`` (1-based) given the errors of repetitions
    1 .. repetition − 1 (fading: only their number matters; they may be NaN)."""
    if len(errors) != repetition - 1:
        raise ValueError(f"repetition {repetition} needs the {repetition - 1} errors before "
                         f"it, got {len(errors)}")  # fmt: skip
    return B_schedule(errors, rule)[-1]


def build_adaptive(path, *, B: float | None = None, transition: float = DEFAULT_TRANSITION,
                   **params) -> ViscousGuidance:  # fmt: skip
    """The fixture of an adaptive entry for one repetition: the seed's viscous law along
    ``path`` with the current ``B`` (None: B0) and the rule's G_max (the rule's parameters
    are checked here)."""
    unknown = set(params) - set(DEFAULTS)
    if unknown:
        raise TypeError(f"unknown adaptive parameters {sorted(unknown)}")
    rule = AdaptiveRule.of(params)
    current = rule.B0 if B is None else B
    return ViscousGuidance(path, current, rule.G_max, transition)


def describe_adaptive(p: Mapping[str, Any]) -> str:
    """An adaptive entry in one line (its rule, and the B that runs when it is set)."""
    rule = AdaptiveRule.of(p)
    now = f", now B={p['B']:g} N·s/m" if isinstance(p.get("B"), int | float) else ""
    if rule.mode == "fading":
        how = f"fading from B0={rule.B0:g} N·s/m to 0 at repetition {rule.zero_at}"
    else:
        how = (
            f"assist-as-needed on {rule.metric} (target {rule.target:g}, gain {rule.gain:g}, "
            f"step ≤ {rule.max_step:g}, B in [{rule.B_min:g}, {rule.B_max:g}] N·s/m, "
            f"last {rule.window} repetitions, B0={rule.B0:g})"
        )
    return f"adaptive viscous guidance, {how}, G_max={rule.G_max:g} N{now}"
