"""Path-following tasks as data: a YAML (or JSON) file per task.

A task file gives the path's waypoints (the numbered points, m) in a frame (``world``: the
cart frame, or ``camera``: the ECM tip), the corner rounding, the tolerances of the task
states (:mod:`davinci_sim.tasks.state`) and of the metrics (:mod:`davinci_sim.tasks.metrics`),
the teleoperation it is done with (PSM, MTM, motion scale, start keyframe), its fixture and,
optionally, a list of fixture conditions for studies, walls, and the look of the path. The
shipped tasks live in ``davinci_sim/tasks/data``: ``seed_path`` reproduces the seed paper's
task (§II-D); :func:`available_tasks` lists them, :func:`load_task` reads one by name or
from a path, :meth:`PathTask.to_dict` / :func:`save_task` write one.

Fixture entries (``fixture``, each of ``conditions``): ``type`` is ``viscous`` (B, G_max,
transition: :class:`~davinci_sim.haptics.viscous.ViscousGuidance`), ``spring`` (stiffness,
damping, max_force, transition: :class:`~davinci_sim.haptics.spring.SpringGuidance`) or
``none``; a condition also has a ``name``. Walls (``walls``): ``type: plane`` (point, normal,
stiffness, damping, damping_depth, max_force) or ``type: sphere`` (center, radius, keep_out,
…), see :mod:`davinci_sim.haptics.wall`. A task's fixture is its guidance plus its walls, in
the task's frame.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from davinci_sim.geometry.path import Polyline, rounded_polyline
from davinci_sim.haptics.combine import combine
from davinci_sim.haptics.fixture import Fixture
from davinci_sim.haptics.spring import SpringGuidance
from davinci_sim.haptics.viscous import DEFAULT_TRANSITION, ViscousGuidance
from davinci_sim.haptics.wall import PlaneWall, SphereWall

FRAMES = ("world", "camera")
_FIXTURE_KEYS = {
    "viscous": {"B", "G_max", "transition"},
    "spring": {"stiffness", "damping", "max_force", "transition"},
    "none": set(),
}
_WALLS = {"plane": PlaneWall, "sphere": SphereWall}


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


@dataclass(frozen=True)
class VisualSpec:
    """How the path is drawn (:func:`davinci_sim.tasks.scene.add_path_visual`)."""

    tube_radius: float = 0.0006
    marker_radius: float = 0.0018
    path_rgba: tuple[float, float, float, float] = (1.0, 0.25, 0.9, 0.9)
    marker_rgba: tuple[float, float, float, float] = (1.0, 0.85, 0.1, 1.0)


@dataclass(frozen=True, eq=False)
class PathTask:
    """A path-following task (see the module docstring for the file format)."""

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
    teleop: TeleopSpec = field(default_factory=TeleopSpec)
    fixture_spec: dict = field(default_factory=lambda: {"type": "none"})
    conditions: tuple[dict, ...] = ()
    walls: tuple[dict, ...] = ()
    visual: VisualSpec = field(default_factory=VisualSpec)

    def __post_init__(self) -> None:
        w = np.array(self.waypoints, dtype=float)
        if w.ndim != 2 or w.shape[1] != 3 or len(w) < 2 or not np.all(np.isfinite(w)):
            raise TaskError(f"task {self.name!r}: waypoints must be N >= 2 points [x, y, z] (m)")
        w.setflags(write=False)
        object.__setattr__(self, "waypoints", w)
        if self.frame not in FRAMES:
            raise TaskError(f"task {self.name!r}: unknown frame {self.frame!r}; frames: {FRAMES}")
        for name in ("corner_radius", "start_tolerance", "finish_tolerance", "tube_radius"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise TaskError(f"task {self.name!r}: {name} must be a number >= 0, got {value!r}")
        if not 0.0 <= self.min_progress <= 1.0:
            raise TaskError(f"task {self.name!r}: min_progress must be in [0, 1]")
        if not 0.0 < self.teleop.scale <= 1.0:
            raise TaskError(f"task {self.name!r}: teleop scale must be in ]0, 1]")
        _check_fixture(self.name, self.fixture_spec)
        names = []
        for c in self.conditions:
            _check_fixture(self.name, c, condition=True)
            names.append(c["name"])
        if len(set(names)) != len(names):
            raise TaskError(f"task {self.name!r}: condition names must be unique, got {names}")
        for wall in self.walls:
            _wall(self.name, wall)
        try:
            self.path  # noqa: B018 (builds and checks the corners)
        except ValueError as e:
            raise TaskError(f"task {self.name!r}: {e}") from e

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
        return self._rounded[1]

    @property
    def markers(self) -> np.ndarray:
        """The numbered points as drawn: their places on the path (N, 3), m, in the frame."""
        return self.path.point_at(self.marker_arc_lengths)

    @property
    def start(self) -> np.ndarray:
        return self.waypoints[0]

    @property
    def finish(self) -> np.ndarray:
        return self.waypoints[-1]

    def T_task_camera(self, T_world_camera) -> np.ndarray:
        """The camera (ECM tip) in the task's frame, 4x4: ``T_world_camera`` for a
        world-frame task, the identity for a camera-frame one."""
        if self.frame == "camera":
            return np.eye(4)
        return np.asarray(T_world_camera, dtype=float).copy()

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

    # ------------------------------------------------------------ fixtures
    def condition(self, name: str) -> dict:
        """The fixture entry of the condition called ``name``."""
        for c in self.conditions:
            if c["name"] == name:
                return c
        raise TaskError(
            f"task {self.name!r} has no condition {name!r}; "
            f"conditions: {[c['name'] for c in self.conditions]}"
        )

    def fixture(self, spec: dict | str | None = None, *, path: Polyline | None = None) -> Fixture:
        """The task's fixture in its frame: the guidance of ``spec`` (a fixture entry, a
        condition name, or None for the task's own ``fixture``) plus the walls.

        ``path`` replaces the task's path (e.g. the same path in another frame; the walls
        are then left out, as they are given in the task's frame).
        """
        if spec is None:
            spec = self.fixture_spec
        elif isinstance(spec, str):
            spec = self.condition(spec)
        _check_fixture(self.name, spec)
        parts = []
        guidance = _guidance(spec, self.path if path is None else path)
        if guidance is not None:
            parts.append(guidance)
        if path is None:
            parts.extend(_wall(self.name, w) for w in self.walls)
        return combine(*parts)

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
            "teleop",
            "fixture",
            "conditions",
            "walls",
            "visual",
        }
        unknown = set(data) - known
        name = data.get("name", "?")
        if unknown:
            raise TaskError(f"task {name!r}: unknown keys {sorted(unknown)}; keys: {sorted(known)}")
        if "waypoints" not in data or "name" not in data:
            raise TaskError(f"task {name!r}: 'name' and 'waypoints' are required")
        kw = {k: data[k] for k in known & set(data) if k not in ("teleop", "fixture", "visual")}
        try:
            kw["teleop"] = TeleopSpec(**data.get("teleop", {}))
            visual = dict(data.get("visual", {}))
            for key in ("path_rgba", "marker_rgba"):
                if key in visual:
                    visual[key] = tuple(float(x) for x in visual[key])
            kw["visual"] = VisualSpec(**visual)
        except TypeError as e:
            raise TaskError(f"task {name!r}: {e}") from e
        kw["fixture_spec"] = dict(data.get("fixture", {"type": "none"}))
        kw["conditions"] = tuple(dict(c) for c in data.get("conditions", ()))
        kw["walls"] = tuple(dict(w) for w in data.get("walls", ()))
        return cls(**kw)

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "description": self.description,
            "frame": self.frame,
            "waypoints": self.waypoints.tolist(),
            "corner_radius": self.corner_radius,
            "start_tolerance": self.start_tolerance,
            "finish_tolerance": self.finish_tolerance,
            "min_progress": self.min_progress,
            "tube_radius": self.tube_radius,
            "teleop": vars(self.teleop).copy(),
            "fixture": dict(self.fixture_spec),
            "conditions": [dict(c) for c in self.conditions],
            "walls": [dict(w) for w in self.walls],
            "visual": {
                k: list(v) if isinstance(v, tuple) else v for k, v in vars(self.visual).items()
            },
        }


def _check_fixture(task: str, spec: dict, *, condition: bool = False) -> None:
    if not isinstance(spec, dict):
        raise TaskError(f"task {task!r}: a fixture entry must be a mapping, got {spec!r}")
    kind = spec.get("type", "none")
    if kind not in _FIXTURE_KEYS:
        raise TaskError(
            f"task {task!r}: unknown fixture type {kind!r}; types: {list(_FIXTURE_KEYS)}"
        )
    allowed = _FIXTURE_KEYS[kind] | {"type", "name"}
    unknown = set(spec) - allowed
    if unknown:
        raise TaskError(
            f"task {task!r}: unknown keys {sorted(unknown)} for a {kind} fixture; "
            f"keys: {sorted(allowed)}"
        )
    if condition and not isinstance(spec.get("name"), str):
        raise TaskError(f"task {task!r}: each condition needs a 'name', got {spec!r}")
    try:
        _guidance(spec, Polyline([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))
    except (TypeError, ValueError) as e:
        raise TaskError(f"task {task!r}: fixture {spec!r}: {e}") from e


def _guidance(spec: dict, path: Polyline):
    kind = spec.get("type", "none")
    params = {k: float(v) for k, v in spec.items() if k not in ("type", "name")}
    if kind == "viscous":
        params.setdefault("transition", DEFAULT_TRANSITION)
        return ViscousGuidance(path, **params)
    if kind == "spring":
        return SpringGuidance(path, **params)
    return None


def _wall(task: str, spec: dict):
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


# ---------------------------------------------------------------- files
def _data_dir():
    return resources.files("davinci_sim.tasks") / "data"


def available_tasks() -> list[str]:
    """Names of the shipped tasks."""
    return sorted(
        p.name.rsplit(".", 1)[0]
        for p in _data_dir().iterdir()
        if p.name.endswith((".yaml", ".yml", ".json"))
    )


def load_task(name_or_path: str | Path = "seed_path") -> PathTask:
    """A shipped task by name, or a task file (``.yaml``, ``.yml`` or ``.json``).

    Raises:
        TaskError: unknown name, unreadable file or invalid content.
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
    return PathTask.from_dict(data)


def save_task(task: PathTask, path: str | Path) -> None:
    """Write ``task`` as YAML (or JSON for a ``.json`` path)."""
    p = Path(path)
    data = task.to_dict()
    if p.suffix == ".json":
        p.write_text(json.dumps(data, indent=2))
    else:
        p.write_text(yaml.safe_dump(data, sort_keys=False))
