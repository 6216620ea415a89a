"""Needle pick-up and hand-off: lift the curved needle out of its park with one instrument
and hand it to the other (kind ``needle_pickup``).

The needle (:mod:`davinci_sim.tasks.needle_scene`) stands upright in a slit of a foam block
on the tissue; the jaws hold it by contact and friction only. The trainee picks it up with
either instrument, hands it to the other, and holds it there, lifted clear of the park, for
``hold_time``: the first skill of suturing, before the needle is driven.

**What is observed each tick** (the :class:`~davinci_sim.tasks.base.Sample`'s ``objects``,
the needle's centre (n, 1, 3) (the centre of its circle, world frame, m), ``grasp``, the
bit mask of the jaws touching it, and ``tools``, every instrument's tip; holding, resting,
hand-offs and drops are the law :mod:`davinci_sim.tasks.handling` shares with peg transfer):

* the needle is *held* by an instrument when both its jaws touch it;
* it *rests* when no jaw touches it and its centre has moved slower than ``rest_speed``
  for ``rest_time``; it rests *in the park* within ``park_tolerance`` of its start;
* its *owner* is the instrument that holds it alone; a *hand-off* is the owner changing
  while the needle is carried (held since it last rested);
* a carried needle that comes to rest outside the park is *dropped* (a needle put back
  in its park is not); the hand-off must then be made again;
* it is *delivered* when, after a hand-off, its owner holds it alone with its centre
  ``lift_height`` above the start for ``hold_time``.

**States**: IDLE → READY when the needle rests in its park; READY → RUNNING when it is
first held (the clock starts); RUNNING → FINISHED when it is delivered or ``time_limit``
(s; 0: none) has run out (a missed target); then RESULTS.

**Metrics**: time, economy of motion over every instrument
(:data:`~davinci_sim.tasks.peg.ECONOMY_ALL`), hand-offs, and the trainer metrics
(collisions, excessive force, out of view, master workspace, drops, missed = not
delivered).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar, NamedTuple

import numpy as np

from davinci_sim.kinematics.jit import kernel_array
from davinci_sim.tasks.base import (
    Sample,
    Task,
    TaskError,
    TeleopSpec,
    common_fields,
    common_to_dict,
)
from davinci_sim.tasks.exercise_parts import positive
from davinci_sim.tasks.handling import Events, Handling, handling_step
from davinci_sim.tasks.needle_row import pickup_rows
from davinci_sim.tasks.needle_scene import NeedlePark, NeedleSpec
from davinci_sim.tasks.peg import ECONOMY_ALL, HANDOFFS, _AnyMapping
from davinci_sim.tasks.schema import NONNEGATIVE, ListOf, Number, Text, Vector
from davinci_sim.tasks.state import Phase
from davinci_sim.tasks.trainer import TIME, trainer_metrics

_IDLE, _READY, _RUNNING, _FINISHED, _RESULTS = (int(p) for p in Phase)


class NeedleState(NamedTuple):
    """n trials: (n,) arrays (``p_prev`` (n, 3))."""

    phase: np.ndarray
    t_start: np.ndarray
    t_finish: np.ndarray
    t_prev: np.ndarray
    """Time of the previous sample, s (nan before the first)."""
    p_prev: np.ndarray
    """The needle's centre at the previous sample, m."""
    t_still: np.ndarray
    """Since when the needle has been slow and untouched, s (nan: it is not)."""
    owner: np.ndarray
    """1 + index of the instrument that last held it alone (0: none)."""
    carried: np.ndarray
    """Held since it last rested."""
    handed: np.ndarray
    """Handed off since it was picked up."""
    loose: np.ndarray
    """Resting outside the park (its drop already counted)."""
    t_held: np.ndarray
    """Since when it has been held for delivery (handed, alone, lifted), s (nan: not)."""


