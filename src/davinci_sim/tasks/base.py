"""The Task protocol: what every kind of training task provides, and the registry of kinds.

A task is a frozen value loaded from a YAML (or JSON) file. Its ``kind:`` field selects the
class that reads it (:func:`task_from_dict`; no ``kind``: ``path``, the seed's
path-following task, :class:`~davinci_sim.tasks.task.PathTask`). A kind is a subclass of
:class:`Task` declared with its name, ``class ReachTask(Task, kind="reach")``: defining it
registers it, so a new exercise is one new file (imported before its task files are
loaded). A kind provides:

* **file format**: :meth:`Task.from_dict` / :meth:`Task.to_dict` (``name``, ``description``,
  ``frame``, ``teleop``, ``fixture``, ``conditions`` and ``walls`` are common to every kind,
  read by :func:`common_fields`);
* **scene**: :meth:`Task.draw` adds the task's visuals to a ``mujoco.MjSpec``;
* **state machine**: :meth:`Task.initial_state` (a NamedTuple of (n,) arrays with a
  ``phase`` field of :class:`~davinci_sim.tasks.state.Phase` values) and
  :meth:`Task.step`, a pure step of n trials by one :class:`Sample` that also returns the
  task's observations of the sample (``distance``: the tip to what the task is about, m,
  always; others as its metrics need); :meth:`Task.at_start` says where a repetition starts;
* **samples**: one :class:`Sample` record per tick — the same record the live session
  (:mod:`davinci_sim.tasks.session`), the study's live and batched trials and the offline
  runs (:mod:`davinci_sim.operators.offline`) feed to :class:`~davinci_sim.tasks.state.TaskMonitor`;
* **metrics**: ``METRICS``, declared once (:class:`~davinci_sim.tasks.metrics.Metric`);
* **fixtures and conditions**: :meth:`Task.guidance` for each fixture ``type`` the kind
  offers (``FIXTURE_TYPES``), plus the walls every kind has (:meth:`Task.fixture`);
* **teleoperation**: :class:`TeleopSpec` (PSM, MTM, motion scale, start keyframe).

Samples are measured from the tick where a trial is RUNNING to the one where it is
FINISHED, the same for every kind.

Size: one module over 500 lines because the protocol, the one :class:`Sample` record that
every engine fills (its optional fields: the trainer metrics', a kind's objects) and the
registry of kinds and files are what every kind imports together; split, each part would
import the others.
"""

from __future__ import annotations

import json
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import yaml

from davinci_sim.haptics.combine import combine
from davinci_sim.haptics.fixture import Fixture
from davinci_sim.haptics.wall import PlaneWall, SphereWall
from davinci_sim.tasks.metrics import Metric, MetricsAccumulator

if TYPE_CHECKING:
    import mujoco

FRAMES = ("world", "camera")
DEFAULT_KIND = "path"
_WALLS = {"plane": PlaneWall, "sphere": SphereWall}
_KINDS: dict[str, type[Task]] = {}


class TaskError(ValueError):
    """A task file that cannot be used; the message says what to fix."""


@dataclass(frozen=True)
class TeleopSpec:
    """How the task is teleoperated."""

    psm: str = "PSM1"
    mtm: str = "MTMR"
    scale: float = 0.6
    """MTM → PSM translation scale (the seed: 0.6)."""
    keyframe: str = "surgical"
    """Simulation start keyframe (``surgical``: the endoscope sees the instruments)."""


