"""Needle driving and the running suture: pick the curved needle out of its park and
drive it through the suture pad's entry and exit marks in order (kind ``needle_drive``).

A task file with one pair of marks is the needle-driving exercise; with four, the running
suture. The scene is needle pick-up's (:mod:`davinci_sim.tasks.needle_pickup`) with a
suture pad beside the park (:mod:`davinci_sim.tasks.suture_pad`): a skin that the jaws
dent, marks on it, and the needle's passage read from geometry.

**What is observed each tick**: the needle's centre and grasp (as for pick-up), its frame
(``Sample.T_task_object``), every instrument's tip, and the instruments' normal force on
the skin (``Sample.tissue_force``, N). A *pass* of a pair is the needle's point entering
the skin within ``mark_radius`` of the pair's entry mark and coming out within it of the
exit mark (:func:`~davinci_sim.tasks.suture_pad.passage_step`); the pairs are passed in
order (a pass of another pair does not count).

**States**: IDLE → READY when the needle rests in its park; READY → RUNNING when it is
first held; RUNNING → FINISHED when every pair is passed or ``time_limit`` has run out
(each pair not passed a missed target); then RESULTS.

**Metrics**: time, economy over every instrument, passes, the worst entry and exit errors
(m, shown in mm), tissue trauma (the peak distance of an entry point from the needle's
circle while the point is in the tissue, m, shown in mm), the peak force of the
instruments on the tissue (N), and the trainer metrics (drops, missed pairs, collisions,
excessive force, out of view, master workspace).

**Guidance** (a fixture of the user's, :meth:`NeedleDriveTask.guidance`): any guidance
kind of :mod:`davinci_sim.haptics.kinds` but the adaptive (its B follows a path metric)
along :meth:`NeedleDriveTask.drive_path`, the path the driving instrument's tool tip takes
as it turns the needle along its own curve through each pair (the drive of the scripted
expert, :mod:`davinci_sim.study.experts`), on the task's MTM.

What the simulation does not do yet: the tissue does not hold the needle (the needle does
not collide with the skin), so a needle let go in the tissue falls through it (a drop).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any, ClassVar, NamedTuple

import numpy as np

from davinci_sim.kinematics.jit import kernel_array
from davinci_sim.model.psm import JAW_LENGTH
from davinci_sim.tasks.base import Sample, TaskError
from davinci_sim.tasks.metrics import Metric, Peak, observed
from davinci_sim.tasks.needle_pickup import NeedlePickupTask, _kernel_state
from davinci_sim.tasks.needle_row import drive_rows
from davinci_sim.tasks.peg import ECONOMY_ALL
from davinci_sim.tasks.schema import ListOf, Number, Vector
from davinci_sim.tasks.state import Phase
from davinci_sim.tasks.suture_pad import Passage, SuturePad, no_passage, passage_step
from davinci_sim.tasks.trainer import TIME, Sum, trainer_metrics


def _tissue_force(task, s, obs):
    return np.asarray(s.tissue_force, dtype=float)


#: The drive of :meth:`NeedleDriveTask.drive_path` (and of the scripted expert): the
#: needle's plane tilted from the vertical about the line between the marks towards the
#: instruments (rad; the needle driver's jaws along its normal are then 45° off the
#: vertical, in reach of the PSM's wrist from its shaft), turned about its centre from
#: :data:`DRIVE_START` to :data:`DRIVE_OUT` (rad, :func:`~davinci_sim.tasks.suture_pad.
#: drive_pose`'s angles: the point 3 mm above the skin before the entry mark, then out
#: past the exit, 15° past level), held by the needle driver at :data:`DRIVE_GRIP` of its
#: length from the swage, the wire :data:`DRIVE_GRIP_DEPTH` m into the jaws from their
#: pivot, 1.5 mm of jaw past it. 6 mm into the 10 mm jaws, the 4 mm past the wire, pointing
#: 45° down along the plane's normal, pressed on the skin for the last ~60° of the turn
#: (measured: up to 20 N on one jaw, PSM1's wrist pitch pushed 0.37 rad off its setpoint,
#: a tracking fault).
DRIVE_TILT = math.radians(45.0)
DRIVE_START, DRIVE_OUT = 0.0, math.radians(205.0)
DRIVE_GRIP, DRIVE_GRIP_DEPTH = 0.12, JAW_LENGTH - 0.0015
#: Vertices of :meth:`NeedleDriveTask.drive_path` per pair (5° apart).
DRIVE_PATH_POINTS = 42

MM = ("mm", 1e3)
PASSES = Metric(
    "passes", "1", "higher", "pairs of marks the needle was driven through, in order",
    Sum(observed("passes"), True), integer=True,
)  # fmt: skip
ENTRY_ERROR = Metric(
    "entry_error", "m", "lower", "largest distance of an entry of the needle's point from its mark",
    Peak(observed("entry_error", float)), report=MM, display=MM,
)  # fmt: skip
EXIT_ERROR = Metric(
    "exit_error", "m", "lower", "largest distance of an exit of the needle's point from its mark",
    Peak(observed("exit_error", float)), report=MM, display=MM,
)  # fmt: skip
TRAUMA = Metric(
    "tissue_trauma", "m", "lower",
    "peak distance of an entry point from the needle's circle while in the tissue",
    Peak(observed("trauma", float)), report=MM, display=MM,
)  # fmt: skip
TISSUE_FORCE = Metric(
    "tissue_force", "N", "lower", "peak normal force of the instruments on the tissue",
    Peak(_tissue_force), needs=("tissue_force",), report=("N", 1.0),
)  # fmt: skip


class DriveState(NamedTuple):
    """n trials: (n,) arrays (``p_prev`` (n, 3)); ``passage`` the needle's passage."""

    phase: np.ndarray
    t_start: np.ndarray
    t_finish: np.ndarray
    t_prev: np.ndarray
    p_prev: np.ndarray
    t_still: np.ndarray
    owner: np.ndarray
    carried: np.ndarray
    handed: np.ndarray
    loose: np.ndarray
    next_pair: np.ndarray
    """The pair to pass next (= pairs passed)."""
    passage: Passage


