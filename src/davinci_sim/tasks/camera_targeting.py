"""Camera targeting: move the endoscope to centre a series of targets at the right distance
— the ``camera_targeting`` kind.

The operator moves the camera with the console's camera pedal and both masters (the ECM
teleoperation, :mod:`davinci_sim.console.teleop_ecm`); the instruments stay where they
are. Targets come one at a time, in order. With the camera (the ECM tip frame, between the
two stereo cameras: x to the image's left, y up, z along the view) at ``T_task_camera``,
target k at ``p`` is seen at p_c = T_task_camera⁻¹·p: its **off-axis angle**
atan2(√(x_c² + y_c²), z_c) (0: the image centre) and its **depth** z_c. It is *acquired*
when the angle stays within ``centre_tolerance`` (deg) and the depth within
``depth ± depth_tolerance`` (m) for ``dwell`` seconds; then the next target comes.

States::

    IDLE ──the camera still (moved < still_step between two samples)──> READY
    READY ──the camera moves start_motion (m, or the same in rad of its view axis)
            away from where it was at READY──> RUNNING (t_start)
    RUNNING ──last target acquired──> FINISHED ──> RESULTS

so the clock starts with the first camera motion, not while a session frames the view.
Between repetitions the camera stays where it is: the next repetition starts with target 1
as soon as the camera is still (:meth:`at_start` is true wherever the tool is).

Metrics: ``completion_time`` (s), ``targets_acquired`` (1, higher is better),
``camera_path_length`` (m, shown in cm: Σ‖c_i − c_{i−1}‖ of the camera's position), plus
the trainer metrics that apply to an instrument held still while the camera moves:
economy of the instrument (``path_length``), collisions, excessive force, instruments out
of view (the view moves), master workspace; no objects (drops) and no target can be
missed (one at a time, each until acquired), so those two are left out.

The sample must carry the camera pose (``Sample.T_task_camera``, filled by the live
session); a sample without it is refused.

**Fixture: none.** The camera is moved with both hands in the ECM teleoperation, whose only
force is its own spring keeping the hands' relative placement
(:func:`~davinci_sim.console.camera_control.hands_force`); the haptic loop's task fixture
acts on the task's one MTM as a function of its PSM's tool tip, which this exercise keeps
still, so a guidance field there would not guide the camera.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar, NamedTuple

import numpy as np

from davinci_sim.tasks.base import Sample, Task, TeleopSpec, common_to_dict
from davinci_sim.tasks.exercise_parts import (
    VisualBody,
    fields_from_dict,
    points,
    positive,
    viewer_axes,
    world_points,
)
from davinci_sim.tasks.metrics import Metric, PairSum
from davinci_sim.tasks.schema import NONNEGATIVE, POINT, ListOf, Number
from davinci_sim.tasks.state import Phase
from davinci_sim.tasks.trainer import ECONOMY, TIME, Sum, trainer_metrics


class CameraState(NamedTuple):
    """State of n trials, each (n,) (``p_ready``, ``z_ready``: (n, 3))."""

    phase: np.ndarray
    t_start: np.ndarray
    target: np.ndarray
    """Index of the current target (K when done), int."""
    hold_since: np.ndarray
    """Time the current target has been centred since, s (nan: not centred)."""
    p_last: np.ndarray
    """The camera's position at the last sample, task frame, m (nan before)."""
    p_ready: np.ndarray
    """The camera's position when READY, m."""
    z_ready: np.ndarray
    """The camera's view axis when READY (unit)."""


def target_in_camera(T_task_camera: np.ndarray, p_task: np.ndarray) -> np.ndarray:
    """(n, 3) the points ``p_task`` (n, 3) in the cameras ``T_task_camera`` (n, 4, 4), m."""
    R = T_task_camera[:, :3, :3]
    d = p_task - T_task_camera[:, :3, 3]
    return np.einsum("nji,nj->ni", R, d)  # Rᵀ·(p − t)


def off_axis_angle(p_camera: np.ndarray) -> np.ndarray:
    """(n,) angle between the view axis (z) and the camera-frame points (n, 3), rad."""
    return np.arctan2(np.hypot(p_camera[:, 0], p_camera[:, 1]), p_camera[:, 2])


def _camera_step(task, prev, s, obs):
    return np.linalg.norm(s.T_task_camera[:, :3, 3] - prev.T_task_camera[:, :3, 3], axis=1)


def _acquired(task, s, obs):
    return np.asarray(obs["acquired"], dtype=np.int64)


TARGETS_ACQUIRED = Metric(
    "targets_acquired", "1", "higher", "targets centred at the right distance for the dwell",
    Sum(_acquired, True), integer=True, label="targets acquired",
)  # fmt: skip
CAMERA_PATH_LENGTH = Metric(
    "camera_path_length", "m", "lower", "length of the camera's trajectory (its economy)",
    PairSum(_camera_step), label="camera path", display=("cm", 100.0),
    needs=("T_task_camera",),
)  # fmt: skip


