"""Needle targeting (pick and place at targets): touch a sequence of targets, each with the
tool pointing the way the target requires — the ``needle_targeting`` kind.

A target is a point and a direction (task frame). The tool *touches* target k when its tip
is within ``target_radius`` of the point; the touch is a **hit** when, while the tip is
inside, the tool's direction (the tip frame's z axis: where the jaws point, the direction a
held needle is driven) stays within ``angle_tolerance`` of the target's for ``dwell``
seconds; the tip leaving the target without a hit is a **miss**. Either way the exercise
moves on to target k + 1; it is finished when every target was hit or missed.

States::

    IDLE ──tip within start_tolerance of start──> READY ──tip leaves──> RUNNING (t_start)
    RUNNING ──last target hit or missed──> FINISHED ──> RESULTS

Metrics (besides time, economy and the trainer metrics that apply — collisions, excessive
force, out of view, master workspace; no objects, so no drops):

* ``targets_hit`` (1, higher is better);
* ``missed_targets`` (1): the targets left without a hit;
* ``orientation_error`` (rad, shown in deg): over the targets hit or missed, the mean of
  the smallest angle between the tool's and the target's direction while the tip was
  inside the target.

The sample must carry the tool's orientation (``Sample.R_task_tip``: the live session fills
it); a sample without it is refused. Fixture: ``viscous`` guidance (the seed's law) along
the straight runs start → target 1 → … → target K, or ``none``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar, NamedTuple

import numpy as np

from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics.viscous import DEFAULT_TRANSITION, ViscousGuidance
from davinci_sim.tasks.base import Sample, Task, TaskError, TeleopSpec, common_to_dict
from davinci_sim.tasks.exercise_parts import (
    VisualBody,
    angle_between,
    fields_from_dict,
    points,
    positive,
    start_transitions,
    unit_rows,
    viewer_axes,
    world_points,
)
from davinci_sim.tasks.metrics import Metric, observed
from davinci_sim.tasks.schema import NONNEGATIVE, POINT, ListOf, Number
from davinci_sim.tasks.state import Phase
from davinci_sim.tasks.trainer import ECONOMY, TIME, Sum, trainer_metrics


class NeedleState(NamedTuple):
    """State of n trials, each (n,)."""

    phase: np.ndarray
    t_start: np.ndarray
    target: np.ndarray
    """Index of the current target (K when done), int."""
    inside: np.ndarray
    """The tip was inside the current target at the last sample."""
    hold_since: np.ndarray
    """Time the tool has been inside and aligned since, s (nan: not aligned)."""
    best: np.ndarray
    """Smallest angle to the current target's direction while inside, rad (inf before)."""


@dataclass(frozen=True)
class EventMean:
    """The mean of the observation ``value`` over the samples where ``event`` is 1 (nan
    without events)."""

    value: str
    event: str

    def init(self, n: int, task=None):
        return (np.zeros(n), np.zeros(n, dtype=np.int64))

    def add(self, acc, m, pair, task, prev, s, obs):
        e = m & (np.asarray(obs[self.event]) > 0)
        return (acc[0] + np.where(e, obs[self.value], 0.0), acc[1] + e)

    def final(self, acc, k, done):
        total, count = acc
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


TARGETS_HIT = Metric(
    "targets_hit", "1", "higher", "targets touched with the tool within the angle tolerance",
    Sum(observed("hit"), True), integer=True, label="targets hit",
)  # fmt: skip
ORIENTATION_ERROR = Metric(
    "orientation_error", "rad", "lower",
    "mean over the targets of the smallest angle between the tool's and the target's "
    "direction while touching it", EventMean("orientation_error", "done"),
    label="orientation error", display=("deg", 180.0 / math.pi),
)  # fmt: skip