@dataclass(frozen=True, eq=False)
class Sample:
    """What a task samples at one tick, for n trials (struct of arrays)."""

    time: np.ndarray
    """(n,) simulated time, s."""
    tip: np.ndarray
    """(n, 3) tool tip position in the task's frame, m."""
    force: np.ndarray
    """(n, 3) guidance force the haptic loop requests on the hand (HRSV = camera axes), N."""
    clutch: np.ndarray
    """(n,) bool: the clutch pedal is pressed."""
    # Optional (None: not sampled; metrics that need one are then nan, see Metric.needs).
    visible: np.ndarray | None = None
    """(n,) bool: the tool tip projects inside the left endoscope image."""
    master: np.ndarray | None = None
    """(n, 3) the master (MTM handle) position in HRSV, m."""
    contacts: np.ndarray | None = None
    """(n,) int: contacts of the task's instruments with the scene at this tick (each one's
    own arm's and the task's objects' left out,
    :class:`~davinci_sim.tasks.trainer.InstrumentContacts`)."""
    tool_force: np.ndarray | None = None
    """(n,) total normal force of those contacts on the instrument, N."""
    objects: np.ndarray | None = None
    """(n, k, 3) centres of the task's k graspable objects, task frame, m (a kind with
    objects fills it: :meth:`Task.scene_fields`)."""
    grasp: np.ndarray | None = None
    """(n, k) int: bit mask of the jaws touching each object (bit 2·a + j: jaw j of the
    task's instrument a)."""
    T_task_camera: np.ndarray | None = None
    """(n, 4, 4) the endoscope's camera (ECM tip) frame in the task's frame, m (the camera
    targeting exercise's input)."""
    R_task_tip: np.ndarray | None = None
    """(n, 3, 3) the tool tip frame's orientation in the task's frame (column 2, z: the
    direction the jaws point; the needle targeting exercise's input)."""
    tools: np.ndarray | None = None
    """(n, A, 3) tool tips of every instrument the task uses, task frame, m (a kind with
    several instruments fills it, :meth:`Task.scene_fields`: peg transfer's economy of
    motion sums their paths)."""
    T_task_object: np.ndarray | None = None
    """(n, 4, 4) the frame of the task's first object in the task's frame, m (the needle:
    its passage through the tissue is read from its pose)."""
    tissue_force: np.ndarray | None = None
    """(n,) total normal force of the instruments on the deformable tissue, N."""

    @classmethod
    def of(
        cls, time, tip, force=None, clutch=None, *, visible=None, master=None, contacts=None,
        tool_force=None, objects=None, grasp=None, T_task_camera=None, R_task_tip=None,
        tools=None, T_task_object=None, tissue_force=None,
    ) -> Sample:  # fmt: skip
        """A sample of n trials: ``tip`` (n, 3) or (3,) for one; ``time`` scalar or (n,);
        ``force`` (n, 3) (None: 0); ``clutch`` (n,) or scalar (None: released); the
        optional fields (n,) or scalar, ``master`` (n, 3) or (3,), ``T_task_camera``
        (n, 4, 4) or (4, 4), ``R_task_tip`` (n, 3, 3) or (3, 3), ``tools`` (n, A, 3) or
        (A, 3), ``T_task_object`` (n, 4, 4) or (4, 4) (None: not sampled)."""
        p = np.asarray(tip, dtype=float).reshape(-1, 3)
        n = len(p)
        f = np.zeros((n, 3)) if force is None else np.asarray(force, dtype=float).reshape(n, 3)
        # np.full rather than broadcast_to: this runs every tick of every engine.
        t = np.asarray(time, dtype=float)
        t = np.full(n, float(t)) if t.ndim == 0 else t.reshape(n)
        if clutch is None:
            c = np.zeros(n, dtype=bool)
        else:
            c = np.asarray(clutch, dtype=bool)
            c = np.full(n, bool(c)) if c.ndim == 0 else c.reshape(n)
        optional = (visible, master, contacts, tool_force, objects, grasp, T_task_camera,
                    R_task_tip, tools, T_task_object, tissue_force)  # fmt: skip
        if all(o is None for o in optional):
            return cls(t, p, f, c)
        x = None if master is None else np.asarray(master, dtype=float).reshape(n, 3)
        v, k, g = _rows(visible, n, bool), _rows(contacts, n, np.int64), _rows(tool_force, n, float)
        o = None if objects is None else np.asarray(objects, dtype=float).reshape(n, -1, 3)
        j = None if grasp is None else np.asarray(grasp, dtype=np.int64).reshape(n, -1)
        cam = None if T_task_camera is None else _matrices(T_task_camera, n, 4)
        rot = None if R_task_tip is None else _matrices(R_task_tip, n, 3)
        a = None if tools is None else np.asarray(tools, dtype=float).reshape(n, -1, 3)
        obj = None if T_task_object is None else _matrices(T_task_object, n, 4)
        return cls(t, p, f, c, visible=v, master=x, contacts=k, tool_force=g, objects=o,
                   grasp=j, T_task_camera=cam, R_task_tip=rot, tools=a, T_task_object=obj,
                   tissue_force=_rows(tissue_force, n, float))  # fmt: skip

    @cached_property
    def force_magnitude(self) -> np.ndarray:
        """(n,) ‖force‖, N (computed once per sample, for the metrics)."""
        return np.linalg.norm(self.force, axis=-1)

    @property
    def n(self) -> int:
        return len(self.tip)

    def take(self, rows) -> Sample:
        """The trials ``rows`` (indices)."""
        return Sample(*(None if (a := getattr(self, k)) is None else a[rows] for k in _FIELDS))

    def kept(self, other: Sample) -> Sample:
        """:meth:`where` with a mask false everywhere: this sample's rows (the same arrays
        where ``other``'s field has the same type and shape, as ``np.where`` would give
        them), an optional field None unless both have it; this sample itself when that is
        every field of it (samples are values: nothing changes their arrays)."""
        out, same = [], True
        for k in _FIELDS:
            a, b = getattr(self, k), getattr(other, k)
            if a is None or b is None:
                out.append(None)
                same = same and a is None
            elif a.dtype == b.dtype and a.shape == b.shape:
                out.append(a)
            else:
                m = np.zeros(len(a), dtype=bool).reshape(-1, *([1] * (a.ndim - 1)))
                out.append(np.where(m, b, a))
                same = False
        return self if same else Sample(*out)

    def where(self, mask, other: Sample) -> Sample:
        """``other``'s rows where ``mask`` (n,) is true, this sample's elsewhere (an optional
        field is None unless both have it)."""
        m = np.asarray(mask, dtype=bool)
        if m.all():  # every row taken (a running trial, every tick): copies, no np.where
            # (copies: a caller may refill its sample's arrays, e.g. a period's record)
            kept = other.kept(self)
            return Sample(*(None if (a := getattr(kept, k)) is None else a.copy() for k in _FIELDS))
        out = []
        for k in _FIELDS:
            a, b = getattr(self, k), getattr(other, k)
            ok = a is not None and b is not None
            out.append(np.where(m.reshape(-1, *([1] * (a.ndim - 1))), b, a) if ok else None)
        return Sample(*out)


