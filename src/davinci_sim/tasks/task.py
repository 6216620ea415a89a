"""Path-following tasks as data: a YAML (or JSON) file per task — the ``path`` kind of
:class:`~davinci_sim.tasks.base.Task` (the default when a file has no ``kind``).

A task file gives the path's waypoints (the numbered points, m) in a frame (``world``: the
cart frame, or ``camera``: the ECM tip), the corner rounding, the tolerances of the task
states (:mod:`davinci_sim.tasks.state`) and of the metrics (:mod:`davinci_sim.tasks.metrics`),
the teleoperation it is done with (PSM, MTM, motion scale, start keyframe), its fixture and,
optionally, a list of fixture conditions for studies, walls, the look of the path, and an
object carried in the jaws with the wrist turns it asks for (``carry``:
:mod:`davinci_sim.tasks.carry`). The
shipped tasks live in ``davinci_sim/tasks/data``: ``seed_path`` reproduces the seed paper's
task (§II-D); :func:`available_tasks` lists them, :func:`load_task` reads one by name or
from a path, :meth:`PathTask.to_dict` / :func:`save_task` write one.

Fixture entries (``fixture``, each of ``conditions``): ``type`` is ``viscous`` (B, G_max,
transition: :class:`~davinci_sim.haptics.viscous.ViscousGuidance`; ``transition`` defaults
to 0, the seed's law as printed, a positive value is an on-path ramp of that width, m),
``spring`` (stiffness, damping, max_force, transition:
:class:`~davinci_sim.haptics.spring.SpringGuidance`), ``none``, a kind registered with
:func:`~davinci_sim.haptics.kinds.register_fixture_kind`, or an importable
``package.module:Name`` (a user's own law, :mod:`davinci_sim.haptics.kinds`); a condition
also has a ``name``. Walls (``walls``): ``type: plane`` (point, normal,
stiffness, damping, damping_depth, max_force) or ``type: sphere`` (center, radius, keep_out,
…), see :mod:`davinci_sim.haptics.wall`. A task's fixture is its guidance plus its walls, in
the task's frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar

import numpy as np

from davinci_sim.geometry.floats import norm3
from davinci_sim.geometry.path import Polyline, rounded_polyline
from davinci_sim.haptics.adaptive import MODES
from davinci_sim.haptics.adaptive import PARAMS as ADAPTIVE_PARAMS
from davinci_sim.haptics.combine import combine
from davinci_sim.haptics.fixture import Fixture
from davinci_sim.haptics.kinds import build_fixture, fixture_kind
from davinci_sim.haptics.path_query import closest_point
from davinci_sim.tasks.base import (
    FRAMES,
    Sample,
    Task,
    TaskError,
    TeleopSpec,
    available_tasks,
    check_keys,
    check_number,
    common_fields,
    common_to_dict,
    load_task,
    save_task,
)
from davinci_sim.tasks.carry import CARRY_SCHEMA, CarrySpec
from davinci_sim.tasks.metrics import PATH_METRICS
from davinci_sim.tasks.schema import NONNEGATIVE, POINT, ListOf, Number, Record, Text, Vector
from davinci_sim.tasks.state import Phase, initial_state, task_step
from davinci_sim.tasks.trainer import PATH_MISSED_TARGETS, trainer_metrics

#: A crawl along the path, m/s: the path kind's completion time scoring 0 % is its length
#: at this speed (our choice: a third of the synthetic trainees' median practised speed).
FAIL_SPEED = 0.005

__all__ = [
    "FRAMES",
    "PathTask",
    "TaskError",
    "TeleopSpec",
    "VisualSpec",
    "available_tasks",
    "load_task",
    "save_task",
]


@dataclass(frozen=True)
class VisualSpec:
    """How the path is drawn (:func:`davinci_sim.tasks.scene.add_path_visual`)."""

    tube_radius: float = 0.0006
    marker_radius: float = 0.0018
    path_rgba: tuple[float, float, float, float] = (1.0, 0.25, 0.9, 0.9)
    marker_rgba: tuple[float, float, float, float] = (1.0, 0.85, 0.1, 1.0)


@dataclass(frozen=True, eq=False)
class PathTask(Task, kind="path"):
    """A path-following task (see the module docstring for the file format)."""

    #: The path metrics, then the trainers' (:mod:`davinci_sim.tasks.trainer`; missed
    #: targets: the numbered points 2..N−1 never within tube_radius).
    METRICS = (*PATH_METRICS, *trainer_metrics(replace=(PATH_MISSED_TARGETS,)))
    FILE_FIELDS: ClassVar[dict] = {
        "waypoints": ListOf(POINT, min_items=2, what="points [x, y, z]"),
        **dict.fromkeys(("corner_radius", "start_tolerance", "finish_tolerance",
                         "tube_radius"), NONNEGATIVE),
        "min_progress": Number(minimum=0.0, maximum=1.0),
        "numbered": ListOf(Number(minimum=0.0), min_items=2, what="waypoint indices"),
        "visual": Record({"tube_radius": NONNEGATIVE, "marker_radius": NONNEGATIVE,
                          "path_rgba": Vector(4, "r, g, b, a", Number(minimum=0.0, maximum=1.0)),
                          "marker_rgba": Vector(4, "r, g, b, a",
                                                Number(minimum=0.0, maximum=1.0))}),
        "carry": CARRY_SCHEMA,
    }  # fmt: skip
    """The file's fields besides the common ones (:mod:`davinci_sim.tasks.schema`)."""
    FILE_REQUIRED = ("waypoints",)
    #: The built-in guidance types (:mod:`davinci_sim.haptics.kinds`); registered kinds and
    #: ``module:Name`` laws are offered too (:meth:`fixture_keys`).
    FIXTURE_TYPES = {
        "viscous": {"B", "G_max", "transition"},
        "spring": {"stiffness", "damping", "max_force", "transition"},
        "adaptive": set(ADAPTIVE_PARAMS),
        "viscous_elastic": {
            "B",
            "elastic_gain",
            "threshold",
            "half",
            "slope",
            "max_force",
            "assistance",
        },  # fmt: skip
        "none": set(),
    }
    #: The adaptive entry's parameters that are not numbers (for the file schema).
    FIXTURE_PARAMETERS = {"mode": Text(MODES), "metric": Text()}

    name: str
    waypoints: np.ndarray
    """Numbered points 1..N, (N, 3), m, in :attr:`frame`."""
    frame: str = "world"
    description: str = ""
    corner_radius: float = 0.006
    start_tolerance: float = 0.003
    """The tip is *ready* within this distance of point 1, m."""
    finish_tolerance: float = 0.003
    """The run is *finished* within this distance of the last point, m."""
    min_progress: float = 0.5
    """... once the tip has been past this fraction of the path's length."""
    tube_radius: float = 0.003
    """Tolerance tube of the *time outside* metric, m."""
    numbered: tuple[int, ...] | None = None
    """Indices of the waypoints that are numbered points (drawn as markers, the ends of the
    trainee's strokes, the missed-targets metric's targets), the first and last included;
    None: every waypoint. A dense curve (a trajectory taken from elsewhere) numbers its
    ends only."""
    teleop: TeleopSpec = field(default_factory=TeleopSpec)
    fixture_spec: dict = field(default_factory=lambda: {"type": "none"})
    conditions: tuple[dict, ...] = ()
    walls: tuple[dict, ...] = ()
    visual: VisualSpec = field(default_factory=VisualSpec)
    carry: CarrySpec | None = None
    """An object carried in the jaws and the wrist's turns along the path
    (:mod:`davinci_sim.tasks.carry`); None: the bare tool."""
    scoring_spec: dict = field(default_factory=dict)
    """The file's ``scoring`` (updates :attr:`SCORING`, :mod:`davinci_sim.tasks.scoring`)."""

    def __post_init__(self) -> None:
        w = np.array(self.waypoints, dtype=float)
        if w.ndim != 2 or w.shape[1] != 3 or len(w) < 2 or not np.all(np.isfinite(w)):
            raise TaskError(f"task {self.name!r}: waypoints must be N >= 2 points [x, y, z] (m)")
        w.setflags(write=False)
        object.__setattr__(self, "waypoints", w)
        for name in ("corner_radius", "start_tolerance", "finish_tolerance", "tube_radius"):
            check_number(self.name, name, getattr(self, name))
        if not 0.0 <= self.min_progress <= 1.0:
            raise TaskError(f"task {self.name!r}: min_progress must be in [0, 1]")
        if self.numbered is not None:
            numbered = list(self.numbered)
            whole = all(float(i) == int(i) for i in numbered)
            ints = [int(i) for i in numbered] if whole else []
            if not (whole and ints[0] == 0 and ints[-1] == len(w) - 1
                    and all(a < b for a, b in zip(ints, ints[1:], strict=False))):  # fmt: skip
                raise TaskError(
                    f"task {self.name!r}: numbered must be increasing waypoint indices from 0 "
                    f"to {len(w) - 1}, got {numbered}"
                )
            object.__setattr__(self, "numbered", tuple(ints))
        self.check()
        try:
            self.path  # noqa: B018 (builds and checks the corners)
        except ValueError as e:
            raise TaskError(f"task {self.name!r}: {e}") from e

    @property
    def SCORING(self) -> dict:  # noqa: N802 (the kind's declaration, from the geometry)
        """What a path attempt is scored on, and the values scoring 0 % (our choices):
        deviation (weight 2; a mean distance of ``tube_radius``), time (the path's length
        crawled at :data:`FAIL_SPEED`), economy (1.5x the path's length), time outside the
        tube (half the failing time), collisions (5), excessive force (5 s), out of view
        (the path's length), master workspace (2x the numbered points' box diagonal over
        the motion scale), missed targets (all of points 2..N−1); weight 1 but deviation.
        100 %: the expert reference's means."""
        L = float(self.path.length)
        box = np.ptp(self.waypoints, axis=0)
        span = float(np.linalg.norm(box)) / self.teleop.scale
        t_fail = L / FAIL_SPEED
        return {
            "metrics": {
                "deviation_error": {"weight": 2.0, "fail": self.tube_radius},
                "completion_time": {"weight": 1.0, "fail": t_fail},
                "path_length": {"weight": 1.0, "fail": 1.5 * L},
                "time_outside": {"weight": 1.0, "fail": t_fail / 2.0},
                "instrument_collisions": {"weight": 1.0, "fail": 5.0},
                "excessive_force": {"weight": 1.0, "fail": 5.0},
                "out_of_view": {"weight": 1.0, "fail": L},
                "master_workspace": {"weight": 1.0, "fail": 2.0 * span},
                "missed_targets": {
                    "weight": 1.0,
                    "fail": float(max(len(self.marker_arc_lengths) - 2, 1)),
                },  # fmt: skip
            }
        }

    @classmethod
    def along(
        cls,
        path: Polyline,
        *,
        start_tolerance: float,
        finish_tolerance: float,
        tube_radius: float,
        min_progress: float = 0.5,
        name: str = "path",
    ) -> PathTask:
        """A task following ``path`` as it is (its vertices as sharp-cornered waypoints, in
        whatever frame the path is): e.g. a task's path already moved to the camera frame
        (:mod:`davinci_sim.operators.offline`)."""
        return cls(
            name,
            path.vertices,
            corner_radius=0.0,
            start_tolerance=start_tolerance,
            finish_tolerance=finish_tolerance,
            tube_radius=tube_radius,
            min_progress=min_progress,
        )

    # ------------------------------------------------------------ geometry
    @cached_property
    def _rounded(self) -> tuple[Polyline, np.ndarray]:
        return rounded_polyline(self.waypoints, self.corner_radius)

    @property
    def path(self) -> Polyline:
        """The path in :attr:`frame` (rounded corners), m."""
        return self._rounded[0]

    @property
    def marker_arc_lengths(self) -> np.ndarray:
        """Arc length of each numbered point's place on the path (N,), m."""
        at = self._rounded[1]
        return at if self.numbered is None else at[list(self.numbered)]

    @cached_property
    def markers(self) -> np.ndarray:
        """The numbered points as drawn: their places on the path (N, 3), m, in the frame
        (read-only; computed once: the missed-targets metric reads it every tick)."""
        m = self.path.point_at(self.marker_arc_lengths)
        m.setflags(write=False)
        return m

    @property
    def view_points(self) -> np.ndarray:
        """The waypoints' places on the path: framing them shows the whole path (and
        ``task check`` checks each)."""
        if self.numbered is None:
            return self.markers
        return self.path.point_at(self._rounded[1])

    @property
    def start(self) -> np.ndarray:
        return self.waypoints[0]

    @property
    def finish(self) -> np.ndarray:
        return self.waypoints[-1]

    def path_in_camera(self, T_world_camera) -> Polyline:
        """The path in the camera frame, given the camera's pose in the world (cart)."""
        if self.frame == "camera":
            return self.path
        T = np.asarray(T_world_camera, dtype=float)
        R, t = T[:3, :3], T[:3, 3]
        T_camera_world = np.eye(4)
        T_camera_world[:3, :3] = R.T
        T_camera_world[:3, 3] = -R.T @ t
        return self.path.transformed(T_camera_world)

    # ------------------------------------------------------------ Task
    def draw(self, spec, *, T_world_camera=None, prefix: str = "task/"):
        """The path, its numbered markers and their numbers
        (:func:`~davinci_sim.tasks.scene.add_path_visual`)."""
        from davinci_sim.tasks.scene import add_path_visual

        body = add_path_visual(spec, self, T_world_camera=T_world_camera, prefix=prefix)
        if self.carry is not None:
            # The carried object on the task's PSM's wrist (a scene without it: the path).
            try:
                wrist = spec.body(f"{self.teleop.psm}/wrist_yaw")
                site = spec.site(f"{self.teleop.psm}/tip")
            except Exception:
                wrist = site = None
            if wrist is not None and site is not None:
                self.carry.draw(wrist, site, prefix)
        return body

    @property
    def check_points(self) -> np.ndarray:
        """The :attr:`view_points`, then (with :attr:`carry`) the path's points at the
        carry's knots of progress, where ``task check`` checks the turned wrist."""
        if self.carry is None:
            return np.asarray(self.view_points, dtype=float).reshape(-1, 3)
        knots = self.path.point_at(np.asarray(self.carry.progress) * self.path.length)
        return np.concatenate([np.asarray(self.view_points, dtype=float).reshape(-1, 3), knots])

    @property
    def view_turns(self) -> np.ndarray | None:
        """(k, 3) per :attr:`check_points`, the tool's turn from its keyframe orientation
        there (task frame, rad; NaN rows: none), or None without :attr:`carry`."""
        if self.carry is None:
            return None
        none = np.full((len(np.asarray(self.view_points).reshape(-1, 3)), 3), np.nan)
        return np.concatenate([none, self.carry.turn])

    def initial_state(self, n: int):
        """``n`` trials in IDLE (:class:`~davinci_sim.tasks.state.TaskState`)."""
        return initial_state(n)

    def step(self, state, sample: Sample):
        """:func:`~davinci_sim.tasks.state.task_step` of the sample's tips; observations:
        ``distance`` and ``arc_length`` of the tips' closest path points, m."""
        path = self.path
        tip = sample.tip
        cp = closest_point(path, tip)  # (one trial, the live session: a compiled kernel)
        if tip.shape == (1, 3):  # one trial: the two distances on floats, numpy's sums
            d_start, d_finish = _distance(tip[0], self.start), _distance(tip[0], self.finish)
        else:
            d_start = np.linalg.norm(tip - self.start, axis=1)
            d_finish = np.linalg.norm(tip - self.finish, axis=1)
        new = task_step(
            state,
            sample.time,
            d_start,
            d_finish,
            cp.arc_length,
            path_length=path.length,
            start_tolerance=self.start_tolerance,
            finish_tolerance=self.finish_tolerance,
            min_progress=self.min_progress,
        )
        return new, {"distance": cp.distance, "arc_length": cp.arc_length}

    def summary(self, row: dict) -> str:
        return (
            f"deviation {row['deviation_error'] * 1e3:.2f} mm,"
            f" {row['completion_time']:.2f} s; back to point 1 for the next"
        )

    def progress(self, state) -> str:
        """``follow the path to point k of N`` while a repetition runs: the first numbered
        point past the furthest the tool has come along the path (within the finish's
        tolerance: a point the tool is at counts as reached)."""
        if int(state.phase[0]) != Phase.RUNNING:
            return ""
        arcs = self.marker_arc_lengths
        reached = float(state.progress[0]) + self.finish_tolerance
        k = int(np.searchsorted(arcs, reached, side="right"))  # (points reached: 1 at least)
        return f"follow the path to point {min(max(k, 1), len(arcs) - 1) + 1} of {len(arcs)}"

    def at_start(self, tip) -> np.ndarray:
        p = np.asarray(tip, dtype=float).reshape(-1, 3)
        return np.linalg.norm(p - self.start, axis=1) <= self.start_tolerance

    def distance(self, tip) -> np.ndarray:
        return self.path.closest_point(np.asarray(tip, dtype=float).reshape(-1, 3)).distance

    # ------------------------------------------------------------ fixtures
    def fixture_keys(self, kind: str) -> set[str] | None:
        """Any guidance kind of :mod:`davinci_sim.haptics.kinds`: built in, registered, or
        an importable ``module:Name`` (its parameters are checked when it is built)."""
        k = fixture_kind(kind)  # KeyError: no such kind
        return None if k.params is None else set(k.params)

    def guidance(self, spec: dict, path: Polyline | None = None):
        """Viscous or spring guidance along ``path`` (default: the task's), or None."""
        return _guidance(spec, self.path if path is None else path)

    def probe_guidance(self, spec: dict) -> None:
        # On a unit segment: the task's own path is checked after its fixtures.
        _guidance(spec, Polyline([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))

    def fixture(self, spec: dict | str | None = None, *, path: Polyline | None = None) -> Fixture:
        """The task's fixture in its frame: the guidance of ``spec`` (a fixture entry, a
        condition name, or None for the task's own ``fixture``) plus the walls.

        ``path`` replaces the task's path (e.g. the same path in another frame; the walls
        are then left out, as they are given in the task's frame).
        """
        if path is None:
            return super().fixture(spec)
        if spec is None:
            spec = self.fixture_spec
        elif isinstance(spec, str):
            spec = self.condition(spec)
        self.check_fixture(spec)
        guidance = _guidance(spec, path)
        return combine(*([] if guidance is None else [guidance]))

    # ------------------------------------------------------------ I/O
    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PathTask:
        known = {
            "name",
            "description",
            "frame",
            "waypoints",
            "corner_radius",
            "start_tolerance",
            "finish_tolerance",
            "min_progress",
            "tube_radius",
            "numbered",
            "teleop",
            "fixture",
            "conditions",
            "walls",
            "visual",
            "scoring",
            "carry",
        }
        check_keys(data, known, required=("name", "waypoints"))
        name = data.get("name", "?")
        kw = common_fields(data)
        kw.update({k: data[k] for k in known & set(data) if k not in (*_COMMON, "visual", "carry")})
        try:
            visual = dict(data.get("visual", {}))
            for key in ("path_rgba", "marker_rgba"):
                if key in visual:
                    visual[key] = tuple(float(x) for x in visual[key])
            kw["visual"] = VisualSpec(**visual)
            if data.get("carry") is not None:
                kw["carry"] = CarrySpec.from_dict(data["carry"])
        except TypeError as e:
            raise TaskError(f"task {name!r}: {e}") from e
        return cls(**kw)

    def to_dict(self) -> dict[str, Any]:
        return {
            **common_to_dict(self),
            "waypoints": self.waypoints.tolist(),
            "corner_radius": self.corner_radius,
            "start_tolerance": self.start_tolerance,
            "finish_tolerance": self.finish_tolerance,
            "min_progress": self.min_progress,
            "tube_radius": self.tube_radius,
            **({} if self.numbered is None else {"numbered": list(self.numbered)}),
            "visual": {
                k: list(v) if isinstance(v, tuple) else v for k, v in vars(self.visual).items()
            },
            **({} if self.carry is None else {"carry": self.carry.to_dict()}),
        }


_COMMON = ("name", "description", "frame", "teleop", "fixture", "conditions", "walls", "scoring")


def _guidance(spec: dict, path: Polyline):
    # One registry builds every kind (haptics.kinds): the live loop and the study alike.
    return build_fixture(spec, path)


def _distance(p: np.ndarray, q: np.ndarray) -> float:
    """‖p − q‖ of two points (3,), m, summed as ``np.linalg.norm`` sums a row: the same
    float as the batch form's row."""
    return norm3(*(p - q).tolist())
