"""Kinds of guidance fixture: what a fixture entry of a task file (``{"type": ..., params}``)
builds along a path, and how the law that ran is described.

A *kind* turns a task's fixture entry into a :class:`~davinci_sim.haptics.fixture.Fixture`
along the task's path: ``build(path, **params)``, a fixture whose ``force(position,
velocity)`` takes and returns ``(..., 3)`` arrays, one row per tool tip. The live haptic
loop (:class:`~davinci_sim.haptics.fixture.FixtureField`) calls it with one row; the study's
batch engine with one row per trial of the condition. Kinds offered:

* ``viscous`` — the seed's law (:class:`~davinci_sim.haptics.viscous.ViscousGuidance`): B,
  G_max, transition. ``transition`` defaults to 0, the law as printed; a positive value is
  the width of an on-path ramp (m), an explicit option that the study reports.
* ``spring`` — :class:`~davinci_sim.haptics.spring.SpringGuidance`.
* ``viscous_elastic`` — Rota's dVRK-console study's fixture
  (:class:`~davinci_sim.haptics.viscous_elastic.ViscousElasticGuidance`): the seed's viscous
  law uncapped plus a logistic elastic pull, the sum capped (``max_force``, 3 N) and scaled
  by ``assistance``.
* ``adaptive`` — the seed's viscous law with a B that follows the trainee between
  repetitions (``mode: assist_as_needed`` or ``fading``, :mod:`davinci_sim.haptics.adaptive`);
  the entry's ``B`` is the B of the repetition that runs (absent: B0).
* ``none`` — no guidance.
* any name registered with :func:`register_fixture_kind` (e.g. by a module the user imports
  before loading the task);
* ``"package.module:Name"`` — an importable class or function called as
  ``Name(path, **params)``: a user's own law without registering it (a study's worker
  processes import it by name).

A kind may describe itself (``describe(params) -> str``; for a ``module:Name`` kind, an
optional ``describe`` attribute of ``Name``): the study's report and CSV rows say which law
ran with it.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from davinci_sim.haptics import adaptive
from davinci_sim.haptics.fixture import Fixture
from davinci_sim.haptics.spring import SpringGuidance
from davinci_sim.haptics.viscous import ViscousGuidance
from davinci_sim.haptics.viscous_elastic import ViscousElasticGuidance, describe_viscous_elastic


@dataclass(frozen=True)
class FixtureKind:
    """A kind of guidance fixture (see the module docstring)."""

    name: str
    build: Callable[..., Fixture | None]
    """``build(path, **params)``: the fixture along ``path`` (None: no force)."""
    params: frozenset[str] | None = None
    """The parameter names it takes (None: whatever ``build`` accepts)."""
    defaults: Mapping[str, Any] = field(default_factory=dict)
    """Values of parameters an entry leaves out (filled in by :func:`resolve_fixture`)."""
    describe: Callable[[Mapping[str, Any]], str] | None = None
    """``describe(params) -> str``: the law in one line (params with defaults filled)."""

    def description(self, params: Mapping[str, Any]) -> str:
        if self.describe is not None:
            return str(self.describe(params))
        text = ", ".join(f"{k}={_fmt(v)}" for k, v in params.items())
        return f"{self.name}({text})"


_KINDS: dict[str, FixtureKind] = {}
#: The keys of a fixture entry that are not parameters of its law.
ENTRY_KEYS = ("type", "name")


def register_fixture_kind(
    name: str,
    build: Callable[..., Fixture | None],
    *,
    params=None,
    defaults: Mapping[str, Any] | None = None,
    describe: Callable[[Mapping[str, Any]], str] | None = None,
) -> FixtureKind:
    """Offer ``type: name`` in task files' fixture entries (see the module docstring).

    A study runs its trials in worker processes forked from the caller's: register the kind
    at import time of a module the caller imports (or name it ``module:Name`` instead).
    Re-registering a name replaces it."""
    if not isinstance(name, str) or not name or ":" in name:
        raise ValueError(f"a fixture kind needs a name without ':', got {name!r}")
    if not callable(build):
        raise TypeError(f"build must be callable, got {build!r}")
    kind = FixtureKind(
        name,
        build,
        None if params is None else frozenset(params),
        dict(defaults or {}),
        describe,
    )
    _KINDS[name] = kind
    return kind


def fixture_kinds() -> dict[str, FixtureKind]:
    """The registered kinds, by name."""
    return dict(_KINDS)


def fixture_kind(type_name: str) -> FixtureKind:
    """The kind of ``type_name``: a registered name or an importable ``module:Name``.

    Raises:
        KeyError: neither (the message lists the registered names).
    """
    if type_name in _KINDS:
        return _KINDS[type_name]
    if isinstance(type_name, str) and ":" in type_name:
        module, _, attr = type_name.partition(":")
        try:
            target = getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError, ValueError) as e:
            raise KeyError(f"cannot import fixture {type_name!r}: {e}") from e
        if not callable(target):
            raise KeyError(f"fixture {type_name!r} is not a class or function")
        return FixtureKind(type_name, target, describe=getattr(target, "describe", None))
    raise KeyError(f"unknown fixture type {type_name!r}; types: {sorted(_KINDS)} or 'module:Name'")


def fixture_params(spec: Mapping[str, Any]) -> dict[str, Any]:
    """The law's parameters of a fixture entry, with the kind's defaults filled in (numbers
    as floats)."""
    kind = fixture_kind(spec.get("type", "none"))
    params = dict(kind.defaults)
    for k, v in spec.items():
        if k not in ENTRY_KEYS:
            is_number = isinstance(v, int | float) and not isinstance(v, bool)
            params[k] = float(v) if is_number else v
    return params


def resolve_fixture(spec: Mapping[str, Any]) -> dict[str, Any]:
    """The entry as it runs: ``type``, ``name`` if any, and every parameter (defaults
    filled in): what a study records for each trial."""
    out = {"type": spec.get("type", "none")}
    if "name" in spec:
        out["name"] = spec["name"]
    out.update(fixture_params(spec))
    return out


def build_fixture(spec: Mapping[str, Any], path) -> Fixture | None:
    """The guidance of a fixture entry along ``path`` (None: no force)."""
    kind = fixture_kind(spec.get("type", "none"))
    params = fixture_params(spec)
    if kind.params is not None:
        unknown = set(params) - kind.params
        if unknown:
            raise ValueError(
                f"unknown keys {sorted(unknown)} for a {kind.name} fixture; "
                f"keys: {sorted(kind.params | set(ENTRY_KEYS))}"
            )
    fixture = kind.build(path, **params)
    if fixture is not None and not callable(getattr(fixture, "force", None)):
        raise TypeError(f"fixture type {kind.name!r} built {fixture!r}, which has no force()")
    return fixture


def describe_fixture(spec: Mapping[str, Any]) -> str:
    """The law of a fixture entry in one line (e.g. ``viscous guidance (the seed's law as
    printed, no on-path ramp), B=40 N·s/m, G_max=5 N``)."""
    kind = fixture_kind(spec.get("type", "none"))
    return kind.description(fixture_params(spec))


def _fmt(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def viscous_law(transition: float) -> str:
    """Which variant of the seed's law a viscous fixture with this ``transition`` (m) is."""
    if transition == 0:
        return "the seed's law as printed (no on-path ramp)"
    return f"with a {transition * 1e3:g} mm on-path ramp"