_FIELDS = ("time", "tip", "force", "clutch", "visible", "master", "contacts", "tool_force",
           "objects", "grasp", "T_task_camera", "R_task_tip", "tools", "T_task_object",
           "tissue_force")  # fmt: skip


def _rows_where(mask: np.ndarray, a, b):
    """Rows of ``a`` where ``mask`` (n,), of ``b`` elsewhere: (n, ...) arrays, or tuples of
    them (a state's fields, a field itself a NamedTuple of arrays)."""
    if isinstance(b, tuple):
        return type(b)(*(_rows_where(mask, x, y) for x, y in zip(a, b, strict=True)))
    return np.where(mask.reshape(-1, *([1] * (a.ndim - 1))), a, b)


def _matrices(value, n: int, k: int) -> np.ndarray:
    """(k, k) or (n, k, k) matrices as (n, k, k) floats."""
    a = np.asarray(value, dtype=float)
    return np.broadcast_to(a, (n, k, k)).copy() if a.ndim == 2 else a.reshape(n, k, k)


def _rows(value, n: int, dtype):
    """An optional per-trial field as (n,) of ``dtype`` (None stays None)."""
    if value is None:
        return None
    a = np.asarray(value, dtype=dtype)
    return np.full(n, a, dtype=dtype) if a.ndim == 0 else a.reshape(n)


