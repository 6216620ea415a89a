"""The metrics trainers score an attempt by, declared once for every kind of task.

The VR robotic-surgery simulators (da Vinci Skills Simulator, Mimic dV-Trainer, Hugo RAS)
report each attempt on a fixed set of metrics with units (the project's reference notes,
training.md §1). This module declares those that the existing task metrics do not already
give, as :class:`~davinci_sim.tasks.metrics.Metric` values a kind adds to its ``METRICS``
(:func:`trainer_metrics`); the other two are the path kind's own declarations, reused:

========================  ======  ================================================================
metric                    unit    definition (over the samples of the repetition)
========================  ======  ================================================================
``completion_time``       s       time to complete: t_K − t_1 (:data:`PATH_METRICS`)
``path_length``           m       economy of motion: Σ ‖p_i − p_{i−1}‖ of the tool tip (shown in cm)
``instrument_collisions`` 1       onsets of instrument contact: pairs (i−1, i) with no contact at
                                  i−1 and ≥ 1 at i (``Sample.contacts``)
``excessive_force``       s       Σ (t_i − t_{i−1}) over pairs whose sample i has a contact force on
                                  the instrument above the threshold (``Sample.tool_force``; the
                                  threshold: the task's scoring, ``force_threshold``, N)
``out_of_view``           m       Σ ‖p_i − p_{i−1}‖ over pairs whose sample i is outside the left
                                  endoscope image (``Sample.visible``; shown in cm)
``master_workspace``      m       diagonal of the box the master handle positions span, HRSV
                                  (‖max_i x_i − min_i x_i‖ per axis; ``Sample.master``; shown in cm)
``drops``                 1       objects dropped: Σ of the task's ``dropped`` observation (a count
                                  per sample; 0 for a kind without objects)
``missed_targets``        1       targets missed: Σ of the task's ``missed`` observation; the path
                                  kind counts instead the numbered points 2..N−1 the tip never came
                                  within ``tube_radius`` of (:data:`PATH_MISSED_TARGETS`)
========================  ======  ================================================================

The master workspace range is a box diagonal, not the diameter of the set of positions: a
box is kept from sample to sample (the diameter needs every pair), lies between the
diameter and √3 times it, and equals it for motion along one line.

Collisions are MuJoCo's contacts (:class:`InstrumentContacts`): of the task's instruments
(its PSM's and, in a two-handed task, the other's) with the table, the patient, the objects
of other tasks, and another arm (its instrument included) or the endoscope (the model makes
instruments of different arms collide, :mod:`davinci_sim.model.contact`; a clash of
instruments is counted). Metrics read
optional sample fields (``Metric.needs``): an engine that does not sample one gives nan
for the metric (unavailable), never a made-up 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from davinci_sim.tasks.metrics import (
    PATH_METRICS,
    Metric,
    PairSum,
    _always,
    _float_acc,
    observed,
)

if TYPE_CHECKING:
    import mujoco

#: Contact force above which the instrument's force is *excessive*, N, when the task's
#: scoring does not say: our assumption (no simulator publishes its threshold), of the
#: order of the 2-5 N tool-tissue forces at which retraction starts to injure tissue.
DEFAULT_FORCE_THRESHOLD = 2.0


def force_threshold(task) -> float:
    """The excessive-force threshold of ``task`` (its scoring's), N."""
    scoring = getattr(task, "scoring", None)
    return float(getattr(scoring, "force_threshold", DEFAULT_FORCE_THRESHOLD))


# ---------------------------------------------------------------- reducers
@dataclass(frozen=True)
class Extent:
    """‖max_i x_i − min_i x_i‖ of a per-sample point x_i (n, 3): the diagonal of the box
    the points span (0 with fewer than one sample)."""

    value: object
    """``value(task, sample, obs) -> (n, 3)``."""

    unchanged_unmeasured = staticmethod(_always)  # (MetricsAccumulator.update)

    def init(self, n: int, task=None):
        return (np.full((n, 3), np.inf), np.full((n, 3), -np.inf))

    def add(self, acc, m, pair, task, prev, s, obs):
        lo, hi = acc
        x = self.value(task, s, obs)
        mm = m[:, None]
        return (np.where(mm, np.minimum(lo, x), lo), np.where(mm, np.maximum(hi, x), hi))

    def final(self, acc, k, done):
        lo, hi = acc
        span = np.where(np.isfinite(hi - lo), hi - lo, 0.0)
        return np.linalg.norm(span, axis=1)


@dataclass(frozen=True)
class Sum:
    """Σ value_i over the repetition's samples (e.g. events the task observes); integer
    when ``integer``."""

    value: object
    """``value(task, sample, obs) -> (n,)``."""
    integer: bool = False

    unchanged_unmeasured = staticmethod(_float_acc)  # (MetricsAccumulator.update)

    def init(self, n: int, task=None):
        return np.zeros(n, dtype=np.int64 if self.integer else float)

    def add(self, acc, m, pair, task, prev, s, obs):
        return acc + np.where(m, self.value(task, s, obs), 0)

    def final(self, acc, k, done):
        return acc.copy()


@dataclass(frozen=True)
class Unreached:
    """Targets the tip never came within a tolerance of: ``targets(task)`` (k, 3) in the
    task's frame, m; ``tolerance(task)``, m. (n, k) flags, kept from sample to sample."""

    targets: object
    tolerance: object

    unchanged_unmeasured = staticmethod(_always)  # (MetricsAccumulator.update)

    def init(self, n: int, task=None):
        k = 0 if task is None else len(self.targets(task))
        return np.zeros((n, k), dtype=bool)

    def add(self, acc, m, pair, task, prev, s, obs):
        pts = np.asarray(self.targets(task), dtype=float).reshape(-1, 3)
        d = np.linalg.norm(s.tip[:, None, :] - pts[None, :, :], axis=2)
        return acc | (m[:, None] & (d <= self.tolerance(task)))

    def final(self, acc, k, done):
        return (~acc).sum(axis=1).astype(np.int64)


# ---------------------------------------------------------------- values
def _contact_onset(task, prev, s, obs):
    return (s.contacts > 0) & ~(prev.contacts > 0)


def _over_force(task, prev, s, obs):
    return np.where(s.tool_force > force_threshold(task), s.time - prev.time, 0.0)


def _unseen_step(task, prev, s, obs):
    return np.where(s.visible, 0.0, np.linalg.norm(s.tip - prev.tip, axis=1))


def _master(task, s, obs):
    return s.master


_BY_NAME = {m.name: m for m in PATH_METRICS}

#: Time to complete and economy of motion: the path kind's declarations (shown in s, cm).
TIME = _BY_NAME["completion_time"]
ECONOMY = _BY_NAME["path_length"]

INSTRUMENT_COLLISIONS = Metric(
    "instrument_collisions", "1", "lower",
    "contacts of the instruments with the scene (onsets)",
    PairSum(_contact_onset, True), integer=True, label="collisions", needs=("contacts",),
)  # fmt: skip
EXCESSIVE_FORCE = Metric(
    "excessive_force", "s", "lower",
    "time the instrument's contact force is above the threshold (force_threshold, N)",
    PairSum(_over_force), label="excessive force", needs=("tool_force",),
)  # fmt: skip
OUT_OF_VIEW = Metric(
    "out_of_view", "m", "lower",
    "distance the tool tip travels outside the left endoscope image",
    PairSum(_unseen_step), label="out of view", display=("cm", 100.0), needs=("visible",),
)  # fmt: skip
MASTER_WORKSPACE = Metric(
    "master_workspace", "m", "lower",
    "diagonal of the box the master handle positions span (HRSV)",
    Extent(_master), label="master workspace", display=("cm", 100.0), needs=("master",),
)  # fmt: skip
DROPS = Metric(
    "drops", "1", "lower", "objects dropped (0 for a task without objects)",
    Sum(observed("dropped"), True), integer=True,
)  # fmt: skip
MISSED_TARGETS = Metric(
    "missed_targets", "1", "lower", "targets missed (the task's 'missed' observations)",
    Sum(observed("missed"), True), integer=True, label="missed targets",
)  # fmt: skip
#: The path kind's missed targets: numbered points 2..N−1 never within ``tube_radius``.
PATH_MISSED_TARGETS = Metric(
    "missed_targets", "1", "lower",
    "numbered points 2..N-1 the tip never came within tube_radius of",
    Unreached(lambda task: task.markers[1:-1], lambda task: task.tube_radius),
    integer=True, label="missed targets",
)  # fmt: skip

#: The trainer metrics a kind adds to its own (time and economy are usually among its own).
TRAINER_METRICS: tuple[Metric, ...] = (
    INSTRUMENT_COLLISIONS, EXCESSIVE_FORCE, OUT_OF_VIEW, MASTER_WORKSPACE, DROPS, MISSED_TARGETS,
)  # fmt: skip


def trainer_metrics(*, replace: tuple[Metric, ...] = (), leave_out=()) -> tuple[Metric, ...]:
    """:data:`TRAINER_METRICS` with the kind's own declarations of some of them (same
    ``name``) in their place, and without those named in ``leave_out``."""
    own = {m.name: m for m in replace}
    return tuple(own.get(m.name, m) for m in TRAINER_METRICS if m.name not in set(leave_out))


# ---------------------------------------------------------------- contacts
def task_instruments(task) -> tuple[str, ...]:
    """The PSMs whose instruments ``task`` uses: its teleoperated PSM, then its other
    instruments (peg transfer's, the needle exercises')."""
    return tuple(dict.fromkeys((task.teleop.psm, *getattr(task, "instruments", ()))))


class InstrumentContacts:
    """The contacts of the instruments of ``psms`` (each the bodies from ``<psm>/roll``
    down: shaft, wrist, jaws) with anything but their own arm (another instrument, its arm
    and the endoscope included) and the bodies named with one of ``ignore`` (prefixes, e.g.
    the objects a task grasps): their number and total normal force, N, at the current
    state of ``data``. A clash of two of the instruments is one contact.

    Args:
        model: the compiled model.
        psms: the arm's name (``PSM1``) or several (a two-handed task's instruments).
        ignore: body-name prefixes whose contacts with the instrument are not collisions.
    """

    def __init__(self, model: mujoco.MjModel, psms: str | tuple[str, ...],
                 ignore: tuple[str, ...] = ()) -> None:  # fmt: skip
        import mujoco

        psms = (psms,) if isinstance(psms, str) else tuple(psms)
        names = [model.body(i).name for i in range(model.nbody)]
        tool_of = np.full(model.nbody, -1, dtype=np.intp)
        arm_of = np.full(model.nbody, -1, dtype=np.intp)
        for k, psm in enumerate(psms):
            arm_of[[n.startswith(f"{psm}/") for n in names]] = k
            root = names.index(f"{psm}/roll") if f"{psm}/roll" in names else None
            if root is None:
                continue
            for i in range(model.nbody):  # parents come before children in MuJoCo's order
                if i == root or (i > 0 and tool_of[model.body_parentid[i]] == k):
                    tool_of[i] = k
        ignored = np.array([bool(ignore) and n.startswith(tuple(ignore)) for n in names])
        # One more entry for a contact's geom −1: a flex's side of a contact (the suture
        # pad's skin is what the instruments work on, not a collision).
        self.tool_of = np.append(tool_of[model.geom_bodyid], -1)
        """(ngeom + 1,) the instrument (index into ``psms``) a geom belongs to, or −1."""
        self.arm_of = np.append(arm_of[model.geom_bodyid], -1)
        """(ngeom + 1,) the arm of ``psms`` a geom belongs to, or −1."""
        self.counts = np.append(~ignored[model.geom_bodyid], False)
        """(ngeom + 1,) geoms whose contact with an instrument of another arm counts."""
        self.tool_geom = self.tool_of >= 0
        """(ngeom + 1,) geoms of an instrument (the compiled ticks' watch)."""
        self.other_geom = self.counts & (self.arm_of < 0 if len(psms) == 1 else True)
        """(ngeom + 1,) geoms whose contact with an instrument may count (with several
        instruments a superset: their own arms' too, which :meth:`measure` leaves out)."""
        self._force = np.zeros(6)
        self._contact_force = mujoco.mj_contactForce

    def measure(self, model: mujoco.MjModel, data: mujoco.MjData) -> tuple[int, float]:
        """(contacts, total normal force, N) of the instruments at ``data``'s state."""
        ncon = data.ncon
        if ncon == 0:
            return 0, 0.0
        g = data.contact.geom[:ncon]
        tool = self.tool_of[g]  # (ncon, 2)
        if not (tool >= 0).any():  # (the usual case: contacts elsewhere in the scene)
            return 0, 0.0
        arm, counts = self.arm_of[g], self.counts[g]
        hit = ((tool[:, 0] >= 0) & (arm[:, 1] != tool[:, 0]) & counts[:, 1]) | (
            (tool[:, 1] >= 0) & (arm[:, 0] != tool[:, 1]) & counts[:, 0]
        )
        force = 0.0
        for i in np.flatnonzero(hit).tolist():
            self._contact_force(model, data, i, self._force)
            force += abs(float(self._force[0]))  # normal component, contact frame
        return int(hit.sum()), force

    @classmethod
    def of_task(cls, model: mujoco.MjModel, task) -> InstrumentContacts:
        """The contacts ``task`` meters: of its PSM's instrument and its other instruments'
        (a two-handed task's: PSM2's collisions count too), its objects left out."""
        return cls(model, task_instruments(task), task.CONTACT_IGNORE)

    def measure_rows(self, models, datas, rows, n_contacts, contact_force) -> None:
        """:meth:`measure` of the simulations ``rows`` (indices into ``models``/``datas``)
        into ``n_contacts`` and ``contact_force`` (a batch of trials after a step), reading
        only a step that has contacts or rows that had some."""
        for i in rows.tolist():
            d = datas[i]
            if d.ncon:  # (the study scene has no patient: usually none)
                n_contacts[i], contact_force[i] = self.measure(models[i], d)
            elif n_contacts[i]:
                n_contacts[i], contact_force[i] = 0, 0.0