@dataclass(frozen=True, eq=False)
class CameraTargetingTask(Task, kind="camera_targeting"):
    """Centre each target in the endoscope's view at the right depth (module docstring)."""

    METRICS = (TIME, TARGETS_ACQUIRED, CAMERA_PATH_LENGTH, ECONOMY,
               *trainer_metrics(leave_out=("drops", "missed_targets")))  # fmt: skip
    FILE_FIELDS: ClassVar[dict] = {
        "start": POINT,
        "targets": ListOf(POINT, min_items=1, what="points [x, y, z]"),
        "depth": Number(above=0.0),
        "depth_tolerance": Number(above=0.0),
        "centre_tolerance": Number(above=0.0, maximum=90.0),
        "dwell": NONNEGATIVE,
        "start_motion": Number(above=0.0),
        "still_step": Number(above=0.0),
        "marker_radius": Number(above=0.0),
    }
    FILE_REQUIRED = ("start", "targets")
    FIXTURE_TYPES = {"none": set()}

    name: str
    start: np.ndarray
    """(3,) where the tool waits, in view (the session brings it there), task frame, m."""
    targets: np.ndarray
    """(K, 3) the targets in order, task frame, m."""
    depth: float = 0.09
    """The right distance: the target's depth in the camera frame, m."""
    depth_tolerance: float = 0.015
    centre_tolerance: float = 4.0
    """Off-axis angle within which a target is centred, deg (the image's half-height is
    22.5°)."""
    dwell: float = 0.3
    start_motion: float = 0.002
    """Camera motion that starts the clock, m (the view axis turning by start_motion/0.1
    rad counts as much)."""
    still_step: float = 2e-6
    """Largest camera step between samples at which it is still, m (2 mm/s at 1 kHz)."""
    marker_radius: float = 0.003
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
        object.__setattr__(self, "targets", points(n, "targets", self.targets))
        for key in ("depth", "depth_tolerance", "centre_tolerance", "start_motion",
                    "still_step", "marker_radius"):  # fmt: skip
            positive(n, key, getattr(self, key))
        if not 0.0 <= float(self.dwell) < math.inf:
            positive(n, "dwell", self.dwell)
        self.check()

    @property
    def SCORING(self) -> dict:  # noqa: N802 (the kind's declaration, from the geometry)
        """Scored: targets acquired (weight 2; 100 % all, 0 % none), time (100 % at 3 s per
        target, 0 % at 30 s), camera path (100 % the straight runs between the targets: the
        camera, nearer the ECM's RCM than they are, needs less; 0 % 4x), instrument
        economy (0 % at 5 cm: it should stay still), collisions (5), excessive force (5 s),
        out of view (5 cm), master workspace (0 % at 30 cm). The 100 % values are our
        choice until an expert reference exists."""
        K = len(self.targets)
        runs = float(np.linalg.norm(np.diff(self.targets, axis=0), axis=1).sum())
        return {
            "metrics": {
                "targets_acquired": {"weight": 2.0, "fail": 0.0, "expert": float(K)},
                "completion_time": {"weight": 1.0, "fail": 30.0 * K, "expert": 3.0 * K},
                "camera_path_length": {
                    "weight": 1.0,
                    "fail": 4.0 * max(runs, 0.01),
                    "expert": runs,
                },  # fmt: skip
                "path_length": {"weight": 1.0, "fail": 0.05, "expert": 0.0},
                "instrument_collisions": {"weight": 1.0, "fail": 5.0, "expert": 0.0},
                "excessive_force": {"weight": 1.0, "fail": 5.0, "expert": 0.0},
                "out_of_view": {"weight": 1.0, "fail": 0.05, "expert": 0.0},
                "master_workspace": {"weight": 1.0, "fail": 0.30, "expert": 0.05},
            }
        }

    # ------------------------------------------------------------ geometry
    @property
    def view_points(self) -> np.ndarray:
        """The tool's start: framing it shows the instrument (the targets are to be found)."""
        return self.start.reshape(1, 3)

    @property
    def camera_targets(self) -> np.ndarray:
        """(K, 3) points the ECM must be able to centre at :attr:`depth` (the check)."""
        return self.targets

    # ------------------------------------------------------------ Task
    def draw(self, spec, *, T_world_camera=None, prefix: str = "task/"):
        """Each target as a numbered orange sphere inside a thin ring facing the endoscope
        of ``T_world_camera``; the tool's start as a small green sphere."""
        body = VisualBody(spec.worldbody, "camera_targeting", prefix)
        right, up = viewer_axes(T_world_camera)
        facing = np.cross(right, up)
        body.sphere("start", world_points(self, self.start, T_world_camera)[0], 0.0015,
                    (0.2, 0.9, 0.3, 1.0))  # fmt: skip
        r = self.marker_radius
        rgba = (1.0, 0.55, 0.1, 1.0)
        for k, p in enumerate(world_points(self, self.targets, T_world_camera), start=1):
            body.sphere(f"target{k}", p, r, rgba)
            body.ring(f"ring{k}_", p, facing, 2.2 * r, 0.0004, rgba)
            body.number("label", k, p + 2.6 * r * (right + up) / np.sqrt(2), right, up,
                        2.5 * r, rgba)  # fmt: skip
        return body.body

    def initial_state(self, n: int) -> CameraState:
        nan3 = np.full((n, 3), np.nan)
        return CameraState(
            np.full(n, Phase.IDLE, dtype=np.int8), np.full(n, np.nan),
            np.zeros(n, dtype=np.int64), np.full(n, np.nan), nan3, nan3.copy(), nan3.copy(),
        )  # fmt: skip

    def step(self, state: CameraState, sample: Sample):
        """Observations: ``distance`` of the current target to the view axis's point at
        :attr:`depth` (m, 0 when perfectly placed), its ``off_axis`` angle (rad) and
        ``depth`` (m), ``acquired`` (1 at the sample it is)."""
        T = sample.T_task_camera
        if T is None:
            raise ValueError(f"task {self.name!r} needs the camera pose (Sample.T_task_camera)")
        K = len(self.targets)
        t = sample.time
        c, z = T[:, :3, 3], T[:, :3, 2]
        phase = state.phase.copy()
        step = np.linalg.norm(c - state.p_last, axis=1)
        still = np.isfinite(step) & (step <= self.still_step)
        ready = (state.phase == Phase.IDLE) & still
        phase[ready] = Phase.READY
        p_ready = np.where(ready[:, None], c, state.p_ready)
        z_ready = np.where(ready[:, None], z, state.z_ready)
        moved = np.linalg.norm(c - p_ready, axis=1)
        turned = 0.1 * np.arccos(np.clip(np.einsum("ni,ni->n", z, z_ready), -1.0, 1.0))
        begin = (state.phase == Phase.READY) & (np.maximum(moved, turned) > self.start_motion)
        phase[begin] = Phase.RUNNING
        phase[state.phase == Phase.FINISHED] = Phase.RESULTS
        running = state.phase == Phase.RUNNING
        k = np.minimum(state.target, K - 1)
        p_c = target_in_camera(T, self.targets[k])
        angle = off_axis_angle(p_c)
        placed = (angle <= math.radians(self.centre_tolerance)) & (
            np.abs(p_c[:, 2] - self.depth) <= self.depth_tolerance
        )
        on = running & (state.target < K) & placed
        hold = np.where(on, np.where(np.isnan(state.hold_since), t, state.hold_since), np.nan)
        acquired = on & (t - hold >= self.dwell)
        target = state.target + acquired
        phase[running & (target >= K)] = Phase.FINISHED
        new = CameraState(
            phase,
            np.where(begin, t, state.t_start),
            np.where(begin, 0, target),
            np.where(acquired | begin, np.nan, hold),
            c.copy(),
            p_ready,
            z_ready,
        )
        ideal = p_c - np.array([0.0, 0.0, self.depth])
        obs = {
            "distance": np.linalg.norm(ideal, axis=1),
            "off_axis": angle,
            "depth": p_c[:, 2],
            "acquired": acquired.astype(np.int64),
        }
        return new, obs

    def progress(self, state) -> str:
        """``centre target k of K`` while running."""
        if int(state.phase[0]) not in (Phase.RUNNING, Phase.FINISHED):
            return ""
        k = min(int(state.target[0]) + 1, len(self.targets))
        return f"centre target {k} of {len(self.targets)}"

    def at_start(self, tip) -> np.ndarray:
        """True wherever the tool is: the exercise is the camera's (see the docstring)."""
        return np.ones(len(np.asarray(tip, dtype=float).reshape(-1, 3)), dtype=bool)

    def distance(self, tip) -> np.ndarray:
        """nan: the distance is the camera's to its target, not the tool's (:meth:`step`)."""
        return np.full(len(np.asarray(tip, dtype=float).reshape(-1, 3)), np.nan)

    def summary(self, row: dict) -> str:
        return (f"{row['targets_acquired']}/{len(self.targets)} targets in "
                f"{row['completion_time']:.1f} s, camera path "
                f"{100 * row['camera_path_length']:.1f} cm; hold the camera still for the "
                "next")  # fmt: skip

    # ------------------------------------------------------------ I/O
    _OWN = ("start", "targets", "depth", "depth_tolerance", "centre_tolerance", "dwell",
            "start_motion", "still_step", "marker_radius")  # fmt: skip

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CameraTargetingTask:
        return cls(**fields_from_dict(data, cls._OWN, ("start", "targets")))

    def to_dict(self) -> dict[str, Any]:
        out = common_to_dict(self)
        out.update({k: getattr(self, k) for k in self._OWN})
        out["start"], out["targets"] = self.start.tolist(), self.targets.tolist()
        return out