class Task(ABC):
    """A kind of training task (see the module docstring). Subclasses are frozen
    dataclasses with at least the fields (or properties) ``name``, ``description``,
    ``frame``, ``teleop``, ``fixture_spec``, ``conditions``, ``walls`` and ``start``."""

    kind: ClassVar[str]
    METRICS: ClassVar[tuple[Metric, ...]]
    """The kind's metrics, in the order of the rows' columns."""
    FIXTURE_TYPES: ClassVar[dict[str, set[str]]] = {"none": set()}
    """Fixture ``type`` → its parameters (see :meth:`guidance`)."""
    SCORING: ClassVar[dict] = {}
    """Scored metrics, weights, thresholds: a file's ``scoring:`` (:mod:`~.scoring`)."""
    CONTACT_IGNORE: ClassVar[tuple[str, ...]] = ()
    """Body-name prefixes whose contacts with the instrument are not collisions."""
    DISTANCE_LABEL: ClassVar[str | None] = "deviation"
    """What the console's page calls :meth:`distance` (None: it shows none, the distance
    meaning nothing to a trainee)."""

    name: str
    description: str
    frame: str
    """``world`` (cart) or ``camera`` (ECM tip): the frame of the task's geometry."""
    teleop: TeleopSpec
    fixture_spec: dict
    """The fixture when no condition is chosen."""
    conditions: tuple[dict, ...]
    """Named fixture entries for studies and sessions."""
    walls: tuple[dict, ...]
    start: np.ndarray
    """(3,) where a repetition starts, task frame, m (the study's set-up and a session's
    next repetition bring the tool there)."""

    def __init_subclass__(cls, kind: str | None = None, **kw: Any) -> None:
        super().__init_subclass__(**kw)
        if kind is None:
            return
        if kind in _KINDS and _KINDS[kind].__qualname__ != cls.__qualname__:
            raise ValueError(f"task kind {kind!r} is already {_KINDS[kind].__qualname__}")
        cls.kind = kind
        _KINDS[kind] = cls

    # ------------------------------------------------------------ file format
    @classmethod
    @abstractmethod
    def from_dict(cls, data: dict[str, Any]) -> Task:
        """The task of a file's mapping (without its ``kind``)."""

    @abstractmethod
    def to_dict(self) -> dict[str, Any]:
        """The file's mapping (without ``kind``; :func:`save_task` adds it)."""

    def check(self) -> None:
        """Check the fields common to every kind (call from ``__post_init__``)."""
        if self.frame not in FRAMES:
            raise TaskError(f"task {self.name!r}: unknown frame {self.frame!r}; frames: {FRAMES}")
        if not 0.0 < self.teleop.scale <= 1.0:
            raise TaskError(f"task {self.name!r}: teleop scale must be in ]0, 1]")
        self.check_fixture(self.fixture_spec)
        names = []
        for c in self.conditions:
            self.check_fixture(c, condition=True)
            names.append(c["name"])
        if len(set(names)) != len(names):
            raise TaskError(f"task {self.name!r}: condition names must be unique, got {names}")
        for wall in self.walls:
            make_wall(self.name, wall)
        from davinci_sim.tasks.scoring import merge_scoring, parse_scoring

        try:
            spec = merge_scoring(self.SCORING, getattr(self, "scoring_spec", None) or {})
            parse_scoring(spec, self.METRICS, self.name)
        except ValueError as e:
            raise TaskError(f"task {self.name!r}: {e}") from e

    # ------------------------------------------------------------ scene
    @abstractmethod
    def draw(
        self, spec: mujoco.MjSpec, *, T_world_camera=None, prefix: str = "task/"
    ) -> mujoco.MjsBody:
        """Add the task's visuals (visual-only geoms) to ``spec``; ``T_world_camera`` is the
        endoscope's pose (to place a camera-frame task and face labels to the viewer)."""

    @property
    def view_points(self) -> np.ndarray:
        """(k, 3) points the endoscope should frame to show the task, task frame, m (a
        session can bring the camera to them: :meth:`TaskSession.frame_view`)."""
        return np.asarray(self.start, dtype=float).reshape(1, 3)

    @property
    def check_points(self) -> np.ndarray:
        """(k, 3) points the task's PSM must reach, task frame, m (``task check``);
        by default the :attr:`view_points`."""
        return np.asarray(self.view_points, dtype=float).reshape(-1, 3)

    def scene_fields(self, model, data, cache: dict) -> dict:
        """Optional :class:`Sample` fields the kind reads from the simulation at
        ``data``'s state (e.g. its objects: ``objects``, ``grasp``); ``cache`` is the
        caller's dict, kept between ticks, for lookups built once per model. A kind with
        an :meth:`objects_probe` makes them from its reading (:meth:`objects_fields`);
        nothing by default: a kind without objects reads nothing."""
        probe = self.objects_probe(model, cache)
        if probe is None:
            return {}
        return self.objects_fields(probe.read(data), model, data, cache)

    def objects_probe(self, model, cache: dict):
        """The :class:`~davinci_sim.tasks.objects_probe.ObjectsProbe` whose reading makes
        the kind's scene fields (kept in ``cache``, as :meth:`cached_probe`), or None for a
        kind without objects. The console's compiled ticks record its reading after each
        step (:mod:`davinci_sim.console.chunk`)."""
        return None

    def objects_fields(self, reading, model, data, cache: dict) -> dict:
        """The sample's scene fields from an
        :class:`~davinci_sim.tasks.objects_probe.ObjectsReading` taken after a step;
        ``data`` is that step's state, or None where the reading was recorded by the
        compiled ticks (the reading then holds all the kind reads of the step)."""
        raise NotImplementedError(f"{type(self).__name__} has no objects")

    def reset_scene(self, model, data) -> None:  # noqa: B027 (an optional hook)
        """Put the task's objects in the simulation (``data``) back at their start poses,
        at rest, without a rebuild: what a session's reset does before the next
        repetition (:meth:`~davinci_sim.tasks.session.TaskSession.reset`). Nothing by
        default: a kind without objects has nothing to put back."""

    # ------------------------------------------------------------ state machine
    @abstractmethod
    def initial_state(self, n: int):
        """``n`` trials in IDLE: a NamedTuple of (n,)-leading arrays with a ``phase`` field."""

    def reset_state(self, state, mask=None):
        """Back to IDLE, all trials or those where ``mask`` (n,) is true (a state's fields
        are (n, ...) arrays)."""
        fresh = self.initial_state(len(state.phase))
        if mask is None:
            return fresh
        return _rows_where(np.asarray(mask, dtype=bool), fresh, state)

    def cached_probe(self, model, cache: dict):
        """``self.probe(model)`` (a kind with objects reads the scene through a probe) kept
        in the caller's ``cache`` (:meth:`scene_fields`'s) for this model and task; the
        cache keeps at most four."""
        key = ("probe", id(model), id(self))
        entry = cache.get(key)
        if entry is None or entry[0] is not model or entry[1] is not self:
            entry = cache[key] = (model, self, self.probe(model))
            while len(cache) > 4:
                del cache[next(iter(cache))]
        return entry[2]

    @abstractmethod
    def step(self, state, sample: Sample) -> tuple[Any, dict[str, np.ndarray]]:
        """Advance n trials by one sample (pure): ``(new state, observations)``, the
        observations a dict of (n,...) arrays with at least ``distance`` (m)."""

    @abstractmethod
    def at_start(self, tip) -> np.ndarray:
        """(n,) bool: tips (n, 3), task frame, m, where a repetition starts (IDLE → READY)."""

    @abstractmethod
    def distance(self, tip) -> np.ndarray:
        """(n,) the ``distance`` observation of tips (n, 3), task frame, m."""

    # ------------------------------------------------------------ metrics
    def metrics_accumulator(self, n: int) -> MetricsAccumulator:
        """An accumulator of the kind's ``METRICS`` for ``n`` trials of this task."""
        return MetricsAccumulator(self.METRICS, n, self)

    @cached_property
    def scoring(self):
        """The task's :class:`~davinci_sim.tasks.scoring.Scoring` (its reference loaded)."""
        from davinci_sim.tasks.scoring import task_scoring

        return task_scoring(self)

    def score(self, values: dict, finished: bool = True) -> dict:
        """``score`` (%) and ``passed`` of an attempt's metric ``values`` (name → value)."""
        return self.scoring.row(values, finished)

    def progress(self, state) -> str:
        """Where the first trial of ``state`` is within a repetition, in a few words for
        the console's panel (e.g. ``target 2 of 4``; "" by default)."""
        return ""

    def summary(self, row: dict) -> str:
        """A repetition's row in a few words (the session's status message)."""
        shown = [m for m in self.METRICS if m.report is not None][:2]
        return (
            ", ".join(f"{m.label} {row[m.name] * m.report[1]:.2f} {m.report[0]}" for m in shown)
            + "; back to the start for the next"
        )

    # ------------------------------------------------------------ frames
    def T_task_camera(self, T_world_camera) -> np.ndarray:
        """The camera (ECM tip) in the task's frame, 4x4: ``T_world_camera`` for a
        world-frame task, the identity for a camera-frame one."""
        if self.frame == "camera":
            return np.eye(4)
        return np.asarray(T_world_camera, dtype=float).copy()

    def T_task_cameras(self, T_world_cameras) -> np.ndarray:
        """:meth:`T_task_camera` of m cameras ``T_world_cameras`` (m, 4, 4): (m, 4, 4)."""
        T = np.asarray(T_world_cameras, dtype=float)
        if self.frame == "camera":
            return np.broadcast_to(np.eye(4), T.shape).copy()
        return T.copy()

    # ------------------------------------------------------------ fixtures
    def guidance(self, spec: dict):
        """The guidance field of a fixture entry in the task's frame (None: no force). The
        base kind offers ``none`` only."""
        return None

    def probe_guidance(self, spec: dict) -> None:
        """Build the guidance of ``spec`` to check its parameters (raises ValueError or
        TypeError); by default :meth:`guidance` itself."""
        self.guidance(spec)

    def fixture_keys(self, kind: str) -> set[str] | None:
        """The parameter names a fixture entry of type ``kind`` may have (None: whatever
        its law takes, checked when it is built); KeyError if the kind offers no such type.
        By default :attr:`FIXTURE_TYPES`."""
        if kind not in self.FIXTURE_TYPES:
            raise KeyError(f"unknown fixture type {kind!r}; types: {list(self.FIXTURE_TYPES)}")
        return set(self.FIXTURE_TYPES[kind])

    def check_fixture(self, spec: dict, *, condition: bool = False) -> None:
        """Refuse a fixture entry of a type or with parameters the kind does not offer."""
        if not isinstance(spec, dict):
            raise TaskError(f"task {self.name!r}: a fixture entry must be a mapping, got {spec!r}")
        kind = spec.get("type", "none")
        try:
            keys = self.fixture_keys(kind)
        except KeyError as e:
            raise TaskError(f"task {self.name!r}: {e.args[0]}") from e
        allowed = (keys or set()) | {"type", "name"}
        unknown = set(spec) - allowed
        if keys is not None and unknown:
            raise TaskError(
                f"task {self.name!r}: unknown keys {sorted(unknown)} for a {kind} fixture; "
                f"keys: {sorted(allowed)}"
            )
        if condition and not isinstance(spec.get("name"), str):
            raise TaskError(f"task {self.name!r}: each condition needs a 'name', got {spec!r}")
        try:
            self.probe_guidance(spec)
        except (TypeError, ValueError) as e:
            raise TaskError(f"task {self.name!r}: fixture {spec!r}: {e}") from e

    def condition(self, name: str) -> dict:
        """The fixture entry of the condition called ``name``."""
        for c in self.conditions:
            if c["name"] == name:
                return c
        raise TaskError(
            f"task {self.name!r} has no condition {name!r}; "
            f"conditions: {[c['name'] for c in self.conditions]}"
        )

    def fixture(self, spec: dict | str | None = None) -> Fixture:
        """The task's fixture in its frame: the guidance of ``spec`` (a fixture entry, a
        condition name, or None for the task's own ``fixture``) plus the walls."""
        if spec is None:
            spec = self.fixture_spec
        elif isinstance(spec, str):
            spec = self.condition(spec)
        self.check_fixture(spec)
        guidance = self.guidance(spec)
        parts = [] if guidance is None else [guidance]
        parts.extend(make_wall(self.name, w) for w in self.walls)
        return combine(*parts)


