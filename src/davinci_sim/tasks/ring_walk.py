"""Ring walk: guide a ring along a curved wire without touching it — the ``ring_walk`` kind,
a path task (:class:`~davinci_sim.tasks.task.PathTask`) whose error is contact.

**The model.** The wire is the task's path (waypoints with rounded corners,
:mod:`davinci_sim.geometry.path`), a rod of radius ``wire_radius``. The ring is held by the
instrument: a ring of inner radius ``ring_radius`` centred on the tool tip (the dVRK's tip
point, on the wrist-yaw axis), drawn on the wrist so that it moves with the tool. The ring
is taken as always turned square to the wire (its orientation is not scored): it touches
the wire when the tip's distance to the wire's axis exceeds the clearance
``ring_radius − wire_radius``.

States: those of the path kind (:mod:`davinci_sim.tasks.state`): ready with the tip (the
ring's centre) within ``start_tolerance`` of the wire's first point, running once it
leaves, finished at the last point after half the wire.

Metrics: ``completion_time`` (s); ``contact_time`` (s): Σ (t_i − t_{i−1}) over pairs whose
sample i is in contact; ``contact_count`` (1): onsets of contact, pairs with no contact at
i−1 and contact at i; ``deviation_error`` (m): the mean distance of the ring's centre to
the wire's axis; ``path_length`` (economy, m, shown in cm); then the trainer metrics that
apply (collisions, excessive force, out of view, master workspace; no object is dropped
and the wire has no targets to miss).

Fixture: the path kind's — ``viscous`` guidance toward the wire's axis (the seed's law) or
``spring``, or ``none``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from davinci_sim.tasks.base import TaskError
from davinci_sim.tasks.exercise_parts import VisualBody, positive, viewer_axes
from davinci_sim.tasks.metrics import PATH_METRICS, Metric, PairSum
from davinci_sim.tasks.schema import Number
from davinci_sim.tasks.state import Phase
from davinci_sim.tasks.task import PathTask
from davinci_sim.tasks.trainer import ECONOMY, TIME, trainer_metrics


def _contact(task, s, obs) -> np.ndarray:
    return np.asarray(obs["distance"]) > task.clearance


def _contact_dt(task, prev, s, obs):
    return np.where(_contact(task, s, obs), s.time - prev.time, 0.0)


@dataclass(frozen=True)
class Onsets:
    """Pairs of consecutive samples of the repetition with ``flag`` false at i − 1 and true
    at i (the flag of the previous sample is kept, not recomputed)."""

    flag: object
    """``flag(task, sample, obs) -> (n,) bool``."""

    def init(self, n: int, task=None):
        return (np.zeros(n, dtype=np.int64), np.zeros(n, dtype=bool))

    def add(self, acc, m, pair, task, prev, s, obs):
        count, before = acc
        now = self.flag(task, s, obs)
        return (count + (pair & now & ~before), np.where(m, now, before))

    def final(self, acc, k, done):
        return acc[0].copy()


CONTACT_TIME = Metric(
    "contact_time", "s", "lower", "time the ring touches the wire",
    PairSum(_contact_dt), label="contact time",
)  # fmt: skip
CONTACT_COUNT = Metric(
    "contact_count", "1", "lower", "touches of the wire (onsets of contact)",
    Onsets(_contact), integer=True, label="contacts",
)  # fmt: skip
DEVIATION = next(m for m in PATH_METRICS if m.name == "deviation_error")


@dataclass(frozen=True, eq=False)
class RingWalkTask(PathTask, kind="ring_walk"):
    """A ring walked along a wire (see the module docstring)."""

    METRICS = (TIME, CONTACT_TIME, CONTACT_COUNT, DEVIATION, ECONOMY,
               *trainer_metrics(leave_out=("drops", "missed_targets")))  # fmt: skip
    FILE_FIELDS: ClassVar[dict] = {
        # (no tube: the ring's clearance is the tolerance; no look: the wire is drawn as it is)
        **{k: v for k, v in PathTask.FILE_FIELDS.items() if k not in ("tube_radius", "visual")},
        "ring_radius": Number(above=0.0),
        "wire_radius": Number(above=0.0),
    }
    FILE_REQUIRED = ("waypoints",)

    ring_radius: float = 0.004
    """Inner radius of the ring, m."""
    wire_radius: float = 0.0006
    """Radius of the wire, m."""

    def __post_init__(self) -> None:
        positive(self.name, "ring_radius", self.ring_radius)
        positive(self.name, "wire_radius", self.wire_radius)
        if self.wire_radius >= self.ring_radius:
            raise TaskError(f"task {self.name!r}: the wire (radius {self.wire_radius} m) must "
                            f"be thinner than the ring's hole ({self.ring_radius} m)")  # fmt: skip
        # The tube of the path kind's views is the ring's clearance.
        object.__setattr__(self, "tube_radius", self.clearance)
        super().__post_init__()

    @property
    def clearance(self) -> float:
        """Largest distance of the ring's centre to the wire's axis without contact, m."""
        return float(self.ring_radius - self.wire_radius)

    @property
    def SCORING(self) -> dict:  # noqa: N802 (the kind's declaration, from the geometry)
        """Scored: contact time (weight 2; 0 % at a third of the failing time), contacts
        (2; 0 % at 10), time (100 % the wire at 1 cm/s, 0 % at 2 mm/s), economy (100 % the
        wire's length, 0 % 3x), collisions (5), excessive force (5 s), out of view (the
        wire's length), master workspace (3x the wire's box diagonal over the motion
        scale). The 100 % values are our choice until an expert reference exists."""
        L = float(self.path.length)
        span = float(np.linalg.norm(np.ptp(self.waypoints, axis=0))) / self.teleop.scale
        t_fail = L / 0.002
        return {
            "metrics": {
                "contact_time": {"weight": 2.0, "fail": t_fail / 3.0, "expert": 0.0},
                "contact_count": {"weight": 2.0, "fail": 10.0, "expert": 0.0},
                "completion_time": {"weight": 1.0, "fail": t_fail, "expert": L / 0.01},
                "path_length": {"weight": 1.0, "fail": 3.0 * L, "expert": L},
                "instrument_collisions": {"weight": 1.0, "fail": 5.0, "expert": 0.0},
                "excessive_force": {"weight": 1.0, "fail": 5.0, "expert": 0.0},
                "out_of_view": {"weight": 1.0, "fail": L, "expert": 0.0},
                "master_workspace": {"weight": 1.0, "fail": 3.0 * span, "expert": span},
            }
        }

    def progress(self, state) -> str:
        """How far along the wire the ring has been, % of its length, while running."""
        if int(state.phase[0]) != Phase.RUNNING:
            return ""
        return f"{100.0 * float(state.progress[0]) / self.path.length:.0f} % of the wire"

    def summary(self, row: dict) -> str:
        return (f"{row['contact_count']} contacts, {row['contact_time']:.2f} s touching, "
                f"{row['completion_time']:.1f} s; back to the wire's start")  # fmt: skip

    # ------------------------------------------------------------ drawing
    def draw(self, spec, *, T_world_camera=None, prefix: str = "task/"):
        """The wire (a grey rod of ``wire_radius``) with a green post at its start and a red
        one at its end, and the ring on the task's PSM's wrist (visual only, it moves with
        the tool)."""
        T = np.eye(4) if self.frame == "world" else np.asarray(T_world_camera, dtype=float)
        path = self.path.transformed(T)
        body = VisualBody(spec.worldbody, "ring_walk", prefix)
        body.polyline("wire", path.vertices, self.wire_radius, (0.75, 0.75, 0.8, 1.0))
        right, up = viewer_axes(T_world_camera)
        for name, p, rgba in (("start", path.vertices[0], (0.2, 0.9, 0.3, 1.0)),
                              ("finish", path.vertices[-1], (0.95, 0.2, 0.2, 1.0))):  # fmt: skip
            body.sphere(name, p, 2.0 * self.wire_radius + 0.0008, rgba)
            body.number(f"{name}_label", 1 if name == "start" else 2,
                        p + 0.003 * (right + up), right, up, 0.004, rgba)  # fmt: skip
        try:
            wrist = spec.body(f"{self.teleop.psm}/wrist_yaw")
            site = spec.site(f"{self.teleop.psm}/tip")
        except Exception:  # a scene without the task's PSM: the wire alone
            wrist = site = None
        if wrist is not None and site is not None:
            ring = VisualBody(wrist, "ring_walk_ring", prefix)
            # The ring's axis along the tip frame's x (site quaternion w, x, y, z).
            w, x, y, z = np.asarray(site.quat, dtype=float)
            axis = np.array([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)])
            centre = np.asarray(site.pos, dtype=float)
            r = self.ring_radius + 0.0005
            ring.ring("ring", centre, axis, r, 0.0005, (1.0, 0.8, 0.1, 1.0), segments=20)
        return body.body

    # ------------------------------------------------------------ I/O
    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RingWalkTask:
        own = {k: data[k] for k in ("ring_radius", "wire_radius") if k in data}
        rest = {k: v for k, v in data.items() if k not in own}
        base = PathTask.from_dict.__func__(cls, rest)
        return dataclasses.replace(base, **own) if own else base

    def to_dict(self) -> dict[str, Any]:
        out = super().to_dict()
        out.pop("tube_radius", None)
        out.pop("visual", None)
        out["ring_radius"] = self.ring_radius
        out["wire_radius"] = self.wire_radius
        return out
