"""The peg-transfer board in the MuJoCo scene, and what the task reads of it each tick.

:func:`add_peg_board` adds to a scene's ``MjSpec`` a static board with pegs (and, for the
ICRA 2026 variant, a wall across its middle), all colliding like the environment
(:mod:`davinci_sim.model.contact` ``env``), and one free body per ring, ``<prefix>ring<i>``,
resting on its start peg. Rings are grasped by contact and friction only: each is a loop of
capsules (kind ``object``: condim 4, friction 1.0/0.02, the nearly hard 3 ms contacts that
the jaws' ``tool`` geoms also have; the scene gets MuJoCo's noslip solver), nothing welds or
attaches it to a jaw. A ring is light
(:data:`RING_DENSITY`, ≈ 0.5 g for the shipped size) and clears the pegs (its hole's radius
minus the peg's is several mm, so one jaw fits between peg and ring wall).

The free bodies add degrees of freedom after the scene's keyframes were made, so every
keyframe gets the rings' resting poses appended (their joints come last in ``qpos``).

:class:`PegProbe` is the task's view of the simulation at a tick: each ring's centre (task
frame) and which jaws touch it, read from MuJoCo's contacts (``data.contact``) — what the
task's pure state machine (:mod:`davinci_sim.tasks.peg`) turns into grasps, hand-offs,
drops and transfers — and the tips of every instrument the task uses (its economy of
motion).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

from davinci_sim.model import contact
from davinci_sim.model.shapes import set_inertial
from davinci_sim.tasks.objects_probe import ObjectsProbe

if TYPE_CHECKING:
    from davinci_sim.tasks.peg import PegTransferTask

#: Silicone rubber, kg/m³ (FLS and VR peg-transfer objects are rubber): 1.1-1.2 g/cm³.
RING_DENSITY = 1200.0
#: Noslip solver iterations of a scene with a board (see :func:`add_peg_board`).
NOSLIP_ITERATIONS = 10
BOARD_RGBA = (0.92, 0.92, 0.88, 1.0)
PEG_RGBA = (0.25, 0.25, 0.28, 1.0)
WALL_RGBA = (0.55, 0.75, 0.95, 0.85)
RING_RGBA = ((0.95, 0.35, 0.15, 1.0), (0.20, 0.75, 0.30, 1.0), (0.95, 0.80, 0.10, 1.0),
             (0.30, 0.45, 0.95, 1.0), (0.85, 0.25, 0.75, 1.0), (0.15, 0.80, 0.85, 1.0))  # fmt: skip


def ring_mass(radius: float, tube_radius: float) -> float:
    """Mass of a torus of centre-line ``radius`` and ``tube_radius`` (m) at
    :data:`RING_DENSITY`, kg."""
    return RING_DENSITY * 2.0 * np.pi * radius * np.pi * tube_radius**2


def ring_segments(radius: float, segments: int) -> np.ndarray:
    """(segments, 2, 3) end points of the capsules whose chain makes the ring, in the ring's
    frame (centre at the origin, in the z = 0 plane), m: a regular polygon of ``segments``
    sides whose vertices lie on the circle of ``radius``."""
    a = 2.0 * np.pi * np.arange(segments + 1) / segments
    pts = np.column_stack([radius * np.cos(a), radius * np.sin(a), np.zeros(len(a))])
    return np.stack([pts[:-1], pts[1:]], axis=1)


def _geom(body, kind: str, rgba, name: str = "", **kw):
    g = body.add_geom(name=name, **kw)
    contact.apply(g, kind)
    g.rgba = list(rgba)
    g.mass = 0.0
    return g


def add_peg_board(spec: mujoco.MjSpec, task: PegTransferTask, prefix: str = "task/"):
    """Add ``task``'s board, pegs, wall (if any) and rings to ``spec`` (see the module
    docstring); ``task`` is in the world frame. Returns the board's body."""
    box, capsule = mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_CAPSULE
    world = spec.worldbody
    top = task.board_top
    board = world.add_body(name=f"{prefix}board")
    cx, cy = task.board_center
    hx, hy = task.board_half_size
    t = task.board_thickness
    _geom(board, "env", BOARD_RGBA, f"{prefix}board", type=box, pos=[cx, cy, top - t / 2],
          size=[hx, hy, t / 2])  # fmt: skip
    # Legs down to the tissue (drawn only: the board stands over the pad and the organ).
    for sx in (-1, 1):
        for sy in (-1, 1):
            _geom(board, "visual", BOARD_RGBA, type=box,
                  pos=[cx + sx * (hx - 0.004), cy + sy * (hy - 0.004), top - t - 0.02],
                  size=[0.003, 0.003, 0.02])  # fmt: skip
    for i, (x, y) in enumerate(task.pegs):
        _geom(board, "env", PEG_RGBA, f"{prefix}peg{i + 1}", type=capsule,
              fromto=[x, y, top - t / 2, x, y, top + task.peg_height - task.peg_radius],
              size=[task.peg_radius, 0, 0])  # fmt: skip
    if task.wall:
        _geom(board, "env", WALL_RGBA, f"{prefix}wall", type=box,
              pos=[cx, cy, top + task.wall_height / 2],
              size=[task.wall_thickness / 2, hy, task.wall_height / 2])  # fmt: skip
    mass = ring_mass(task.ring_radius, task.ring_tube_radius)
    r = task.ring_tube_radius
    start = ring_start_qpos(task)
    for k in range(len(task.start_pegs)):
        body = world.add_body(name=f"{prefix}ring{k + 1}", pos=start[k, :3])
        body.add_freejoint(name=f"{prefix}ring{k + 1}")
        rgba = RING_RGBA[k % len(RING_RGBA)]
        for j, (a, b) in enumerate(ring_segments(task.ring_radius, task.ring_segments)):
            _geom(body, "object", rgba, f"{prefix}ring{k + 1}_{j}", type=capsule,
                  fromto=np.concatenate([a, b]), size=[r, 0, 0])  # fmt: skip
        # A thin torus: I_zz = m R² (about its axis), I_xx = I_yy = m R² / 2.
        R2 = task.ring_radius**2
        set_inertial(body, mass, [0, 0, 0], [mass * R2 / 2, mass * R2 / 2, mass * R2])
    _extend_keyframes(spec, start.ravel())
    # A ring squeezed between the two angled jaws (each ≈ 10° off the closing plane on a
    # 3 mm tube) is pushed towards the jaw tips; MuJoCo's soft friction lets it creep out
    # within a second (measured: lifted rings fell during a 1 s hold). The noslip solver
    # (MuJoCo's remedy for grasp slip) removes it: measured ≈ 0.4 mm of creep over a lift,
    # a 1 s hold and 5 cm and 3 cm moves. Only scenes with a board get it.
    spec.option.noslip_iterations = max(spec.option.noslip_iterations, NOSLIP_ITERATIONS)
    return board