def common_fields(data: dict[str, Any]) -> dict[str, Any]:
    """The constructor arguments common to every kind, from a file's mapping: ``teleop``
    (a :class:`TeleopSpec`), ``fixture_spec``, ``conditions``, ``walls``, and ``name``,
    ``description``, ``frame``, ``scoring_spec`` (the file's ``scoring``) when present."""
    name = data.get("name", "?")
    kw = {k: data[k] for k in ("name", "description", "frame") if k in data}
    try:
        kw["teleop"] = TeleopSpec(**data.get("teleop", {}))
    except TypeError as e:
        raise TaskError(f"task {name!r}: {e}") from e
    kw["fixture_spec"] = dict(data.get("fixture", {"type": "none"}))
    kw["conditions"] = tuple(dict(c) for c in data.get("conditions", ()))
    kw["walls"] = tuple(dict(w) for w in data.get("walls", ()))
    if "scoring" in data:  # only for kinds whose files may have it (check_keys)
        scoring = data["scoring"]
        if not isinstance(scoring, dict):
            raise TaskError(f"task {name!r}: scoring must be a mapping, got {scoring!r}")
        kw["scoring_spec"] = dict(scoring)
    return kw


def common_to_dict(task) -> dict[str, Any]:
    """The common fields of ``task`` as its file has them (the inverse of
    :func:`common_fields`)."""
    out = {
        "name": task.name,
        "description": task.description,
        "frame": task.frame,
        "teleop": vars(task.teleop).copy(),
        "fixture": dict(task.fixture_spec),
        "conditions": [dict(c) for c in task.conditions],
        "walls": [dict(w) for w in task.walls],
    }
    if getattr(task, "scoring_spec", None):
        out["scoring"] = dict(task.scoring_spec)
    return out