@dataclass(frozen=True, eq=False)
class NeedleTargetingTask(Task, kind="needle_targeting"):
    """Touch each target with the required tool direction (see the module docstring)."""

    METRICS = (TIME, TARGETS_HIT, ORIENTATION_ERROR, ECONOMY,
               *trainer_metrics(leave_out=("drops",)))  # fmt: skip
    FILE_FIELDS: ClassVar[dict] = {
        "start": POINT,
        "targets": ListOf(POINT, min_items=1, what="points [x, y, z]"),
        "directions": ListOf(POINT, min_items=1, what="directions [x, y, z]"),
        "target_radius": Number(above=0.0),
        "angle_tolerance": Number(above=0.0, maximum=180.0),
        "dwell": NONNEGATIVE,
        "start_tolerance": Number(above=0.0),
    }
    FILE_REQUIRED = ("start", "targets", "directions")
    FIXTURE_TYPES = {"viscous": {"B", "G_max", "transition"}, "none": set()}
    DISTANCE_LABEL = "to the target"

    name: str
    start: np.ndarray
    """(3,) where the tool waits before a repetition, task frame, m."""
    targets: np.ndarray
    """(K, 3) the targets in order, task frame, m."""
    directions: np.ndarray
    """(K, 3) the direction the tool must point at each, as given (any length > 0)."""
    target_radius: float = 0.003
    angle_tolerance: float = 20.0
    """deg (the file's unit)."""
    dwell: float = 0.1
    """s the tool must stay inside and aligned for a hit."""
    start_tolerance: float = 0.003
    frame: str = "world"
    description: str = ""
    teleop: TeleopSpec = field(default_factory=TeleopSpec)
    fixture_spec: dict = field(default_factory=lambda: {"type": "none"})
    conditions: tuple[dict, ...] = ()
    walls: tuple[dict, ...] = ()
    scoring_spec: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = self.name
        object.__setattr__(self, "start", points(n, "start", self.start)[0])
        t = points(n, "targets", self.targets)
        unit_rows(self.directions, n, "directions")  # (checks them)
        d = points(n, "directions", self.directions)
        if len(d) != len(t):
            raise TaskError(f"task {n!r}: one direction per target ({len(t)}), got {len(d)}")
        object.__setattr__(self, "targets", t)
        object.__setattr__(self, "directions", d)
        for key in ("target_radius", "angle_tolerance", "start_tolerance"):
            positive(n, key, getattr(self, key))
        if not (0.0 <= float(self.dwell) < math.inf):
            raise TaskError(f"task {n!r}: dwell must be a number >= 0 (s)")
        if self.angle_tolerance > 180.0:
            raise TaskError(f"task {n!r}: angle_tolerance must be at most 180 deg")
        self.check()

    @property
    def SCORING(self) -> dict:  # noqa: N802 (the kind's declaration, from the geometry)
        """Scored: targets hit (weight 2; 100 % all, 0 % none), orientation error (2; 100 %
        at 0°, 0 % at the tolerance), missed targets (0 % all), time (100 % at 5 s per
        target, 0 % at 30 s per target), economy (100 % the sequence's length, 0 % 3x),
        collisions (0 % at 5), excessive force (5 s), out of view (the sequence's length),
        master workspace (3x the targets' box diagonal over the motion scale). The 100 %
        values are our choice until an expert reference of this kind exists."""
        K = len(self.targets)
        L = self.sequence.length
        span = float(np.linalg.norm(np.ptp(np.vstack([self.start, self.targets]), axis=0)))
        return {
            "metrics": {
                "targets_hit": {"weight": 2.0, "fail": 0.0, "expert": float(K)},
                "orientation_error": {
                    "weight": 2.0,
                    "fail": math.radians(self.angle_tolerance),
                    "expert": 0.0,
                },  # fmt: skip
                "missed_targets": {"weight": 1.0, "fail": float(K), "expert": 0.0},
                "completion_time": {"weight": 1.0, "fail": 30.0 * K, "expert": 5.0 * K},
                "path_length": {"weight": 1.0, "fail": 3.0 * L, "expert": L},
                "instrument_collisions": {"weight": 1.0, "fail": 5.0, "expert": 0.0},
                "excessive_force": {"weight": 1.0, "fail": 5.0, "expert": 0.0},
                "out_of_view": {"weight": 1.0, "fail": L, "expert": 0.0},
                "master_workspace": {
                    "weight": 1.0,
                    "fail": 3.0 * span / self.teleop.scale,
                    "expert": span / self.teleop.scale,
                },  # fmt: skip
            }
        }

    # ------------------------------------------------------------ geometry
    @cached_property
    def unit_directions(self) -> np.ndarray:
        """(K, 3) :attr:`directions` as unit vectors."""
        return unit_rows(self.directions, self.name, "directions")

    @cached_property
    def sequence(self) -> Polyline:
        """The straight runs start → target 1 → … → target K, task frame, m."""
        return Polyline(np.vstack([self.start, self.targets]))

    @property
    def view_points(self) -> np.ndarray:
        return np.vstack([self.start, self.targets])

    @property
    def view_directions(self) -> np.ndarray:
        """(k, 3) the tool direction each view point needs (None rows: any), for the
        reachability check: the start none (nan), each target its direction."""
        return np.vstack([np.full(3, np.nan), self.unit_directions])

    # ------------------------------------------------------------ Task
    def draw(self, spec, *, T_world_camera=None, prefix: str = "task/"):
        """The start (green), each target as a translucent sphere of ``target_radius``
        with its number and a stem along the required direction: the tool comes in along
        the stem (from −direction), pointing at the target."""
        body = VisualBody(spec.worldbody, "needle_targeting", prefix)
        T = None if self.frame == "world" else np.asarray(T_world_camera, dtype=float)
        start = world_points(self, self.start, T_world_camera)[0]
        targets = world_points(self, self.targets, T_world_camera)
        u = self.unit_directions
        dirs = u if T is None else u @ T[:3, :3].T
        body.sphere("start", start, 0.0018, (0.2, 0.9, 0.3, 1.0))
        right, up = viewer_axes(T_world_camera)
        for k, (p, d) in enumerate(zip(targets, dirs, strict=True), start=1):
            body.sphere(f"target{k}", p, self.target_radius, (0.1, 0.6, 1.0, 0.45))
            body.sphere(f"centre{k}", p, 0.0007, (1.0, 0.85, 0.1, 1.0))
            body.capsule(f"stem{k}", p - 0.015 * d, p - self.target_radius * d, 0.0006,
                         (1.0, 0.85, 0.1, 1.0))  # fmt: skip
            origin = p + (self.target_radius + 0.001) * (right + up) / np.sqrt(2)
            body.number("label", k, origin, right, up, 0.005, (1.0, 0.85, 0.1, 1.0))
        return body.body

    def initial_state(self, n: int) -> NeedleState:
        return NeedleState(
            np.full(n, Phase.IDLE, dtype=np.int8), np.full(n, np.nan),
            np.zeros(n, dtype=np.int64), np.zeros(n, dtype=bool), np.full(n, np.nan),
            np.full(n, np.inf),
        )  # fmt: skip

    def step(self, state: NeedleState, sample: Sample):
        """Observations: ``distance`` to the current target (m), ``hit``, ``missed`` and
        ``done`` (1 at the sample a target is hit, missed, either), ``orientation_error``
        (rad, the target's smallest angle, at those samples)."""
        if sample.R_task_tip is None:
            raise ValueError(f"task {self.name!r} needs the tool's orientation "
                             "(Sample.R_task_tip)")  # fmt: skip
        K = len(self.targets)
        tip, t = sample.tip, sample.time
        phase, begin = start_transitions(state.phase, self.at_start(tip))
        running = state.phase == Phase.RUNNING
        k = np.minimum(state.target, K - 1)
        d = np.linalg.norm(tip - self.targets[k], axis=1)
        inside = running & (state.target < K) & (d <= self.target_radius)
        angle = angle_between(sample.R_task_tip[:, :, 2], self.unit_directions[k])
        best = np.where(inside, np.minimum(state.best, angle), state.best)
        aligned = inside & (angle <= math.radians(self.angle_tolerance))
        hold = np.where(aligned, np.where(np.isnan(state.hold_since), t, state.hold_since),
                        np.nan)  # fmt: skip
        hit = aligned & (t - hold >= self.dwell)
        missed = running & state.inside & ~inside & ~hit
        done = hit | missed
        target = state.target + done
        phase[running & (target >= K)] = Phase.FINISHED
        new = NeedleState(
            phase,
            np.where(begin, t, state.t_start),
            np.where(begin, 0, target),
            np.where(done | begin, False, inside),
            np.where(done | begin, np.nan, hold),
            np.where(done | begin, np.inf, best),
        )
        obs = {
            "distance": d,
            "hit": hit.astype(np.int64),
            "missed": missed.astype(np.int64),
            "done": done.astype(np.int64),
            "orientation_error": np.where(done, best, 0.0),
        }
        return new, obs

    def progress(self, state) -> str:
        """``touch target k of K`` while running."""
        if int(state.phase[0]) not in (Phase.RUNNING, Phase.FINISHED):
            return ""
        k = min(int(state.target[0]) + 1, len(self.targets))
        return f"touch target {k} of {len(self.targets)}"

    def at_start(self, tip) -> np.ndarray:
        p = np.asarray(tip, dtype=float).reshape(-1, 3)
        return np.linalg.norm(p - self.start, axis=1) <= self.start_tolerance

    def distance(self, tip) -> np.ndarray:
        """Distance to the nearest target, m (the session's between repetitions)."""
        p = np.asarray(tip, dtype=float).reshape(-1, 3)
        return np.linalg.norm(p[:, None] - self.targets[None], axis=2).min(axis=1)

    def summary(self, row: dict) -> str:
        err = row["orientation_error"]
        shown = "n/a" if not math.isfinite(err) else f"{math.degrees(err):.1f}°"
        return (f"{row['targets_hit']}/{len(self.targets)} hit, orientation error {shown}, "
                f"{row['completion_time']:.1f} s; back to the start for the next")  # fmt: skip

    # ------------------------------------------------------------ fixture
    def guidance(self, spec: dict, path: Polyline | None = None):
        """Viscous guidance along :attr:`sequence` (or ``path``), or None."""
        if spec.get("type", "none") != "viscous":
            return None
        params = {k: float(v) for k, v in spec.items() if k not in ("type", "name")}
        params.setdefault("transition", DEFAULT_TRANSITION)
        return ViscousGuidance(self.sequence if path is None else path, **params)

    # ------------------------------------------------------------ I/O
    _OWN = ("start", "targets", "directions", "target_radius", "angle_tolerance", "dwell",
            "start_tolerance")  # fmt: skip

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> NeedleTargetingTask:
        return cls(**fields_from_dict(data, cls._OWN, ("start", "targets", "directions")))

    def to_dict(self) -> dict[str, Any]:
        out = common_to_dict(self)
        out.update({
            "start": self.start.tolist(), "targets": self.targets.tolist(),
            "directions": self.directions.tolist(), "target_radius": self.target_radius,
            "angle_tolerance": self.angle_tolerance, "dwell": self.dwell,
            "start_tolerance": self.start_tolerance,
        })  # fmt: skip
        return out