@dataclass(frozen=True, eq=False)
class NeedleDriveTask(NeedlePickupTask, kind="needle_drive"):
    """Needle driving through the suture pad's marks (see the module docstring)."""

    METRICS = (TIME, ECONOMY_ALL, PASSES, ENTRY_ERROR, EXIT_ERROR, TRAUMA, TISSUE_FORCE,
               *trainer_metrics())  # fmt: skip
    FILE_FIELDS: ClassVar[dict] = {
        **NeedlePickupTask.FILE_FIELDS,
        "pad_center": Vector(2, "x, y"),
        "pad_top": Number(),
        "pad_yaw": Number(),
        "pairs": ListOf(
            ListOf(Vector(2, "x, y"), min_items=2),
            min_items=1,
            what="[[entry x, y], [exit x, y]] pairs (pad frame, m)",
        ),  # fmt: skip
        "mark_radius": Number(above=0.0),
    }
    FILE_REQUIRED = ("park_center", "park_top", "pad_center", "pad_top", "pairs")
    #: The needle is what the jaws hold: not a collision. The skin, what they work on, is
    #: not one either (a flex: ``InstrumentContacts`` leaves its contacts out); the pad's
    #: firm base is.
    CONTACT_IGNORE = ("task/needle",)

    pad_center: tuple[float, float] = (0.0, 0.0)
    pad_top: float = 0.0
    pad_yaw: float = 0.0
    pairs: tuple = (((-0.007, 0.0), (0.007, 0.0)),)
    mark_radius: float = 0.0025
    time_limit: float = 180.0

    def __post_init__(self) -> None:
        center = tuple(float(x) for x in self.pad_center)
        if len(center) != 2:
            raise TaskError(f"task {self.name!r}: pad_center must be [x, y] (m)")
        object.__setattr__(self, "pad_center", center)
        try:
            pairs = tuple(tuple((float(a[0]), float(a[1])) for a in pair) for pair in self.pairs)
            if any(len(pair) != 2 for pair in pairs):
                raise ValueError("a pair is [[entry x, y], [exit x, y]]")
            object.__setattr__(self, "pairs", pairs)
        except (TypeError, ValueError, IndexError) as e:
            raise TaskError(f"task {self.name!r}: pairs: {e}") from e
        try:
            self.pad  # noqa: B018 (built to check it)
        except ValueError as e:
            raise TaskError(f"task {self.name!r}: {e}") from e
        for k, (entry, exit_) in enumerate(pairs):
            if math.dist(entry, exit_) >= 2 * float(self.needle_radius):
                raise TaskError(f"task {self.name!r}: pairs: pair {k}'s marks are farther "
                                "apart than the needle's diameter")  # fmt: skip
        super().__post_init__()

    @cached_property
    def pad(self) -> SuturePad:
        return SuturePad(self.pad_center, float(self.pad_top), float(self.pad_yaw),
                         pairs=self.pairs, mark_radius=float(self.mark_radius))  # fmt: skip

    @cached_property
    def T_pad_world(self) -> np.ndarray:
        return np.linalg.inv(self.pad.T_world_pad)

    @property
    def SCORING(self) -> dict:  # noqa: N802 (the kind's declaration)
        """Time (100 % at 20 s a pair, 0 % at the time limit), missed pairs (weight 2),
        entry and exit errors (100 % at 0.5 mm, 0 % at the 2.5 mm mark radius), trauma
        (100 % at 0.5 mm, 0 % at 3 mm), tissue force (100 % at 0.5 N, 0 % at 3 N), drops,
        collisions, economy (100 % at 15 cm a pair, 0 % at 80 cm a pair). Our assumptions
        until an expert reference is shipped."""
        k = len(self.pairs)
        t_fail = self.time_limit if self.time_limit > 0 else 90.0 * k
        return {
            "metrics": {
                "completion_time": {"weight": 1.0, "fail": t_fail, "expert": 20.0 * k},
                "missed_targets": {"weight": 2.0, "fail": float(k), "expert": 0.0},
                "entry_error": {"weight": 1.0, "fail": self.mark_radius, "expert": 0.0005},
                "exit_error": {"weight": 1.0, "fail": self.mark_radius, "expert": 0.0005},
                "tissue_trauma": {"weight": 1.0, "fail": 0.003, "expert": 0.0005},
                "tissue_force": {"weight": 1.0, "fail": 3.0, "expert": 0.5},
                "drops": {"weight": 1.0, "fail": 2.0, "expert": 0.0},
                "instrument_collisions": {"weight": 1.0, "fail": 10.0, "expert": 0.0},
                "path_length": {"weight": 1.0, "fail": 0.8 * k, "expert": 0.15 * k},
            }
        }

    @property
    def view_points(self) -> np.ndarray:
        """The needle in its park, and the pad's marks just above the skin."""
        marks = self.pad.marks_world().reshape(-1, 3) + [0.0, 0.0, 0.002]
        return np.vstack([super().view_points[:3], marks])

    @property
    def check_points(self) -> np.ndarray:
        """The needle's top and every mark."""
        return self.view_points[1:]

    # ------------------------------------------------------------ guidance
    @cached_property
    def drive_path(self):
        """The driving instrument's tool tip (its jaws' pivot, world, m) as it drives the
        needle through each pair in turn (see :data:`DRIVE_TILT`): a circle about the
        needle's centre, one arc per pair, joined by straight lines from one pair's exit to
        the next pair's start (above the skin). A :class:`~davinci_sim.geometry.path.
        Polyline`."""
        from davinci_sim.geometry.path import Polyline
        from davinci_sim.tasks.suture_pad import drive_pose

        s = self.needle.points(DRIVE_GRIP)
        points = []
        for k in range(len(self.pairs)):
            for a in np.linspace(DRIVE_START, DRIVE_OUT, DRIVE_PATH_POINTS):
                T = drive_pose(self.pad, k, self.needle, float(a), DRIVE_TILT)
                # (the jaws along the needle's normal, their tips down: the pivot above)
                z = T[:3, 2] if T[2, 2] < 0.0 else -T[:3, 2]
                points.append(T[:3, :3] @ s + T[:3, 3] - DRIVE_GRIP_DEPTH * z)
        return Polyline(np.array(points))

    def fixture_keys(self, kind: str) -> set[str] | None:
        """Any guidance kind of :mod:`davinci_sim.haptics.kinds` (built in, registered, or
        an importable ``module:Name``) but ``adaptive``, along :attr:`drive_path`."""
        from davinci_sim.haptics.kinds import fixture_kind

        if kind == "adaptive":
            raise KeyError("an adaptive fixture follows a path task's deviation; a needle "
                           "drive offers the other kinds along its drive path")  # fmt: skip
        k = fixture_kind(kind)  # KeyError: no such kind
        return None if k.params is None else set(k.params)

    def guidance(self, spec: dict):
        """The guidance of ``spec`` along :attr:`drive_path` (None for ``none``)."""
        from davinci_sim.haptics.kinds import build_fixture

        return build_fixture(spec, self.drive_path)

    # ------------------------------------------------------------ Task
    def draw(self, spec, *, T_world_camera=None, prefix: str = "task/"):
        """Needle pick-up's park and needle, and the suture pad."""
        from davinci_sim.tasks.suture_pad import add_suture_pad

        body = super().draw(spec, T_world_camera=T_world_camera, prefix=prefix)
        add_suture_pad(spec, self.pad, prefix)
        return body

    def probe(self, model, prefix: str = "task/"):
        """The needle's :class:`~davinci_sim.tasks.needle_scene.NeedleProbe` of ``model``,
        its readings with the normal force of the contacts with the skin (the flex
        ``<prefix>pad_skin``)."""
        from davinci_sim.tasks.needle_scene import NeedleProbe

        return NeedleProbe(model, self.instruments, prefix, flex=f"{prefix}pad_skin")

    def reset_scene(self, model, data) -> None:
        """The needle back in its park, the skin at rest."""
        from davinci_sim.tasks.suture_pad import reset_pad

        reset_pad(model, data)
        super().reset_scene(model, data)

    def objects_fields(self, reading, model, data, cache: dict) -> dict:
        """Needle pick-up's fields and the instruments' normal force on the tissue (the
        reading's force on the skin, N)."""
        fields = super().objects_fields(reading, model, data, cache)
        fields["tissue_force"] = float(reading.flex_force)
        return fields

    def initial_state(self, n: int) -> DriveState:
        s = super().initial_state(n)
        return DriveState(*s[:10], np.zeros(n, dtype=np.int64), no_passage(n))

    def step(self, state: DriveState, sample: Sample):
        """One sample of n trials (pure; see the module docstring). Observations:
        ``distance`` (tip to the needle's centre, m), ``handoffs``, ``dropped``, ``passes``
        (1 at a pass of the next pair), ``entry_error``, ``exit_error``, ``trauma`` (m, at
        the sample of an exit, else 0), ``missed`` (the pairs not passed, at the sample
        that finishes). One compiled call (:func:`~davinci_sim.tasks.needle_row.drive_rows`);
        :meth:`step_arrays` is the same in numpy."""
        if sample.T_task_object is None:
            raise ValueError(f"task {self.name!r} needs the sample's objects, grasp and "
                             "T_task_object (NeedleDriveTask.scene_fields)")  # fmt: skip
        t, objects, grasp, tip = self._sample_arrays(sample)
        n = len(t)
        T_pad_needle = kernel_array(np.reshape(self.T_pad_world @ sample.T_task_object,
                                               (n, 4, 4)))  # fmt: skip
        passage = Passage(*(np.array(a, dtype=dtype, order="C") for a, dtype in  # (copies)
                            zip(state.passage, (bool, np.int64, float, float, float, float),
                                strict=True)))  # fmt: skip
        new = DriveState(np.empty(n, dtype=np.int8), np.empty(n), np.empty(n), t,
                         objects.copy(), np.empty(n), np.empty(n, dtype=np.int64),
                         np.empty(n, dtype=bool), np.empty(n, dtype=bool),
                         np.empty(n, dtype=bool), np.empty(n, dtype=np.int64),
                         passage)  # fmt: skip
        obs = {"distance": np.empty(n), "handoffs": np.empty(n, dtype=np.int64),
               "dropped": np.empty(n, dtype=np.int64), "passes": np.empty(n, dtype=np.int64),
               "entry_error": np.empty(n), "exit_error": np.empty(n), "trauma": np.empty(n),
               "missed": np.empty(n, dtype=np.int64)}  # fmt: skip
        tip_point, marks, (half_x, half_y) = self._passage_constants
        drive_rows(self._start_point, float(self.park_tolerance), float(self.time_limit),
                   len(self.instruments), float(self.rest_speed), float(self.rest_time),
                   len(self.pairs), T_pad_needle, tip_point, marks, half_x, half_y,
                   float(self.pad.mark_radius), float(self.needle.radius),
                   *_kernel_state(state[:10]), kernel_array(state.next_pair, np.int64), t,
                   objects, grasp, tip, new.phase, new.t_start, new.t_finish, *new[5:11],
                   *passage, *obs.values())  # fmt: skip
        return new, obs

    @cached_property
    def _passage_constants(self) -> tuple:
        """The needle's point in its own frame (3,), the pad's marks (P, 2, 3) and half
        extent (m) as :func:`~davinci_sim.tasks.needle_row.drive_rows` takes them."""
        return (np.array(self.needle.points(1.0), dtype=float).reshape(3),
                np.array(self.pad.marks, dtype=float),
                tuple(float(h) for h in np.array(self.pad.size, dtype=float) / 2))  # fmt: skip

    def step_arrays(self, state: DriveState, sample: Sample):
        """:meth:`step` in numpy (the tests' oracle: the same bits)."""
        if sample.objects is None or sample.grasp is None or sample.T_task_object is None:
            raise ValueError(f"task {self.name!r} needs the sample's objects, grasp and "
                             "T_task_object (NeedleDriveTask.scene_fields)")  # fmt: skip
        t = sample.time
        p, parked, carry, e = self._handle(state, sample)
        passage, ev = passage_step(state.passage, self.T_pad_world @ sample.T_task_object,
                                   self.needle, self.pad)  # fmt: skip
        new, t_start, running, timeout = self._start(state, e, parked, t)
        scored = running & ev.passed & (ev.pair == state.next_pair)
        next_pair = state.next_pair + scored
        finish, t_finish = self._finish(new, state, running,
                                        (next_pair >= len(self.pairs)) | timeout, t)  # fmt: skip
        counted = running  # (errors and trauma of the attempt only)
        obs = {
            "distance": np.linalg.norm(p - sample.tip, axis=1),
            "handoffs": e.handoff.astype(np.int64),
            "dropped": e.drop.astype(np.int64),
            "passes": scored.astype(np.int64),
            # (finite where their events are: nan elsewhere, not taken)
            "entry_error": np.where(counted & ev.entered, ev.entry_error, 0.0),
            "exit_error": np.where(counted & ev.exited, ev.exit_error, 0.0),
            "trauma": np.where(counted & ev.exited, ev.trauma, 0.0),
            "missed": np.where(finish, len(self.pairs) - next_pair, 0).astype(np.int64),
        }
        new_state = DriveState(new, t_start, t_finish, t.astype(float), p.copy(), *carry,
                               next_pair, passage)  # fmt: skip
        return new_state, obs

    def progress(self, state) -> str:
        """What to do next, while running."""
        if int(state.phase[0]) != Phase.RUNNING:
            return ""
        k = int(state.next_pair[0])
        if bool(state.passage.inside[0]):
            return f"drive the needle round its curve to exit mark {k + 1}"
        if not state.carried[0]:
            return "pick the needle up"
        return f"enter the tissue at entry mark {k + 1} of {len(self.pairs)}"

    def summary(self, row: dict) -> str:
        return (f"{row['passes']} of {len(self.pairs)} pairs passed, entry error "
                f"{row['entry_error'] * 1e3:.1f} mm, exit error {row['exit_error'] * 1e3:.1f} "
                f"mm, trauma {row['tissue_trauma'] * 1e3:.1f} mm, {row['drops']} drops, "
                f"{row['completion_time']:.1f} s")  # fmt: skip

    _FIELDS = (*NeedlePickupTask._FIELDS, "pad_center", "pad_top", "pad_yaw", "pairs",
               "mark_radius")  # fmt: skip

    def to_dict(self) -> dict[str, Any]:
        out = super().to_dict()
        out["pad_center"] = list(self.pad_center)
        out["pairs"] = [[list(a) for a in pair] for pair in self.pairs]
        return out