def ring_start_qpos(task: PegTransferTask) -> np.ndarray:
    """(k, 7) each ring's free-joint pose at the start (world frame): lying flat on its
    start peg's foot, position (m) then the identity quaternion (w, x, y, z)."""
    z = task.board_top + task.ring_tube_radius
    return np.array([[x, y, z, 1.0, 0.0, 0.0, 0.0]
                     for x, y in (task.pegs[p] for p in task.start_pegs)], dtype=float)  # fmt: skip


def reset_rings(model: mujoco.MjModel, data: mujoco.MjData, task: PegTransferTask,
                prefix: str = "task/") -> None:  # fmt: skip
    """Put ``task``'s rings back on their start pegs (:func:`ring_start_qpos`) at rest in
    ``data``, and recompute the derived quantities (``mj_forward``); ValueError if the
    scene has no rings."""
    start = ring_start_qpos(task)
    for k in range(len(start)):
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{prefix}ring{k + 1}")
        if j < 0:
            raise ValueError(f"task {task.name!r}: the scene has no ring {k + 1} (draw the task)")
        q, v = model.jnt_qposadr[j], model.jnt_dofadr[j]
        data.qpos[q : q + 7] = start[k]
        data.qvel[v : v + 6] = 0.0
        data.qacc_warmstart[v : v + 6] = 0.0
    mujoco.mj_forward(model, data)


def _extend_keyframes(spec: mujoco.MjSpec, qpos_rings: np.ndarray) -> None:
    """Append the rings' free-joint poses to every keyframe's qpos (the rings' joints are
    the last in the model's qpos: their bodies are the last added to the world)."""
    if qpos_rings.size == 0:
        return
    for key in spec.keys:
        q = np.asarray(key.qpos, dtype=float)
        if q.size:
            key.qpos = np.concatenate([q, qpos_rings])


class PegProbe(ObjectsProbe):
    """Reads, at a tick, what :class:`~davinci_sim.tasks.peg.PegTransferTask` needs of the
    simulation (:class:`~davinci_sim.tasks.objects_probe.ObjectsProbe` of the rings): ring
    centres (world frame, m; the task is in the world frame) and, per ring, the bit mask of
    the jaws touching it — bit ``2·a + j`` for jaw ``j`` (0, 1) of the task's instrument
    ``a`` (index in ``task.instruments``).

    Args:
        model: the compiled model (with the task's board drawn).
        task: the task.
        prefix: the drawing's name prefix.
    """

    def __init__(self, model: mujoco.MjModel, task: PegTransferTask, prefix: str = "task/"):
        k = len(task.start_pegs)
        bodies = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"{prefix}ring{i + 1}")
                  for i in range(k)]  # fmt: skip
        if any(b < 0 for b in bodies):
            raise ValueError(f"task {task.name!r}: the scene has no rings (draw the task first)")
        try:
            super().__init__(model, bodies, task.instruments)
        except ValueError as e:
            raise ValueError(f"task {task.name!r}: {e}") from e

    def measure(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """``(objects (k, 3) ring centres, m; grasp (k,) jaw bit masks)`` now."""
        return data.xpos[self.bodies].copy(), self.grasps(data)
