"""Adaptive conditions in a study: each trial's B from the subject's earlier trials.

An adaptive condition (fixture entry ``type: adaptive``,
:mod:`davinci_sim.haptics.adaptive`) cannot give every trial its B up front: with
assist-as-needed, a subject's repetition r in the condition runs with the B that the
update rule gives after repetitions 1 .. r − 1 of that subject in that condition. The
runner (:func:`~davinci_sim.study.runner.run_study`) therefore runs the plan in *rounds*:

* round 1: every trial that needs no earlier row — all trials of non-adaptive conditions,
  all trials of fading conditions (their B depends on the repetition number only), and the
  first repetition of each subject's assist-as-needed block;
* round r: each subject's r-th repetition of the assist-as-needed conditions, its B
  computed (:func:`resolve`) from that subject's rows of the earlier rounds with the same
  pure rule the live session applies (:func:`~davinci_sim.haptics.adaptive.B_at`), the
  trial's entry then carrying the resolved ``B`` (so the row's ``B`` and ``fixture``
  columns say which B ran).

The batch engine's laws are untouched: a round is a list of ordinary
:class:`~davinci_sim.study.trial.TrialSpec` whose adaptive entries are the seed's viscous law
with a given B. A trial's result depends only on its spec, so a study without adaptive
conditions runs in one round, as before, with the same rows; rows stay keyed by plan index
(resume, :mod:`davinci_sim.study.store`, keeps working: kept rows are history too).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence

from davinci_sim.haptics.adaptive import AdaptiveRule, B_at
from davinci_sim.haptics.kinds import fixture_params
from davinci_sim.study.trial import TrialSpec


def rule_of(spec: TrialSpec) -> AdaptiveRule | None:
    """The update rule of ``spec``'s condition (None: not adaptive)."""
    if spec.fixture["type"] != "adaptive":
        return None
    return AdaptiveRule.of(fixture_params(spec.fixture))


def histories(specs: Sequence[TrialSpec]) -> list[list[int]]:
    """For each trial, the plan indices of its subject's trials in the same condition with
    a smaller repetition number, in repetition order."""
    by_block: dict[tuple[int, int], list[int]] = {}
    for j, s in enumerate(specs):
        by_block.setdefault((s.subject, s.condition), []).append(j)
    out: list[list[int]] = [[] for _ in specs]
    for members in by_block.values():
        members.sort(key=lambda j: specs[j].repetition)
        for j in members:
            out[j] = [k for k in members if specs[k].repetition < specs[j].repetition]
    return out


def ready(spec: TrialSpec, history: Sequence[int], rows: Sequence[dict | None]) -> bool:
    """Whether ``spec`` can run now: it needs no history, or the rows of its subject's
    earlier repetitions in the condition (plan indices ``history``) are all in."""
    rule = rule_of(spec)
    if rule is None or not rule.uses_history:
        return True
    return all(rows[j] is not None for j in history)


def resolve(spec: TrialSpec, history: Sequence[int], rows: Sequence[dict | None]) -> TrialSpec:
    """``spec`` as it runs: an adaptive trial gets the B of its repetition (from the errors
    in the rows of its subject's earlier repetitions in the condition, plan indices
    ``history``); any other is unchanged."""
    rule = rule_of(spec)
    if rule is None:
        return spec
    if rule.uses_history:
        errors = [_error(rows[j], rule.metric) for j in history]
    else:
        errors = [math.nan] * (spec.repetition - 1)
    if len(errors) != spec.repetition - 1:
        raise ValueError(
            f"subject {spec.subject}'s repetition {spec.repetition} of condition "
            f"{spec.condition} has {len(errors)} earlier repetitions, not {spec.repetition - 1}"
        )
    B = B_at(spec.repetition, errors, rule)
    return dataclasses.replace(spec, fixture={**spec.fixture, "B": B}, B=None, G_max=None)


def rounds(specs: Sequence[TrialSpec]) -> list[int]:
    """The round (0-based) in which :func:`~davinci_sim.study.runner.run_study` runs each
    trial of ``specs`` (the trials still to run): 0 for one that needs no history, else the
    number of its subject's earlier repetitions of the condition among ``specs``."""
    out = []
    for s, h in zip(specs, histories(specs), strict=True):
        rule = rule_of(s)
        out.append(len(h) if rule is not None and rule.uses_history else 0)
    return out


def fixture_keys(specs: Sequence[TrialSpec]) -> list[int]:
    """The key of each trial's fixture in a batch (:class:`~davinci_sim.study.batch.TrialBatch`):
    its condition's index, one fixture per condition; an adaptive condition's trials may run
    with different B, so one key per (condition, B) for them, and a retention trial's
    fixture-off entry one of its own, negative (-1, -2, ...) so as not to meet a condition's.

    Raises:
        ValueError: two trials of a non-adaptive condition with different entries.
    """
    firsts: dict[int, dict] = {}
    negative: dict[tuple, int] = {}
    keys = []
    for s in specs:
        if getattr(s, "block", "practice") != "practice":  # a retention trial: fixture off
            entry = ("off", json.dumps(s.fixture, sort_keys=True))
            keys.append(negative.setdefault(entry, -1 - len(negative)))
            continue
        first = firsts.setdefault(s.condition, s.fixture)
        if s.fixture["type"] == "adaptive":
            keys.append(negative.setdefault((s.condition, s.B), -1 - len(negative)))
        elif s.fixture != first:
            raise ValueError(
                f"condition {s.condition} has two fixture entries in one batch: "
                f"{s.fixture!r} and {first!r}"
            )
        else:
            keys.append(s.condition)
    return keys


def _error(row: dict, metric: str) -> float:
    if metric not in row:
        raise ValueError(f"an adaptive condition's error metric {metric!r} is not a column "
                         f"of the study's rows; columns: {sorted(row)}")  # fmt: skip
    value = row[metric]
    return math.nan if value is None else float(value)