def _describe_viscous(p: Mapping[str, Any]) -> str:
    B, G = p.get("B", math.nan), p.get("G_max", math.nan)
    if B == 0 or G == 0:
        return f"no guidance (viscous B={_fmt(B)} N·s/m, G_max={_fmt(G)} N: no force)"
    return (
        f"viscous guidance, {viscous_law(p.get('transition', 0.0))}: "
        f"B={_fmt(B)} N·s/m, G_max={_fmt(G)} N"
    )


def _describe_spring(p: Mapping[str, Any]) -> str:
    return (
        f"spring guidance: stiffness={_fmt(p.get('stiffness'))} N/m, "
        f"damping={_fmt(p.get('damping'))} N·s/m, max_force={_fmt(p.get('max_force'))} N, "
        f"{_fmt(p.get('transition', 0.0) * 1e3)} mm damping ramp"
    )


register_fixture_kind(
    "viscous",
    ViscousGuidance,
    params={"B", "G_max", "transition"},
    defaults={"transition": 0.0},
    describe=_describe_viscous,
)
register_fixture_kind(
    "spring",
    SpringGuidance,
    params={"stiffness", "damping", "max_force", "transition"},
    defaults={"damping": 0.0, "max_force": 5.0, "transition": 0.0005},
    describe=_describe_spring,
)
register_fixture_kind(
    "viscous_elastic",
    ViscousElasticGuidance,
    params={"B", "elastic_gain", "threshold", "half", "slope", "max_force", "assistance"},
    defaults={"max_force": 3.0, "assistance": 1.0},
    describe=describe_viscous_elastic,
)
register_fixture_kind("none", lambda path: None, params=set(), describe=lambda p: "no guidance")
register_fixture_kind(
    "adaptive",
    adaptive.build_adaptive,
    params=adaptive.PARAMS,
    defaults=adaptive.DEFAULTS,
    describe=adaptive.describe_adaptive,
)
