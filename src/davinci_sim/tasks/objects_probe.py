"""What the kinds with free objects read of the simulation at a tick (peg transfer's rings,
the needle): :class:`ObjectsProbe` and its :class:`ObjectsReading`.

A reading is each object body's pose (world frame, m), the bit mask of the jaws touching
each object — bit ``2·a + j`` for jaw ``j`` (0, 1) of instrument ``a`` — every
instrument's tip (world frame, m) and, for a probe of a flex (the suture pad's skin), the
total normal force of the contacts with it (N). The live tick reads it from ``mjData`` with
:meth:`ObjectsProbe.read`; the console's compiled ticks (:mod:`davinci_sim.console.chunk`)
read the same numbers after each of their steps from the probe's tables
(:attr:`~ObjectsProbe.bodies`, :attr:`~ObjectsProbe.object_of`,
:attr:`~ObjectsProbe.jaw_bit`, :attr:`~ObjectsProbe.tips`, :attr:`~ObjectsProbe.flex`), so a
kind makes its sample's fields from a reading either way
(:meth:`~davinci_sim.tasks.base.Task.objects_fields`).
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np


class ObjectsReading(NamedTuple):
    """The objects at a tick (k objects, A instruments)."""

    xpos: np.ndarray
    """(k, 3) each object body's origin, world frame, m."""
    xmat: np.ndarray
    """(k, 9) each object body's orientation, world frame (row-major rotation matrix)."""
    grasp: np.ndarray
    """(k,) int64: the jaws touching each object (bit ``2·a + j``)."""
    tips: np.ndarray
    """(A, 3) the instruments' tips, world frame, m."""
    flex_force: float = 0.0
    """Total normal force of the contacts with the probe's flex, N (0 without one)."""


class ObjectsProbe:
    """Reads :class:`ObjectsReading` for the bodies ``bodies`` (ids, one per object; every
    geom of an object's body is the object) and the jaws and tips of ``instruments`` (PSM
    names; ``<psm>/jaw_1``, ``<psm>/jaw_2``, ``<psm>/tip``). ValueError if the scene has
    no such jaws or tips.

    ``flex``: the name of a flex (the suture pad's skin) whose contacts' total normal force
    the reading sums (None: none); ValueError if the scene has no such flex."""

    def __init__(self, model: mujoco.MjModel, bodies, instruments, *,
                 flex: str | None = None) -> None:  # fmt: skip
        self.bodies = np.array(bodies, dtype=np.intp).reshape(-1)
        # geom -> object index (or -1); geom -> jaw bit (or 0); one more entry for a
        # contact's geom −1 (a flex's side): neither
        self.object_of = np.full(model.ngeom + 1, -1, dtype=np.intp)
        index = {int(b): i for i, b in enumerate(self.bodies)}
        for g in range(model.ngeom):
            self.object_of[g] = index.get(int(model.geom_bodyid[g]), -1)
        self.jaw_bit = np.zeros(model.ngeom + 1, dtype=np.int64)
        for a, psm in enumerate(instruments):
            for j in (0, 1):
                gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{psm}/jaw_{j + 1}")
                if gid < 0:
                    raise ValueError(f"the scene has no {psm} jaws")
                self.jaw_bit[gid] = 1 << (2 * a + j)
        self.tips = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{p}/tip")
                              for p in instruments], dtype=np.intp)  # fmt: skip
        """(A,) the instruments' tip sites."""
        if np.any(self.tips < 0):
            raise ValueError(f"the scene has no tips of {list(instruments)}")
        self.flex = -1
        """The flex whose contacts' force the reading sums (its id; −1: none)."""
        if flex is not None:
            self.flex = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_FLEX, flex)
            if self.flex < 0:
                raise ValueError(f"the scene has no flex {flex!r} (draw the task first)")
        self._model = model
        self._f6 = np.zeros(6)

    def grasps(self, data: mujoco.MjData) -> np.ndarray:
        """(k,) int64: the jaws touching each object now (bit masks)."""
        grasp = np.zeros(len(self.bodies), dtype=np.int64)
        ncon = data.ncon
        if ncon:
            g = data.contact.geom[:ncon]
            for a, b in ((g[:, 0], g[:, 1]), (g[:, 1], g[:, 0])):
                obj, bit = self.object_of[a], self.jaw_bit[b]
                hit = (obj >= 0) & (bit > 0)
                np.bitwise_or.at(grasp, obj[hit], bit[hit])
        return grasp

    def tool_tips(self, data: mujoco.MjData) -> np.ndarray:
        """(A, 3) the instruments' tips now, world frame, m."""
        return data.site_xpos[self.tips].copy()

    def flex_force(self, data: mujoco.MjData) -> float:
        """Total normal force of the contacts with the probe's flex now, N (0 without one):
        each contact's normal component (``mj_contactForce``, contact frame), in the
        contacts' order."""
        ncon = data.ncon
        if self.flex < 0 or not ncon:
            return 0.0
        hit = np.flatnonzero((data.contact.flex[:ncon] == self.flex).any(axis=1))
        total = 0.0
        for i in hit.tolist():
            mujoco.mj_contactForce(self._model, data, i, self._f6)
            total += abs(float(self._f6[0]))
        return total

    def read(self, data: mujoco.MjData) -> ObjectsReading:
        """The objects now (``data``: of the probe's model)."""
        return ObjectsReading(data.xpos[self.bodies].copy(), data.xmat[self.bodies].copy(),
                              self.grasps(data), self.tool_tips(data),
                              self.flex_force(data))  # fmt: skip


def frame_of(xpos: np.ndarray, xmat: np.ndarray) -> np.ndarray:
    """A body's frame (4×4) from its origin ``xpos`` (3,) and row-major ``xmat`` (9,)."""
    T = np.eye(4)
    T[:3, :3] = xmat.reshape(3, 3)
    T[:3, 3] = xpos
    return T