@dataclass(frozen=True, eq=False)
class NeedlePickupTask(Task, kind="needle_pickup"):
    """Needle pick-up and hand-off (see the module docstring); lengths in m, world frame."""

    METRICS = (TIME, ECONOMY_ALL, HANDOFFS, *trainer_metrics())
    FILE_FIELDS: ClassVar[dict] = {
        "park_center": Vector(2, "x, y"),
        "park_top": Number(),
        "park_yaw": Number(),
        "needle_radius": Number(above=0.0),
        "needle_arc": Number(above=0.0, maximum=2 * math.pi),
        "needle_wire_radius": Number(above=0.0),
        "needle_mass": Number(above=0.0),
        "lift_height": Number(above=0.0),
        "hold_time": NONNEGATIVE,
        "park_tolerance": Number(above=0.0),
        "time_limit": NONNEGATIVE,
        "rest_speed": Number(above=0.0),
        "rest_time": NONNEGATIVE,
        "instruments": ListOf(Text(), min_items=2, what="PSM names"),
        "scoring": _AnyMapping(),
    }
    FILE_REQUIRED = ("park_center", "park_top")
    #: The needle is what the jaws are meant to touch: not a collision (the park is).
    CONTACT_IGNORE = ("task/needle",)
    #: (the tip's distance from the needle's start, an observation for a learning agent:
    #: no deviation a trainee could read)
    DISTANCE_LABEL = None
    FIXTURE_TYPES = {"none": set()}

    name: str
    park_center: tuple[float, float]
    park_top: float
    park_yaw: float = 0.0
    """Direction of the park's slit (the needle's plane) about the world z axis, rad."""
    needle_radius: float = NeedleSpec.radius
    needle_arc: float = NeedleSpec.arc
    needle_wire_radius: float = NeedleSpec.wire_radius
    needle_mass: float = NeedleSpec.mass
    lift_height: float = 0.01
    """How far above its start the needle's centre must be when delivered, m."""
    hold_time: float = 0.5
    """How long the receiving instrument holds it alone, lifted, s."""
    park_tolerance: float = 0.003
    time_limit: float = 120.0
    rest_speed: float = 0.01
    rest_time: float = 0.1
    instruments: tuple[str, ...] = ("PSM2", "PSM1")
    """The PSMs whose jaws hold the needle (the hand-off is between them)."""
    frame: str = "world"
    description: str = ""
    teleop: TeleopSpec = field(default_factory=TeleopSpec)
    fixture_spec: dict = field(default_factory=lambda: {"type": "none"})
    conditions: tuple[dict, ...] = ()
    walls: tuple[dict, ...] = ()
    scoring_spec: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.frame != "world":
            raise TaskError(f"task {self.name!r}: a needle exercise is in the world frame")
        center = tuple(float(x) for x in self.park_center)
        if len(center) != 2 or not all(math.isfinite(x) for x in center):
            raise TaskError(f"task {self.name!r}: park_center must be [x, y] (m)")
        object.__setattr__(self, "park_center", center)
        for key in ("lift_height", "park_tolerance", "rest_speed"):
            positive(self.name, key, getattr(self, key))
        instruments = tuple(self.instruments)
        if len(instruments) != 2 or len(set(instruments)) != 2:
            raise TaskError(f"task {self.name!r}: instruments must be two different PSMs, "
                            f"got {list(instruments)}")  # fmt: skip
        object.__setattr__(self, "instruments", instruments)
        try:
            self.needle, self.park  # noqa: B018 (built to check them)
        except ValueError as e:
            raise TaskError(f"task {self.name!r}: {e}") from e
        self.check()

    @cached_property
    def needle(self) -> NeedleSpec:
        return NeedleSpec(radius=float(self.needle_radius), arc=float(self.needle_arc),
                          wire_radius=float(self.needle_wire_radius),
                          mass=float(self.needle_mass))  # fmt: skip

    @cached_property
    def park(self) -> NeedlePark:
        return NeedlePark(self.park_center, float(self.park_top), float(self.park_yaw))

    @cached_property
    def T_world_start(self) -> np.ndarray:
        """The needle's frame in its park at the start (4×4, world, m)."""
        return self.park.T_world_needle(self.needle)

    # ------------------------------------------------------------ scoring
    @property
    def SCORING(self) -> dict:  # noqa: N802 (the kind's declaration)
        """Time (100 % at 10 s, 0 % at the time limit or 60 s), drops (0 % at 2), hand-offs
        beyond the one asked for are not scored; collisions (0 % at 10), excessive force
        (0 % at 5 s), economy (100 % at 10 cm, 0 % at 60 cm), out of view (0 % at 10 cm).
        Our assumptions until an expert reference is shipped."""
        t_fail = self.time_limit if self.time_limit > 0 else 60.0
        return {
            "metrics": {
                "completion_time": {"weight": 1.0, "fail": t_fail, "expert": 10.0},
                "drops": {"weight": 1.0, "fail": 2.0, "expert": 0.0},
                "missed_targets": {"weight": 2.0, "fail": 1.0, "expert": 0.0},
                "instrument_collisions": {"weight": 1.0, "fail": 10.0, "expert": 0.0},
                "excessive_force": {"weight": 1.0, "fail": 5.0, "expert": 0.0},
                "path_length": {"weight": 1.0, "fail": 0.6, "expert": 0.1},
                "out_of_view": {"weight": 1.0, "fail": 0.1, "expert": 0.0},
            }
        }

    # ------------------------------------------------------------ geometry
    @property
    def start(self) -> np.ndarray:
        """25 mm above the needle's top, where a repetition starts (m, world): the jaws,
        10.5 mm long, clear it."""
        top = self.T_world_start @ np.append(self.needle.points(0.5), 1.0)
        return top[:3] + [0.0, 0.0, 0.025]

    @property
    def view_points(self) -> np.ndarray:
        """The needle's ends and top, and the points it is lifted to."""
        T = self.T_world_start
        pts = T[:3, :3] @ self.needle.points(np.array([0.0, 0.5, 1.0])).T + T[:3, 3:4]
        return np.vstack([pts.T, pts.T + [0.0, 0.0, self.lift_height + 0.01]])

    @property
    def check_points(self) -> np.ndarray:
        """Where the instruments must reach: the needle's top, at the start and lifted."""
        return self.view_points[[1, 4]]

    # ------------------------------------------------------------ Task
    def draw(self, spec, *, T_world_camera=None, prefix: str = "task/"):
        """The park's foam block and the needle standing in it
        (:func:`~davinci_sim.tasks.needle_scene.add_needle`)."""
        from davinci_sim.tasks.needle_scene import add_needle

        return add_needle(spec, self.needle, self.park, prefix)

    def probe(self, model, prefix: str = "task/"):
        """A :class:`~davinci_sim.tasks.needle_scene.NeedleProbe` of ``model`` (drawn)."""
        from davinci_sim.tasks.needle_scene import NeedleProbe

        return NeedleProbe(model, self.instruments, prefix)

    def reset_scene(self, model, data) -> None:
        """The needle back in its park, at rest."""
        from davinci_sim.tasks.needle_scene import reset_needle

        reset_needle(model, data, self.needle, self.park)

    def objects_probe(self, model, cache: dict):
        """The needle's probe (:meth:`probe`)."""
        return self.cached_probe(model, cache)

    def objects_fields(self, reading, model, data, cache: dict) -> dict:
        """The sample's ``objects`` (the needle's centre), ``grasp``, ``tools`` and
        ``T_task_object`` (the needle's frame: its plane, for a learning environment's
        observation and the drive's passage)."""
        from davinci_sim.tasks.objects_probe import frame_of

        return {"objects": reading.xpos[:1].copy(), "grasp": reading.grasp[:1].copy(),
                "tools": reading.tips,
                "T_task_object": frame_of(reading.xpos[0], reading.xmat[0])}  # fmt: skip

    def initial_state(self, n: int) -> NeedleState:
        nan = np.full(n, np.nan)
        off = np.zeros(n, dtype=bool)
        return NeedleState(np.full(n, Phase.IDLE, dtype=np.int8), nan, nan.copy(), nan.copy(),
                           np.full((n, 3), np.nan), nan.copy(), np.zeros(n, dtype=np.int64),
                           off, off.copy(), off.copy(), nan.copy())  # fmt: skip

    def step(self, state: NeedleState, sample: Sample):
        """One sample of n trials (pure; see the module docstring). Observations:
        ``distance`` (tip to the needle's centre, m), ``handoffs``, ``dropped`` (events at
        this sample), ``missed`` (1 at the sample that finishes without a delivery),
        ``held`` (1 + holding instrument's index, 0: none; 3: both). One compiled call
        (:func:`~davinci_sim.tasks.needle_row.pickup_rows`); :meth:`step_arrays` is the same
        in numpy."""
        t, objects, grasp, tip = self._sample_arrays(sample)
        n = len(t)
        new = NeedleState(np.empty(n, dtype=np.int8), np.empty(n), np.empty(n), t,
                          objects.copy(), np.empty(n), np.empty(n, dtype=np.int64),
                          np.empty(n, dtype=bool), np.empty(n, dtype=bool),
                          np.empty(n, dtype=bool), np.empty(n))  # fmt: skip
        obs = {"distance": np.empty(n),
               **{k: np.empty(n, dtype=np.int64) for k in ("handoffs", "dropped", "missed",
                                                            "held")}}  # fmt: skip
        pickup_rows(self._start_point, float(self.park_tolerance), float(self.lift_height),
                    float(self.hold_time), float(self.time_limit), len(self.instruments),
                    float(self.rest_speed), float(self.rest_time), *_kernel_state(state[:10]),
                    kernel_array(state.t_held), t, objects, grasp, tip, new.phase,
                    new.t_start, new.t_finish, *new[5:], *obs.values())  # fmt: skip
        return new, obs

    @cached_property
    def _start_point(self) -> np.ndarray:
        """The needle's start centre (3,), world, m (a kernel's argument)."""
        return np.array(self.T_world_start[:3, 3], dtype=float)

    def _sample_arrays(self, sample: Sample) -> tuple:
        """The sample's time (n,), needle centre (n, 3), jaw bits (n,) and tip (n, 3) as
        the kernels take them (the time a copy: it becomes the state's)."""
        if sample.objects is None or sample.grasp is None:
            raise ValueError(f"task {self.name!r} needs the sample's objects and grasp "
                             "(NeedlePickupTask.scene_fields)")  # fmt: skip
        n = sample.n
        return (np.array(sample.time, dtype=float).reshape(n),
                kernel_array(np.reshape(sample.objects, (n, 3))),
                kernel_array(np.reshape(sample.grasp, n), np.int64),
                kernel_array(sample.tip))  # fmt: skip

    def step_arrays(self, state: NeedleState, sample: Sample):
        """:meth:`step` in numpy (the tests' oracle: the same bits)."""
        if sample.objects is None or sample.grasp is None:
            raise ValueError(f"task {self.name!r} needs the sample's objects and grasp "
                             "(NeedlePickupTask.scene_fields)")  # fmt: skip
        t = sample.time
        p, parked, carry, e = self._handle(state, sample)
        start = self.T_world_start[:3, 3]
        lifted = p[:, 2] >= start[2] + self.lift_height
        holding = carry.handed & e.alone & lifted
        t_held = np.where(holding, np.where(np.isnan(state.t_held), t, state.t_held), np.nan)
        with np.errstate(invalid="ignore"):
            delivered = holding & (t - t_held >= self.hold_time)
        new, t_start, running, timeout = self._start(state, e, parked, t)
        finish, t_finish = self._finish(new, state, running, delivered | timeout, t)

        obs = {
            "distance": np.linalg.norm(p - sample.tip, axis=1),
            "handoffs": e.handoff.astype(np.int64),
            "dropped": e.drop.astype(np.int64),
            "missed": (finish & ~delivered).astype(np.int64),
            "held": np.where(e.held, np.where(e.alone, e.who, 3), 0),
        }
        new_state = NeedleState(new, t_start, t_finish, t.astype(float), p.copy(), *carry,
                                t_held)  # fmt: skip
        return new_state, obs

    def _handle(self, state, sample: Sample) -> tuple[np.ndarray, np.ndarray, Handling, Events]:
        """The needle at this sample (:mod:`~davinci_sim.tasks.handling`): its centre
        (n, 3), whether it is in its park (n,), the carry state and the events."""
        n = sample.n
        p = np.asarray(sample.objects, dtype=float).reshape(n, 1, 3)
        parked = np.linalg.norm(p - self.T_world_start[:3, 3], axis=2) <= self.park_tolerance
        carry, e = handling_step(
            Handling(*(a[:, None] for a in (state.t_still, state.owner, state.carried,
                                            state.handed, state.loose))),
            grasp=np.asarray(sample.grasp).reshape(n, 1), p=p, p_prev=state.p_prev[:, None],
            t=sample.time, t_prev=state.t_prev, placed=parked, instruments=len(self.instruments),
            rest_speed=self.rest_speed, rest_time=self.rest_time,
        )  # fmt: skip
        carry, e = Handling(*(a[:, 0] for a in carry)), Events(*(a[:, 0] for a in e))
        return p[:, 0], parked[:, 0], carry, e

    def _start(self, state, e: Events, parked, t):
        """IDLE → READY when the needle rests in its park, READY → RUNNING when it is
        first held: ``(phases, t_start, running, timed out)`` ((n,) arrays)."""
        phase = state.phase
        new = phase.copy()
        new[(phase == _IDLE) & e.resting & parked] = _READY
        begin = (phase == _READY) & e.held
        new[begin] = _RUNNING
        t_start = np.where(begin, t, state.t_start)
        running = (phase == _RUNNING) | begin
        if self.time_limit > 0:
            with np.errstate(invalid="ignore"):
                timeout = t - t_start >= self.time_limit
        else:
            timeout = np.zeros(len(phase), dtype=bool)
        return new, t_start, running, timeout

    @staticmethod
    def _finish(new, state, running, ends, t):
        """RUNNING → FINISHED where ``ends``, FINISHED → RESULTS, in ``new`` (the phases
        :meth:`_start` gave): ``(finishing (n,), t_finish (n,))``."""
        finish = running & ends
        new[finish] = _FINISHED
        new[state.phase == _FINISHED] = _RESULTS
        return finish, np.where(finish, t, state.t_finish)

    def at_start(self, tip) -> np.ndarray:
        """Tips (n, 3) within 1 cm of :attr:`start` (a session's next repetition also
        needs the needle back in its park: the state machine waits for it)."""
        p = np.asarray(tip, dtype=float).reshape(-1, 3)
        return np.linalg.norm(p - self.start, axis=1) <= 0.01

    def distance(self, tip) -> np.ndarray:
        """Tips (n, 3) to the needle's start centre, m (where it is is the sample's)."""
        p = np.asarray(tip, dtype=float).reshape(-1, 3)
        return np.linalg.norm(p - self.T_world_start[:3, 3], axis=1)

    def progress(self, state) -> str:
        """What to do next, while running."""
        if int(state.phase[0]) != Phase.RUNNING:
            return ""
        if not state.carried[0]:
            return "pick the needle up"
        if not state.handed[0]:
            return "hand the needle to the other instrument"
        return f"hold it {self.lift_height * 1e3:.0f} mm up, in the other instrument alone"

    def summary(self, row: dict) -> str:
        done = "delivered" if row["missed_targets"] == 0 else "not delivered"
        return (f"needle {done}, {row['handoffs']} hand-offs, {row['drops']} drops, "
                f"{row['completion_time']:.1f} s")  # fmt: skip

    def guidance(self, spec: dict):
        """No guidance field (``fixture: none`` only)."""
        return None

    # ------------------------------------------------------------ I/O
    _FIELDS = (
        "park_center", "park_top", "park_yaw", "needle_radius", "needle_arc",
        "needle_wire_radius", "needle_mass", "lift_height", "hold_time", "park_tolerance",
        "time_limit", "rest_speed", "rest_time", "instruments",
    )  # fmt: skip

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> NeedlePickupTask:
        kw = common_fields(data)
        kw.update({k: data[k] for k in cls._FIELDS if k in data})
        try:
            return cls(**kw)
        except TypeError as e:
            raise TaskError(f"task {data.get('name', '?')!r}: {e}") from e

    def to_dict(self) -> dict[str, Any]:
        out = common_to_dict(self)
        for k in self._FIELDS:
            v = getattr(self, k)
            out[k] = list(v) if isinstance(v, tuple) else v
        return out


def _kernel_state(state) -> tuple:
    """A needle state's first ten arrays (phase … loose) as the kernels take them (the same
    arrays where they already are: a step's own outputs)."""
    phase, *floats3, p_prev, t_still, owner, carried, handed, loose = state
    return (kernel_array(phase, np.int8), *(kernel_array(a) for a in floats3),
            kernel_array(p_prev), kernel_array(t_still), kernel_array(owner, np.int64),
            *(kernel_array(a, bool) for a in (carried, handed, loose)))  # fmt: skip
