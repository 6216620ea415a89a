"""The vector environment's reduced physics: the scene with fewer joints, the others welded
where they are at the episodes' start (``DavinciVectorEnv(physics=...)``).

* ``"psm"`` — the PSM and its setup joints; the ECM and its setup joints welded. Exact: the
  ECM's branch of the cart is a separate subtree that no action moves (its joints stay
  within 1e-18 of the start in the full scene), so the PSM's motion is the full scene's to
  rounding (24 → 14 degrees of freedom).
* ``"arm"`` — only the PSM's own joints (six and the jaw's two fingers); its setup joints
  welded too (24 → 8). Not exact: the setup joints are braked on the real cart and stiff
  servos here, but they yield by up to ~1e-4 (rad, m) under the arm's reaction while it
  moves, which the welded scene leaves out; the tool tip then differs from the full scene's
  by up to ~0.3 mm after 30 random actions (``tests/envs/test_reduced_physics.py`` states
  the tolerance it checks).

Every body, geom and contact stays (the PSM can still touch the endoscope). The welding
builds the scene's ``MjSpec`` again (the same scene, so the same bodies in the same
order), replaces each welded body's pose in its parent by the start's and deletes the
joints and their servo actuators. The result maps the reduced model's qpos, dofs and
actuators into the full model's (:class:`ReducedPhysics`), so that the vector environment
keeps its arrays in the full model's layout (the welded joints keep their start values).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from davinci_sim.model import build_spec


@dataclass(frozen=True)
class ReducedPhysics:
    """The reduced model, its start data, and where its entries are in the full model."""

    kept: tuple[str, ...]
    """The prefixes of the joints kept."""

    model: mujoco.MjModel
    data: mujoco.MjData
    """The start (the full start's kept joints; bodies where the full start has them)."""
    qpos: np.ndarray
    """(nq_reduced,) int: the full model's qpos address of each reduced qpos entry."""
    dof: np.ndarray
    """(nv_reduced,) int: the full model's dof address of each reduced dof."""
    actuator: np.ndarray
    """(nu_reduced,) int: the full model's actuator of each reduced actuator."""


def _pose_in_parent(model: mujoco.MjModel, data: mujoco.MjData, body: int):
    """(pos (3,) m, quat (4,) w x y z) of ``body`` in its parent body's frame in ``data``."""
    parent = model.body_parentid[body]
    R_world_parent = data.xmat[parent].reshape(3, 3)
    pos = R_world_parent.T @ (data.xpos[body] - data.xpos[parent])
    q_parent_inv = np.zeros(4)
    mujoco.mju_negQuat(q_parent_inv, data.xquat[parent])
    quat = np.zeros(4)
    mujoco.mju_mulQuat(quat, q_parent_inv, data.xquat[body])
    return pos, quat


def _colliding(model: mujoco.MjModel) -> int:
    """How many geoms can touch anything (contype or conaffinity set)."""
    return int(np.count_nonzero((model.geom_contype != 0) | (model.geom_conaffinity != 0)))


def reduce_to(
    scene, model: mujoco.MjModel, data: mujoco.MjData, keep: tuple[str, ...]
) -> ReducedPhysics:
    """Weld every joint of ``model`` (built from ``scene``) but those whose names start with
    one of ``keep`` (e.g. ``("PSM1/",)``) at their pose in ``data``; see the module
    docstring. Geoms only ``model`` has (a task's drawing) must
    not collide.

    Raises:
        ValueError: ``scene`` does not build ``model`` (a different number of joints or
            colliding geoms), no joint is kept, or an actuator has an
            activation state.
    """
    spec = build_spec(scene)
    keep = tuple(keep)
    # (a task's drawing adds bodies without joints and geoms that do not collide: the
    # rebuilt scene leaves them out, which the contacts' check below allows)
    if len(spec.joints) != model.njnt:
        raise ValueError("the scene does not build the model it should reduce")
    mujoco.mj_kinematics(model, data)  # (the bodies' poses of data's qpos)
    for body in spec.bodies:
        welded = [j for j in body.joints if not j.name.startswith(keep)]
        if not welded:
            continue
        body.pos, body.quat = _pose_in_parent(model, data, model.body(body.name).id)
        for joint in welded:
            spec.delete(joint)
    for actuator in list(spec.actuators):
        if not actuator.name.startswith(keep):
            spec.delete(actuator)
    for key in list(spec.keys):  # (sized for the full model)
        spec.delete(key)
    reduced = spec.compile()
    if reduced.njnt == 0:
        raise ValueError(f"no joint of the scene starts with {keep}")
    if reduced.na or _colliding(reduced) != _colliding(model):
        # (e.g. a task's drawing that collides: the rebuilt scene would lack it)
        raise ValueError("the reduced scene's contacts or actuators differ from the model's")
    reduced.opt.disableflags = model.opt.disableflags
    reduced.opt.enableflags = model.opt.enableflags
    names = [reduced.joint(i).name for i in range(reduced.njnt)]
    full = [model.joint(n).id for n in names]
    qpos = np.array([model.jnt_qposadr[j] for j in full])
    dof = np.array([model.jnt_dofadr[j] for j in full])
    actuator = np.array([model.actuator(reduced.actuator(i).name).id for i in range(reduced.nu)])
    d = mujoco.MjData(reduced)
    d.time = data.time
    d.qpos[:], d.qvel[:] = data.qpos[qpos], data.qvel[dof]
    d.ctrl[:] = data.ctrl[actuator]
    d.qacc_warmstart[:] = data.qacc_warmstart[dof]
    mujoco.mj_forward(reduced, d)
    return ReducedPhysics(keep, reduced, d, qpos, dof, actuator)


def kept_joints(physics: str, psm: str) -> tuple[str, ...]:
    """The joint-name prefixes ``physics`` (``"psm"`` or ``"arm"``) keeps for ``psm``."""
    if physics == "psm":
        return (f"{psm}/", f"SUJ/{psm}/")
    if physics == "arm":
        return (f"{psm}/",)
    raise ValueError(f"no reduced physics {physics!r}")
