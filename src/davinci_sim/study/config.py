"""The configuration of a study and its plan of trials.

Condition order: each subject does every condition in one block of ``n_repetitions``
repetitions, the blocks in a counterbalanced order. ``order="latin"`` (default) gives
subject s row s mod C of a Williams design (C conditions): a Latin square where, for an even
C, each condition follows each other equally often (first-order carry-over balanced); for an
odd C it is a cyclic Latin square. ``order="fixed"`` runs the conditions as listed (the
seed does not say in which order its subjects did them).

Conditions: each is a fixture entry of the task (``{"type": ..., params, "name": ...}``, any
kind of :mod:`davinci_sim.haptics.kinds`: the seed's viscous law, spring, a registered or
``module:Name`` law), or a (B, G_max) pair, the seed's viscous law as printed. By default
they are the task file's ``conditions`` (Table I for ``seed_path``), or Table I when the
task has none. A viscous condition runs the seed's law as printed (no on-path ramp) unless
its entry sets ``transition`` or the study sets one for all (:attr:`StudyConfig.transition`);
every trial's row says which law ran.

Practice carries across conditions: the practice count j of the trainee's power law of
practice (:class:`~davinci_sim.operators.SubjectParams`) counts all the subject's trials so
far, j = prior_practice + (block − 1)·n_repetitions + repetition, so a later block is done by
a more practised trainee; the counterbalancing spreads this over the conditions.
``prior_practice`` (default 0) is the trials a subject practised before the study: Enayati
et al.'s subjects trained for 23 min before their first recorded trial.

Retention (``retention`` = N > 0): right after each condition's practice block, N
repetitions of the same task with the fixture off (rows with ``block`` = ``retention`` and
the practised condition's index and name; their fixture is ``none``). The practice count
continues through them. In the within-subject design this measures the *carry-over* of
each condition's practice into unassisted performance, on top of all the practice before
it (every subject practises every condition, in a counterbalanced order); the between-
subject design (``design="between"``: subject s practises only condition s mod C, then
its retention block) is the design of the guidance-hypothesis literature, each subject's
retention measuring one condition's training.

Rota's protocol (``design="rota"``, training.md §4): two groups over days, the first
condition the control group's, the others the assisted group's days in order (``rota_path``:
control, then the guidance at 1.0, 0.75, 0.5, 0.25 of its force). Subject s is in the
control group if s is even, else in the assisted group; each does ``n_repetitions`` trials
a day for C − 1 days (block = day), its practice count running on through the days.

Mechanisms (``mechanisms``): the trainee reactions to guidance switched on
(:class:`~davinci_sim.operators.params.Mechanisms`): ``reliance`` (a guided trial counts
less for the trainee's own correction: each trial's ``own_practice``) and ``stiffening``
(co-contraction under strong guidance).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from davinci_sim.study.trial import TrialSpec

#: The seed's Table I: (B in N·s/m, G_max in N).
TABLE_I: tuple[tuple[float, float], ...] = ((0.0, 0.0), (20.0, 2.0), (40.0, 5.0), (60.0, 8.0))
ORDERS = ("latin", "fixed")
DESIGNS = ("within", "between", "rota")
BACKENDS = ("local", "ray")
ENGINES = ("batch", "live")


class StudyError(ValueError):
    """A study configuration that cannot be run; the message says what to fix."""


@dataclass(frozen=True)
class StudyConfig:
    """A simulated user study (see the module docstring)."""

    conditions: tuple | None = None
    """The conditions: fixture entries (mappings) or (B, G_max) pairs (N·s/m, N); None: the
    task's own conditions, else Table I. Stored as the entries that run (every parameter,
    a unique ``name`` each: :func:`resolve_conditions`)."""
    n_subjects: int = 10
    n_repetitions: int = 10
    task: str = "seed_path"
    """Task name or task file (:func:`davinci_sim.tasks.load_task`)."""
    seed: int = 0
    order: str = "latin"
    """Condition order policy: ``latin`` or ``fixed``."""
    workers: int = 2
    """Worker processes (local backend) or concurrent tasks (ray)."""
    backend: str = "local"
    """``local`` (a process pool) or ``ray``."""
    timeout: float = 60.0
    """Simulated time a trial may take before it is reported as unfinished, s."""
    engine: str = "batch"
    """``batch`` (trials stepped together, :mod:`davinci_sim.study.batch`) or ``live`` (one
    live simulation per trial: the slow reference the batch is checked against)."""
    transition: float | None = None
    """Width of the on-path ramp of the viscous conditions that do not set their own, m
    (None or 0: the seed's law as printed)."""

    retention: int = 0
    """Repetitions with the fixture off after each condition's practice block (0: none)."""
    design: str = "within"
    """``within`` (every subject does every condition), ``between`` (subject s does
    condition s mod C only) or ``rota`` (two groups over C − 1 days; module docstring)."""
    mechanisms: tuple[str, ...] = ()
    """Trainee mechanisms on (:data:`~davinci_sim.operators.params.MECHANISMS`)."""
    prior_practice: int = 0
    """Trials of practice each subject had before the study's first trial (its practice count
    j starts there)."""
    population: str = "trainee"
    """The synthetic trainees' population (:data:`~davinci_sim.operators.params.POPULATIONS`:
    the module table's ``trainee``, or a fitted profile)."""

    def __post_init__(self) -> None:
        from davinci_sim.operators.params import MECHANISMS, POPULATIONS

        if self.population not in POPULATIONS:
            raise StudyError(
                f"unknown population {self.population!r}; populations: {list(POPULATIONS)}"
            )

        for name in ("retention", "prior_practice"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 0:
                raise StudyError(f"{name} must be an integer >= 0, got {value!r}")
        if self.design not in DESIGNS:
            raise StudyError(f"unknown design {self.design!r}; designs: {DESIGNS}")
        mechanisms = (self.mechanisms,) if isinstance(self.mechanisms, str) else self.mechanisms
        mechanisms = tuple(dict.fromkeys(mechanisms))
        unknown = [m for m in mechanisms if m not in MECHANISMS]
        if unknown:
            raise StudyError(f"unknown mechanisms {unknown}; mechanisms: {list(MECHANISMS)}")
        object.__setattr__(self, "mechanisms", tuple(m for m in MECHANISMS if m in mechanisms))
        if self.n_subjects < 1 or self.n_repetitions < 1:
            raise StudyError("n_subjects and n_repetitions must be >= 1")
        if self.order not in ORDERS:
            raise StudyError(f"unknown order {self.order!r}; orders: {ORDERS}")
        if self.backend not in BACKENDS:
            raise StudyError(f"unknown backend {self.backend!r}; backends: {BACKENDS}")
        if self.engine not in ENGINES:
            raise StudyError(f"unknown engine {self.engine!r}; engines: {ENGINES}")
        if self.workers < 1:
            raise StudyError(f"workers must be >= 1, got {self.workers!r}")
        if not self.timeout > 0:
            raise StudyError(f"timeout must be > 0, got {self.timeout!r}")
        t = self.transition
        if t is not None and not (isinstance(t, int | float) and math.isfinite(t) and t >= 0):
            raise StudyError(f"transition must be a number >= 0 (m), got {t!r}")
        conditions = resolve_conditions(self.conditions, self.task, transition=t)
        object.__setattr__(self, "conditions", conditions)
        self._check_kind()
        if self.design == "rota" and (len(conditions) < 2 or self.retention):
            raise StudyError(
                "the rota design needs two or more conditions (the control group's, then the "
                "assisted group's days) and no retention blocks"
            )

    def _check_kind(self) -> None:
        """Refuse what the task's kind cannot run: the path trainees step on both engines;
        the needle exercises' trainees (:mod:`davinci_sim.study.console_trial`) on the live
        one, without the path trainees' mechanisms or the rota design."""
        from davinci_sim.study.console_trial import CONSOLE_KINDS

        kind = study_task(self.task).kind
        if kind == "path":
            return
        if kind not in CONSOLE_KINDS:
            raise StudyError(f"task {self.task!r} is a {kind} exercise; the study's synthetic "
                             f"trainees do path tasks and {', '.join(CONSOLE_KINDS)}")  # fmt: skip
        if self.engine != "live":
            raise StudyError(f"a {kind} study runs on the live engine (engine 'live'): the "
                             "batch engine steps the path trainees")  # fmt: skip
        if self.mechanisms or self.design == "rota":
            raise StudyError(f"a {kind} study has no trainee mechanisms and no rota design "
                             "(the path trainees' and Rota's path protocol)")  # fmt: skip

    @property
    def kind(self) -> str:
        """The kind of the study's task (``path``, ``needle_drive``, ...)."""
        return study_task(self.task).kind

    @property
    def days(self) -> int:
        """Blocks of a subject's trials: the rota design's days (C − 1), else 1 (between)
        or C (within)."""
        C = len(self.conditions)
        return {"between": 1, "rota": C - 1}.get(self.design, C)

    @property
    def n_trials(self) -> int:
        per_block = self.n_repetitions + self.retention
        return self.n_subjects * self.days * per_block


def study_task(task: str):
    """The task of a study (a name or a file), or StudyError."""
    from davinci_sim.tasks import TaskError, load_task

    try:
        return load_task(task if not Path(task).suffix else Path(task))
    except (TaskError, ValueError, OSError) as e:
        raise StudyError(str(e)) from e


def resolve_conditions(conditions, task, *, transition: float | None = None) -> tuple[dict, ...]:
    """The fixture entries a study runs (see :class:`StudyConfig`): (B, G_max) pairs become
    viscous entries, viscous entries without ``transition`` get ``transition`` (None: 0, the
    law as printed), every entry gets its parameters' defaults and a unique name, and each
    is checked against the task (``task``: a name or file, or a loaded task).

    Raises:
        StudyError: no conditions, a bad pair or entry, or one the task does not offer.
    """
    from davinci_sim.haptics.kinds import resolve_fixture
    from davinci_sim.tasks import TaskError

    loaded = study_task(task) if isinstance(task, str) else task
    if conditions is None:
        conditions = getattr(loaded, "conditions", ()) or TABLE_I
    conditions = tuple(conditions)
    if not conditions:
        raise StudyError("a study needs at least one condition")
    pairs = [c for c in conditions if not isinstance(c, Mapping)]
    for pair in pairs:
        try:
            b, g = (float(x) for x in pair)
        except (TypeError, ValueError) as e:
            raise StudyError(
                f"a condition is a fixture entry or a (B, G_max) pair, got {pair!r}"
            ) from e
        if not (math.isfinite(b) and math.isfinite(g)):
            raise StudyError(f"B and G_max must be finite numbers, got {pair!r}")
        if b < 0 or g < 0:
            raise StudyError(f"B and G_max must be >= 0, got {pair!r}")
    labels = iter(pair_labels([tuple(float(x) for x in p) for p in pairs]))
    out = []
    for c in conditions:
        if isinstance(c, Mapping):
            entry = dict(c)
        else:
            b, g = (float(x) for x in c)
            entry = {"name": next(labels), "type": "viscous", "B": b, "G_max": g}
        if entry.get("type") == "viscous" and "transition" not in entry:
            entry["transition"] = float(transition or 0.0)
        try:
            loaded.check_fixture(entry)
            entry = resolve_fixture(entry)
        except (TaskError, KeyError, ValueError, TypeError) as e:
            raise StudyError(f"condition {c!r}: {e.args[0] if e.args else e}") from e
        out.append(entry)
    names = [e.get("name") or _entry_label(e) for e in out]
    for i, e in enumerate(out):
        e["name"] = names[i] if names.count(names[i]) == 1 else f"{names[i]} #{i + 1}"
    return tuple(out)


def pair_labels(pairs) -> list[str]:
    """Labels of (B, G_max) conditions: ``B=40`` while B tells them apart, ``B=40/Gmax=5``
    when two share a B (they would read the same)."""
    bs = [b for b, _ in pairs]
    if len(set(bs)) == len(bs):
        return [f"B={b:g}" for b in bs]
    return [f"B={b:g}/Gmax={g:g}" for b, g in pairs]


def _entry_label(entry: Mapping) -> str:
    params = ", ".join(
        f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
        for k, v in entry.items()
        if k not in ("type", "name")
    )
    kind = entry.get("type", "none")
    return f"{kind}({params})" if params else kind


def parse_conditions(text: str, task=None) -> tuple:
    """``"0:0,20:2,40:5,60:8"`` → ((0, 0), (20, 2), (40, 5), (60, 8)); with ``task`` (a
    loaded task), an item may also be the name of one of its conditions (its entry).

    Raises:
        StudyError: an item that is neither (the message lists the task's names).
    """
    names = {c["name"]: c for c in getattr(task, "conditions", ())}
    out = []
    for item in text.split(","):
        if item.strip() in names:
            out.append(dict(names[item.strip()]))
            continue
        try:
            b, g = item.split(":")
            out.append((float(b), float(g)))
        except ValueError as e:
            known = f" or a condition of the task: {sorted(names)}" if names else ""
            raise StudyError(
                f"conditions are 'B:G_max' pairs separated by commas{known}, got {text!r}"
            ) from e
    return tuple(out)


def parse_fixture(text: str) -> dict:
    """A fixture entry written as a YAML or JSON mapping, e.g.
    ``'{type: spring, stiffness: 200, name: k200}'`` (StudyError if it is not one)."""
    import yaml

    try:
        entry = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise StudyError(f"a fixture is a YAML mapping, got {text!r}: {e}") from e
    if not isinstance(entry, dict) or "type" not in entry:
        raise StudyError(f"a fixture is a mapping with a 'type', e.g. '{{type: spring, "
                         f"stiffness: 200}}', got {text!r}")  # fmt: skip
    return entry


def williams_row(row: int, n: int) -> list[int]:
    """Row ``row`` (mod n) of a Williams design of n treatments (cyclic if n is odd)."""
    if n % 2:
        return [(row + k) % n for k in range(n)]
    first, lo, hi = [0], 1, n - 1
    while len(first) < n:
        first.append(lo)
        lo += 1
        if len(first) < n:
            first.append(hi)
            hi -= 1
    return [(c + row) % n for c in first]


def condition_order(config: StudyConfig, subject: int) -> list[int]:
    """Indices of the conditions in the order subject ``subject`` does them (one condition,
    s mod C, in the between-subject design; a condition per day in the rota design)."""
    n = len(config.conditions)
    if config.design == "between":
        return [subject % n]
    if config.design == "rota":  # (control: the first condition every day; assisted: the rest)
        return [0] * (n - 1) if subject % 2 == 0 else list(range(1, n))
    return williams_row(subject, n) if config.order == "latin" else list(range(n))


#: The fixture of a retention block: off.
NO_FIXTURE = {"type": "none", "name": "off"}


def plan_trials(config: StudyConfig) -> list[TrialSpec]:
    """Every trial of the study, in the order each subject does them: per condition block,
    its practice repetitions, then its retention repetitions (fixture off). The practice
    count j runs on through all of a subject's trials; with ``reliance`` on, each trial's
    own-correction count is 1 + the sum of the earlier trials' steps
    (:meth:`~davinci_sim.operators.params.Mechanisms.own_practice_step`)."""
    from davinci_sim.operators.params import Mechanisms, guidance_strength

    mechanisms = Mechanisms.named(config.mechanisms)
    reliance = mechanisms.reliance > 0
    specs = []
    for s in range(config.n_subjects):
        j, own = config.prior_practice, 1.0
        for block, c in enumerate(condition_order(config, s), start=1):
            runs = [("practice", config.conditions[c], config.n_repetitions),
                    ("retention", NO_FIXTURE, config.retention)]  # fmt: skip
            for kind, fixture, count in runs:
                step = mechanisms.own_practice_step(guidance_strength(fixture))
                for r in range(1, count + 1):
                    j += 1
                    specs.append(
                        TrialSpec(
                            task=config.task,
                            subject=s,
                            condition=c,
                            fixture=fixture,
                            repetition=r,
                            order=block,
                            practice=j,
                            seed=config.seed,
                            timeout=config.timeout,
                            block=kind,
                            condition_name=config.conditions[c]["name"],
                            own_practice=own if reliance else None,
                            mechanisms=config.mechanisms,
                            population=config.population,
                        )
                    )
                    own += step
    return specs