def check_keys(data: dict[str, Any], known: set[str], required=("name",)) -> None:
    """Refuse unknown or missing keys of a task file's mapping."""
    name = data.get("name", "?")
    unknown = set(data) - known
    if unknown:
        raise TaskError(f"task {name!r}: unknown keys {sorted(unknown)}; keys: {sorted(known)}")
    missing = [k for k in required if k not in data]
    if missing:
        raise TaskError(f"task {name!r}: {' and '.join(repr(k) for k in required)} are required")


def check_number(task: str, name: str, value) -> None:
    """Refuse a value that is not a finite number >= 0."""
    if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
        raise TaskError(f"task {task!r}: {name} must be a number >= 0, got {value!r}")


def make_wall(task: str, spec: dict):
    """A wall of a task file (``type: plane`` or ``sphere``, :mod:`davinci_sim.haptics.wall`)."""
    kind = spec.get("type")
    if kind not in _WALLS:
        raise TaskError(f"task {task!r}: unknown wall type {kind!r}; types: {list(_WALLS)}")
    params = {k: v for k, v in spec.items() if k != "type"}
    for key in ("point", "normal", "center", "fallback_normal"):
        if key in params:
            params[key] = tuple(float(x) for x in params[key])
    try:
        return _WALLS[kind](**params)
    except (TypeError, ValueError) as e:
        raise TaskError(f"task {task!r}: wall {spec!r}: {e}") from e


