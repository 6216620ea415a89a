"""Peg transfer: pick up rings with the PSM jaws and move them between pegs (kind ``peg_transfer``).

A board carries pegs in two groups, the *start* pegs (each with a ring) and the *target*
pegs; the trainee lifts each ring off its peg with an instrument's jaws (MuJoCo contact and
friction, :mod:`davinci_sim.tasks.peg_scene`), carries it over and drops it on a target
peg. With ``wall: true`` (the ICRA 2026 competition's 3-minute variant) a wall across the
board's middle makes the rings change hands: a ring counts as transferred only if it was
handed off from one instrument to the other on its way (one point per ring on a target
peg).

**What is observed each tick** (the :class:`~davinci_sim.tasks.base.Sample`'s ``objects``,
ring centres (n, k, 3), m, and ``grasp``, the bit mask of the jaws touching each ring,
:class:`~davinci_sim.tasks.peg_scene.PegProbe`; holding, resting, hand-offs and drops are
the law :mod:`davinci_sim.tasks.handling` shares with the needle):

* a ring is *held* by an instrument when both its jaws touch it;
* it is *resting* when no jaw touches it and its centre has moved slower than
  ``rest_speed`` for ``rest_time`` (speeds from consecutive samples);
* it is *on a peg* when the peg's axis passes through its hole (the centre within
  ``ring_radius − ring_tube_radius`` of the axis, horizontally) and its centre is lower
  than the peg's top;
* its *owner* is the instrument that holds it alone; a *hand-off* is the owner changing
  from one instrument to the other while the ring is carried (lifted and not yet landed);
* a carried ring that comes to rest *lands*: on a target peg it is *transferred* (with a
  wall: only if handed off on the way; each ring once); off every peg it is *dropped*; a
  ring that was not carried and comes to rest off every peg (knocked off) is dropped too.

**States**: IDLE → READY when every ring rests on a start peg; READY → RUNNING when a ring is
first held (the clock starts); RUNNING → FINISHED when every ring is transferred or the
``time_limit`` (s; 0: none) has run out; then RESULTS.

**Metrics**: time, economy of motion (:data:`ECONOMY_ALL`: the sum of the tip path lengths
of every instrument in ``instruments``, from the sample's ``tools``; a hand-off needs both),
transferred rings and hand-offs (the kind's own), and the trainer metrics
(collisions, excessive force, out of view, master workspace, drops, missed targets = rings
not transferred at the end).

**Fixture**: ``none`` or ``spring`` / ``viscous`` guidance along the *transfer route*, a
polyline from above the start pegs' centroid, over the board's middle (above the wall, if
any), to above the target pegs' centroid (the same laws as the path kind's,
:mod:`davinci_sim.haptics.spring`, :mod:`davinci_sim.haptics.viscous`): a fixture is a
field of the tool's position only, so it guides along the route, not to the ring of the
moment.

Size: one kind, its file fields, geometry, pure state machine and metric declarations
together (a little over 500 lines since its economy of motion counts every instrument);
the scene's side is :mod:`davinci_sim.tasks.peg_scene`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar, NamedTuple

import numpy as np

from davinci_sim.geometry.path import Polyline
from davinci_sim.tasks.base import (
    Sample,
    Task,
    TaskError,
    TeleopSpec,
    common_fields,
    common_to_dict,
)
from davinci_sim.tasks.handling import Handling, handling_step, holders
from davinci_sim.tasks.metrics import Metric, PairSum, observed
from davinci_sim.tasks.schema import (
    NONNEGATIVE,
    Flag,
    ListOf,
    Number,
    Schema,
    SchemaError,
    Text,
    Vector,
)
from davinci_sim.tasks.state import Phase
from davinci_sim.tasks.trainer import TIME, Sum, trainer_metrics

_IDLE, _READY, _RUNNING, _FINISHED, _RESULTS = (int(p) for p in Phase)


TRANSFERRED = Metric(
    "transferred", "1", "higher", "rings transferred to a target peg (one point per peg)",
    Sum(observed("transferred"), True), integer=True, label="rings transferred",
)  # fmt: skip
HANDOFFS = Metric(
    "handoffs", "1", "neither", "hand-offs of a carried ring between the instruments",
    Sum(observed("handoffs"), True), integer=True, label="hand-offs",
)  # fmt: skip


def _tools_step(task, prev, s, obs):
    # Σ over the instruments of each tip's step, (n, A, 3) → (n,).
    return np.linalg.norm(s.tools - prev.tools, axis=2).sum(axis=1)


#: Economy of motion of a task with several instruments: Σ_a Σ_{i≥2} ‖p_a,i − p_a,i−1‖ over
#: the instruments a (the sample's ``tools``), m (shown in cm).
ECONOMY_ALL = Metric(
    "path_length", "m", "lower",
    "length of the tool tips' trajectories, every instrument summed (economy of motion)",
    PairSum(_tools_step), report=("mm", 1e3), display=("cm", 100.0), needs=("tools",),
)  # fmt: skip


class _AnyMapping(Schema):
    """A mapping (the ``scoring`` entry: :mod:`~davinci_sim.tasks.scoring` checks its
    content when the task is built)."""

    def check(self, value, path):
        if not isinstance(value, dict):
            raise SchemaError(path, f"must be a mapping, got {value!r}")


class PegState(NamedTuple):
    """n trials of k rings: (n,) and (n, k) arrays."""

    phase: np.ndarray
    t_start: np.ndarray
    t_finish: np.ndarray
    t_prev: np.ndarray
    """(n,) time of the previous sample, s (nan before the first)."""
    p_prev: np.ndarray
    """(n, k, 3) ring centres at the previous sample, m."""
    t_still: np.ndarray
    """(n, k) since when the ring has been slow and untouched, s (nan: it is not)."""
    owner: np.ndarray
    """(n, k) 1 + index of the instrument that last held the ring alone (0: none)."""
    carried: np.ndarray
    """(n, k) bool: held since it last rested."""
    handed: np.ndarray
    """(n, k) bool: handed off since it was picked up."""
    loose: np.ndarray
    """(n, k) bool: resting off every peg (its drop already counted)."""
    done: np.ndarray
    """(n, k) bool: transferred."""


@dataclass(frozen=True, eq=False)
class PegTransferTask(Task, kind="peg_transfer"):
    """Peg transfer (see the module docstring for the rules); lengths in m, world frame."""

    METRICS = (TIME, ECONOMY_ALL, TRANSFERRED, HANDOFFS, *trainer_metrics())
    FILE_FIELDS: ClassVar[dict] = {
        "board_center": Vector(2, "x, y"),
        "board_top": Number(),
        "board_half_size": Vector(2, "x, y", Number(above=0.0)),
        "board_thickness": Number(above=0.0),
        "pegs": ListOf(Vector(2, "x, y"), min_items=2, what="peg positions [x, y]"),
        "start_pegs": ListOf(Number(minimum=0), min_items=1, what="peg indices"),
        "target_pegs": ListOf(Number(minimum=0), min_items=1, what="peg indices"),
        "peg_radius": Number(above=0.0),
        "peg_height": Number(above=0.0),
        "ring_radius": Number(above=0.0),
        "ring_tube_radius": Number(above=0.0),
        "ring_segments": Number(minimum=6, maximum=32),
        "wall": Flag(),
        "wall_height": Number(above=0.0),
        "wall_thickness": Number(above=0.0),
        "time_limit": NONNEGATIVE,
        "rest_speed": Number(above=0.0),
        "rest_time": NONNEGATIVE,
        "instruments": ListOf(Text(), min_items=1, what="PSM names"),
        "scoring": _AnyMapping(),
    }
    FILE_REQUIRED = ("pegs", "start_pegs", "target_pegs", "board_center", "board_top")
    #: The rings are what the jaws are meant to touch: not collisions.
    CONTACT_IGNORE = ("task/ring",)
    FIXTURE_TYPES = {
        "viscous": {"B", "G_max", "transition"},
        "spring": {"stiffness", "damping", "max_force", "transition"},
        "none": set(),
    }

    name: str
    pegs: np.ndarray
    """(P, 2) peg axes (x, y) on the board, m, world frame."""
    start_pegs: tuple[int, ...]
    """0-based indices of the pegs that carry a ring at the start (one ring each)."""
    target_pegs: tuple[int, ...]
    board_center: tuple[float, float]
    board_top: float
    """Height of the board's top face, m."""
    board_half_size: tuple[float, float] = (0.085, 0.04)
    board_thickness: float = 0.004
    peg_radius: float = 0.0015
    peg_height: float = 0.015
    """Peg top above the board, m."""
    ring_radius: float = 0.009
    """Centre-line radius of a ring, m."""
    ring_tube_radius: float = 0.0015
    ring_segments: int = 12
    wall: bool = False
    wall_height: float = 0.025
    wall_thickness: float = 0.004
    time_limit: float = 300.0
    """s (0: none). The ICRA 2026 variant: 180."""
    rest_speed: float = 0.01
    """A ring untouched by the jaws and slower than this (m/s) ..."""
    rest_time: float = 0.1
    """... for this long (s) is resting."""
    instruments: tuple[str, ...] = ("PSM1", "PSM2")
    """The PSMs whose jaws hold rings (hand-offs are between them)."""
    frame: str = "world"
    description: str = ""
    teleop: TeleopSpec = field(default_factory=TeleopSpec)
    fixture_spec: dict = field(default_factory=lambda: {"type": "none"})
    conditions: tuple[dict, ...] = ()
    walls: tuple[dict, ...] = ()
    scoring_spec: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        pegs = np.array(self.pegs, dtype=float)
        if pegs.ndim != 2 or pegs.shape[1] != 2 or len(pegs) < 2 or not np.isfinite(pegs).all():
            raise TaskError(f"task {self.name!r}: pegs must be P >= 2 points [x, y] (m)")
        pegs.setflags(write=False)
        object.__setattr__(self, "pegs", pegs)
        for key in ("start_pegs", "target_pegs"):
            idx = tuple(int(i) for i in getattr(self, key))
            if any(i < 0 or i >= len(pegs) for i in idx) or len(set(idx)) != len(idx):
                raise TaskError(f"task {self.name!r}: {key} must be distinct peg indices "
                                f"0..{len(pegs) - 1}, got {list(idx)}")  # fmt: skip
            object.__setattr__(self, key, idx)
        if set(self.start_pegs) & set(self.target_pegs):
            raise TaskError(f"task {self.name!r}: a peg cannot be both a start and a target")
        if len(self.target_pegs) < len(self.start_pegs):
            raise TaskError(f"task {self.name!r}: fewer target pegs than rings")
        object.__setattr__(self, "ring_segments", int(self.ring_segments))
        object.__setattr__(self, "instruments", tuple(self.instruments))
        object.__setattr__(self, "board_center", tuple(float(x) for x in self.board_center))
        object.__setattr__(self, "board_half_size",
                           tuple(float(x) for x in self.board_half_size))  # fmt: skip
        if self.frame != "world":
            raise TaskError(f"task {self.name!r}: a peg board is in the world frame")
        hole = self.ring_radius - self.ring_tube_radius
        if hole <= self.peg_radius:
            raise TaskError(f"task {self.name!r}: a ring's hole (radius {hole:g} m) must "
                            f"clear the peg (radius {self.peg_radius:g} m)")  # fmt: skip
        if len(self.instruments) > 31:
            raise TaskError(f"task {self.name!r}: at most 31 instruments")
        self.check()

    # ------------------------------------------------------------ scoring
    @property
    def SCORING(self) -> dict:  # noqa: N802 (the kind's declaration, from its size)
        """Rings transferred (weight 2: all of them 100 %, none 0 %), time (100 % at 20 s
        a ring, 0 % at the time limit or 60 s a ring), drops (0 % at one per ring),
        collisions (0 % at 10), excessive force (0 % at 5 s), economy (100 % at 10 cm a
        ring, 0 % at 60 cm), out of view (0 % at 20 cm). Our assumptions (no trainer
        publishes its thresholds); a programme sets its own in the task file."""
        k = len(self.start_pegs)
        t_fail = self.time_limit if self.time_limit > 0 else 60.0 * k
        return {
            "metrics": {
                "transferred": {"weight": 2.0, "fail": 0.0, "expert": float(k)},
                "completion_time": {"weight": 1.0, "fail": t_fail, "expert": 20.0 * k},
                "drops": {"weight": 1.0, "fail": float(k), "expert": 0.0},
                "instrument_collisions": {"weight": 1.0, "fail": 10.0, "expert": 0.0},
                "excessive_force": {"weight": 1.0, "fail": 5.0, "expert": 0.0},
                "path_length": {"weight": 1.0, "fail": 0.6 * k, "expert": 0.1 * k},
                "out_of_view": {"weight": 1.0, "fail": 0.2, "expert": 0.0},
            }
        }

    # ------------------------------------------------------------ geometry
    @property
    def n_rings(self) -> int:
        return len(self.start_pegs)

    @cached_property
    def route(self) -> Polyline:
        """The transfer route (world frame, m): above the start pegs' centroid, up over the
        board's middle (clearing the wall and the pegs), above the target pegs' centroid."""
        lift = max(self.peg_height, self.wall_height if self.wall else 0.0) + 0.015
        a = self.pegs[list(self.start_pegs)].mean(axis=0)
        b = self.pegs[list(self.target_pegs)].mean(axis=0)
        z0 = self.board_top + self.peg_height + 0.01
        mid = np.array(self.board_center)
        return Polyline([[*a, z0], [*mid, self.board_top + lift], [*b, z0]])

    @property
    def start(self) -> np.ndarray:
        """Above the first ring, at the route's height (where a repetition starts)."""
        return self.route.vertices[0]

    @property
    def view_points(self) -> np.ndarray:
        """Every peg's foot and top, the board's corners and the wall's top ends."""
        top, h = self.board_top, self.peg_height
        pts = [[x, y, top] for x, y in self.pegs] + [[x, y, top + h] for x, y in self.pegs]
        cx, cy = self.board_center
        hx, hy = self.board_half_size
        pts += [[cx + sx * hx, cy + sy * hy, top] for sx in (-1, 1) for sy in (-1, 1)]
        if self.wall:
            pts += [[cx, cy + sy * hy, top + self.wall_height] for sy in (-1, 1)]
        return np.array(pts, dtype=float)

    @property
    def check_points(self) -> np.ndarray:
        """Where the instruments must reach: above each peg at a ring's grasp height."""
        z = self.board_top + self.ring_tube_radius
        return np.array([[x, y, z] for x, y in self.pegs], dtype=float)

    # ------------------------------------------------------------ Task
    def draw(self, spec, *, T_world_camera=None, prefix: str = "task/"):
        """The board, pegs, wall and rings (:func:`~davinci_sim.tasks.peg_scene.add_peg_board`):
        they collide; the rings are free bodies (keyframes extended)."""
        from davinci_sim.tasks.peg_scene import add_peg_board

        return add_peg_board(spec, self, prefix)

    def probe(self, model, prefix: str = "task/"):
        """A :class:`~davinci_sim.tasks.peg_scene.PegProbe` of ``model`` (the task drawn)."""
        from davinci_sim.tasks.peg_scene import PegProbe

        return PegProbe(model, self, prefix)

    def reset_scene(self, model, data) -> None:
        """The rings back on their start pegs, at rest
        (:func:`~davinci_sim.tasks.peg_scene.reset_rings`)."""
        from davinci_sim.tasks.peg_scene import reset_rings

        reset_rings(model, data, self)

    def objects_probe(self, model, cache: dict):
        """The rings' probe (:meth:`probe`, kept in ``cache`` per model)."""
        return self.cached_probe(model, cache)

    def objects_fields(self, reading, model, data, cache: dict) -> dict:
        """The sample's ``objects`` (the rings' centres), ``grasp`` and ``tools`` (the
        instruments' tips)."""
        return {"objects": reading.xpos, "grasp": reading.grasp, "tools": reading.tips}

    def initial_state(self, n: int) -> PegState:
        k = self.n_rings
        return PegState(
            np.full(n, Phase.IDLE, dtype=np.int8), np.full(n, np.nan), np.full(n, np.nan),
            np.full(n, np.nan), np.full((n, k, 3), np.nan), np.full((n, k), np.nan),
            np.zeros((n, k), dtype=np.int64),
            np.zeros((n, k), bool), np.zeros((n, k), bool), np.zeros((n, k), bool),
            np.zeros((n, k), bool),
        )  # fmt: skip

    @cached_property
    def _lookups(self):
        """Per peg index (−1: none, the last entry): is a start peg, is a target peg."""
        P = len(self.pegs)
        start, target = np.zeros(P + 1, bool), np.zeros(P + 1, bool)
        start[list(self.start_pegs)] = True
        target[list(self.target_pegs)] = True
        return start, target

    def peg_of(self, objects) -> np.ndarray:
        """(n, k) index of the peg each ring (centres (n, k, 3), m) is on, −1: none."""
        p = np.asarray(objects, dtype=float)
        delta = p[..., None, :2] - self.pegs
        d2 = np.einsum("...i,...i->...", delta, delta)
        hole = self.ring_radius - self.ring_tube_radius
        inside = d2 <= hole * hole
        low = p[..., 2] <= self.board_top + self.peg_height
        idx = np.argmin(np.where(inside, d2, np.inf), axis=-1)
        return np.where(inside.any(axis=-1) & low, idx, -1)

    def holders(self, grasp) -> np.ndarray:
        """(n, k, A) bool: instrument a holds ring k (both its jaws touch it)."""
        return holders(grasp, len(self.instruments))

    def step(self, state: PegState, sample: Sample):
        """One sample of n trials (pure; see the module docstring). Observations:
        ``distance`` (tip to the nearest ring not yet transferred, m), ``transferred``,
        ``handoffs``, ``dropped`` (events at this sample), ``missed`` (rings not
        transferred, at the sample that finishes), ``held`` (n, k) holder (1 + instrument
        index, 0: none) and ``peg`` (n, k)."""
        if sample.objects is None or sample.grasp is None:
            raise ValueError(f"task {self.name!r} needs the sample's objects and grasp "
                             "(PegTransferTask.scene_fields)")  # fmt: skip
        n, k = sample.n, self.n_rings
        p = np.asarray(sample.objects, dtype=float).reshape(n, k, 3)
        t = sample.time
        peg = self.peg_of(p)
        is_start, is_target = self._lookups
        on_target = is_target[peg]
        carry, e = handling_step(
            Handling(state.t_still, state.owner, state.carried, state.handed, state.loose),
            grasp=sample.grasp.reshape(n, k), p=p, p_prev=state.p_prev, t=t,
            t_prev=state.t_prev, placed=peg >= 0, instruments=len(self.instruments),
            rest_speed=self.rest_speed, rest_time=self.rest_time,
        )  # fmt: skip
        held, resting, who = e.held, e.resting, e.who
        transfer = e.land & on_target & ~state.done & (e.handed | (not self.wall))
        done = state.done | transfer

        phase = state.phase
        new = phase.copy()
        on_start = is_start[peg] & resting
        new[(phase == _IDLE) & on_start.all(axis=1)] = _READY
        begin = (phase == _READY) & held.any(axis=1)
        new[begin] = _RUNNING
        t_start = np.where(begin, t, state.t_start)
        running = (phase == _RUNNING) | begin
        if self.time_limit > 0:
            with np.errstate(invalid="ignore"):
                timeout = t - t_start >= self.time_limit  # (nan before the start: False)
        else:
            timeout = np.zeros_like(running)
        finish = running & (done.all(axis=1) | timeout)
        new[finish] = _FINISHED
        new[phase == _FINISHED] = _RESULTS
        t_finish = np.where(finish, t, state.t_finish)

        rel = p - sample.tip[:, None, :]
        d = np.sqrt(np.where(done, np.inf, np.einsum("...i,...i->...", rel, rel)).min(axis=1))
        obs = {
            "distance": np.where(np.isfinite(d), d, 0.0),
            "transferred": transfer.sum(axis=1),
            "handoffs": e.handoff.sum(axis=1),
            "dropped": e.drop.sum(axis=1),
            "missed": np.where(finish, self.n_rings - done.sum(axis=1), 0),
            "held": np.where(held, who, 0),
            "peg": peg,
        }
        new_state = PegState(new, t_start, t_finish, t.astype(float), p.copy(), *carry, done)
        return new_state, obs

    def at_start(self, tip) -> np.ndarray:
        """Tips (n, 3) within 1 cm of :attr:`start` (a session's next repetition also
        needs the rings back on their start pegs: the state machine waits for them)."""
        p = np.asarray(tip, dtype=float).reshape(-1, 3)
        return np.linalg.norm(p - self.start, axis=1) <= 0.01

    def distance(self, tip) -> np.ndarray:
        """Tips (n, 3) to the transfer route, m (the ring positions are the sample's)."""
        return self.route.closest_point(np.asarray(tip, dtype=float).reshape(-1, 3)).distance

    def progress(self, state) -> str:
        """``ring k of K to a target peg`` (the next not yet transferred) while running,
        with the hand-off the wall asks for while the ring is carried."""
        if int(state.phase[0]) not in (Phase.RUNNING, Phase.FINISHED):
            return ""
        done = int(np.count_nonzero(state.done[0]))
        text = f"ring {min(done + 1, self.n_rings)} of {self.n_rings} to a target peg"
        carried = state.carried[0] & ~state.done[0]
        if self.wall and carried.any() and not state.handed[0][carried].all():
            text += " (hand it off over the wall)"
        return text

    def summary(self, row: dict) -> str:
        return (f"{row['transferred']} of {self.n_rings} rings transferred, "
                f"{row['handoffs']} hand-offs, {row['drops']} drops, "
                f"{row['completion_time']:.1f} s")  # fmt: skip

    # ------------------------------------------------------------ fixtures
    def guidance(self, spec: dict):
        """Spring or viscous guidance along :attr:`route`, or None."""
        from davinci_sim.tasks.task import _guidance

        return _guidance(spec, self.route)

    # ------------------------------------------------------------ I/O
    _FIELDS = ("pegs", "start_pegs", "target_pegs", "board_center", "board_top",
               "board_half_size", "board_thickness", "peg_radius", "peg_height", "ring_radius",
               "ring_tube_radius", "ring_segments", "wall", "wall_height", "wall_thickness",
               "time_limit", "rest_speed", "rest_time", "instruments")  # fmt: skip

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PegTransferTask:
        kw = common_fields(data)
        kw.update({k: data[k] for k in cls._FIELDS if k in data})
        if "pegs" not in kw:
            raise TaskError(f"task {data.get('name', '?')!r}: pegs are required")
        try:
            return cls(**kw)
        except TypeError as e:
            raise TaskError(f"task {data.get('name', '?')!r}: {e}") from e

    def to_dict(self) -> dict[str, Any]:
        out = common_to_dict(self)
        for k in self._FIELDS:
            v = getattr(self, k)
            out[k] = v.tolist() if isinstance(v, np.ndarray) else (
                list(v) if isinstance(v, tuple) else v)  # fmt: skip
        return out