# ---------------------------------------------------------------- kinds and files
def task_kinds() -> dict[str, type[Task]]:
    """The registered kinds: name → class."""
    _load_builtin_kinds()
    return dict(_KINDS)


def _load_builtin_kinds() -> None:
    import davinci_sim.tasks.exercises  # noqa: F401 (camera_targeting, ring_walk, needle_targeting)
    import davinci_sim.tasks.peg  # noqa: F401 (registers "peg_transfer")
    import davinci_sim.tasks.task  # noqa: F401 (registers "path")


def task_from_dict(data: dict[str, Any], *, text: str | None = None, source: str = "") -> Task:
    """The task of a file's mapping; its ``kind`` (default ``path``) selects the class. The
    mapping is first checked against the kind's schema (:mod:`davinci_sim.tasks.schema`);
    ``text``, the file's, and ``source``, its name, put the line in the message."""
    from davinci_sim.tasks.schema import SchemaError, check_task_data

    if not isinstance(data, dict):
        raise TaskError(f"a task must be a mapping, got {type(data).__name__}")
    kinds = task_kinds()
    kind = data.get("kind", DEFAULT_KIND)
    if not isinstance(kind, str) or kind not in kinds:
        raise TaskError(
            f"task {data.get('name', '?')!r}: unknown kind {kind!r}; kinds: {sorted(kinds)}"
        )
    try:
        check_task_data(kinds[kind], data, text, source or f"task {data.get('name', '?')!r}")
    except SchemaError as e:
        raise TaskError(str(e)) from None
    data = dict(data)
    data.pop("kind", None)
    return kinds[kind].from_dict(data)


def task_to_dict(task: Task) -> dict[str, Any]:
    """A task's file mapping; ``kind`` first unless it is the default (path files keep
    their format)."""
    data = task.to_dict()
    return data if task.kind == DEFAULT_KIND else {"kind": task.kind, **data}


def _data_dir():
    return resources.files("davinci_sim.tasks") / "data"


def available_tasks() -> list[str]:
    """Names of the shipped tasks."""
    return sorted(
        p.name.rsplit(".", 1)[0]
        for p in _data_dir().iterdir()
        if p.name.endswith((".yaml", ".yml", ".json"))
    )


def load_task(name_or_path: str | Path = "seed_path") -> Task:
    """A shipped task by name, or a task file (``.yaml``, ``.yml`` or ``.json``).

    Raises:
        TaskError: unknown name, unreadable file, unknown kind or invalid content.
    """
    text: str
    source = str(name_or_path)
    path = Path(source)
    if path.suffix in (".yaml", ".yml", ".json") and path.exists():
        text = path.read_text()
    else:
        for suffix in (".yaml", ".yml", ".json"):
            candidate = _data_dir() / f"{source}{suffix}"
            if candidate.is_file():
                text, path = candidate.read_text(), Path(candidate.name)
                break
        else:
            raise TaskError(
                f"no task {source!r}; shipped tasks: {available_tasks()}, or a file path"
            )
    try:
        data = json.loads(text) if path.suffix == ".json" else yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError) as e:
        raise TaskError(f"cannot parse task file {source!r}: {e}") from e
    if not isinstance(data, dict):
        raise TaskError(f"task file {source!r} must hold a mapping")
    return task_from_dict(data, text=text, source=source)


def save_task(task: Task, path: str | Path) -> None:
    """Write ``task`` as YAML (or JSON for a ``.json`` path)."""
    p = Path(path)
    data = task_to_dict(task)
    if p.suffix == ".json":
        p.write_text(json.dumps(data, indent=2))
    else:
        p.write_text(yaml.safe_dump(data, sort_keys=False))
