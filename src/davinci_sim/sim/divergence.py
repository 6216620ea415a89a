"""Divergence recovery: an unstable step is undone and only the arms involved fault.

MuJoCo checks every step for NaN, inf or huge values (beyond ``mjMAXVAL`` = 1e10) in
``qpos``, ``qvel``, ``qacc`` and ``ctrl`` and reports them as warnings (``mjWARN_BADQPOS``,
``BADQVEL``, ``BADQACC``, ``BADCTRL``). By default it then resets the whole ``MjData`` to
``qpos0`` (auto-reset) or drops every actuator's ``ctrl`` for the step: in a scene of servoed
arms every arm and setup joint jumps, and all of them fault (issue 11: PSM1 and the four
setup-joint arms, the setup joints displaced until a restart).

Here the simulation turns auto-reset off and, every tick, keeps MuJoCo's integration state
as it was right before ``mj_step`` (``mj_getState``, ~1 µs). When a step raises one of those
warnings, the simulation tells which arms were involved (:func:`involved_arms`),
the simulation puts the physics back to the saved state (the clock still advances), stops
the joints of those arms, faults them with the reason on their ``error`` channel, and
ticks on: the other arms never see the unstable step.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import mujoco
import numpy as np

_log = logging.getLogger(__name__)

#: MuJoCo's bound for a "huge" value in its stability checks (``mjMAXVAL``).
MAX_VALUE = 1e10
_W = mujoco.mjtWarning
WARNINGS = {
    int(_W.mjWARN_BADQPOS): "position",
    int(_W.mjWARN_BADQVEL): "velocity",
    int(_W.mjWARN_BADQACC): "acceleration",
    int(_W.mjWARN_BADCTRL): "actuator control",
}
_STATE = mujoco.mjtState.mjSTATE_INTEGRATION


@dataclass(frozen=True)
class Owner:
    """What belongs to one arm: its joints' ``qvel`` addresses (dofs, with its jaw or
    gripper), its actuators, and the arm that carries it (its setup-joint arm), if any."""

    dofs: np.ndarray
    actuators: np.ndarray
    carrier: str | None = None


def arm_owners(arms: dict) -> dict[str, Owner]:
    """Each arm's dofs and actuators (with its jaw or gripper) and its carrier, for ``arms``
    (name -> :class:`~davinci_sim.sim.arm.Arm`)."""
    owners = {}
    for name, arm in arms.items():
        parts = [arm] + [getattr(arm, p) for p in ("jaw", "gripper") if hasattr(arm, p)]
        owners[name] = Owner(
            np.concatenate([p._dofadr for p in parts]),
            np.concatenate([p._idx for p in parts]),
            f"SUJ/{name}" if f"SUJ/{name}" in arms else None,
        )
    return owners


def _mujoco_warning(message: str) -> None:
    logging.getLogger("mujoco").warning("%s", message)


def _bad(x: np.ndarray) -> bool:
    """NaN, inf or beyond :data:`MAX_VALUE` (MuJoCo's test)."""
    return x.size > 0 and not bool((np.abs(x) <= MAX_VALUE).all())


def arms_with_bad(data: mujoco.MjData, owners: dict[str, Owner], fields) -> list[str]:
    """The arms with a bad value (:func:`_bad`) in any of ``fields`` of ``data``
    (``"ctrl"``: their actuators; ``"qpos"``, ``"qvel"``, ``"qacc"``: their joints)."""
    out = []
    for name, o in owners.items():
        for f in fields:
            if f == "ctrl":
                x = data.ctrl[o.actuators]
            elif f == "qpos":
                x = data.qpos[_qpos_of_joints(data.model, o.dofs)]
            else:
                x = getattr(data, f)[o.dofs]
            if _bad(x):
                out.append(name)
                break
    return out


def involved_arms(
    owners: dict[str, Owner],
    tripped: dict[str, int],
    bad_ctrl: list[str],
    bad_before: list[str],
    bad_after: list[str],
) -> tuple[str, ...]:
    """The arms a diverged step involves.

    ``tripped``: the warnings the step raised (name -> MuJoCo's ``lastinfo``, its first bad
    index); ``bad_ctrl``: arms whose own ``ctrl`` was bad (their command was: they are the
    ones); ``bad_before``: arms with a bad position or velocity before the step (written
    between ticks: the divergence starts there); ``bad_after``: arms with a bad value after
    the step. Of these, a setup-joint arm whose carried arm is there too is left out: it
    diverges because the arm it carries does (the two are one kinematic tree). If no arm
    shows a bad value, the arm owning MuJoCo's first bad index.
    """
    if bad_ctrl:
        return tuple(bad_ctrl)
    if bad_before:
        return tuple(bad_before)
    carried = {owners[n].carrier for n in bad_after}
    arms = [n for n in bad_after if n not in carried]
    if not arms and tripped:
        if "actuator control" in tripped:
            first, key = tripped["actuator control"], "actuators"
        else:
            first, key = next(iter(tripped.values())), "dofs"
        arms = [n for n, o in owners.items() if first in getattr(o, key)]
    return tuple(arms)


#: Ticks in a row whose steps diverged after which the objects (the joints no arm owns:
#: needles, rings, the skin) are stopped with the arms involved, and after which they are
#: also put back at the model's ``qpos0``: restoring the previous tick alone repeats a
#: divergence the state itself causes, tick after tick.
OBJECTS_STOPPED_AFTER = 2
OBJECTS_RESET_AFTER = 3


def object_dofs(model: mujoco.MjModel, owners: dict[str, Owner]) -> np.ndarray:
    """The dofs no arm owns (free objects, the skin's vertices), sorted."""
    owned = [o.dofs for o in owners.values()]
    return np.setdiff1d(np.arange(model.nv), np.concatenate(owned) if owned else [])


def _qpos_of_joints(model: mujoco.MjModel, dofs: np.ndarray) -> np.ndarray:
    """Every ``qpos`` address of the joints of ``dofs`` (a free joint's 7, a ball's 4)."""
    size = {int(mujoco.mjtJoint.mjJNT_FREE): 7, int(mujoco.mjtJoint.mjJNT_BALL): 4}
    joints = np.unique(model.dof_jntid[dofs])
    parts = [model.jnt_qposadr[j] + np.arange(size.get(int(model.jnt_type[j]), 1))
             for j in joints]  # fmt: skip
    return np.concatenate(parts) if parts else np.zeros(0, dtype=int)


class DivergenceGuard:
    """Keeps the last good integration state and watches MuJoCo's stability warnings.

    Turns MuJoCo's auto-reset off on ``model`` (the state before the bad step is what the
    simulation restores, and the bad values tell which arms were involved)."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
        if mujoco.get_mju_user_warning() is None:
            # MuJoCo's own warnings go to the log (logger "mujoco"), not to its default
            # handler, which prints them and appends them to MUJOCO_LOG.TXT in the current
            # directory. (Process-wide; a handler someone installed is kept.)
            mujoco.set_mju_user_warning(_mujoco_warning)
        self._model = model
        self._state = np.empty(mujoco.mj_stateSize(model, _STATE))
        self._warnings = data.warning
        # The four counters, kept: live views of data's memory (a lookup each tick costs
        # four times more).
        self._stats = tuple(data.warning[i] for i in WARNINGS)
        self._seen = self._counts()
        self.recoveries = 0
        """How many diverged steps were undone."""
        self.streak = 0
        """How many ticks in a row the last diverged steps were (1: the last one alone)."""
        self._last_time = -np.inf

    def _counts(self) -> tuple[int, ...]:
        a, b, c, d = self._stats  # every tick: no generator
        return (a.number, b.number, c.number, d.number)

    def save(self, data: mujoco.MjData) -> None:
        """Keep ``data``'s integration state (call right before ``mj_step``)."""
        mujoco.mj_getState(self._model, data, self._state, _STATE)

    def sync(self) -> None:
        """Take the warning counts as they are now (after a restore of a whole state)."""
        self._seen = self._counts()

    def tripped(self) -> dict[str, int]:
        """The stability warnings raised since the last call or :meth:`sync` (name ->
        ``lastinfo``), empty if none (the common case: one tuple comparison)."""
        counts = self._counts()
        if counts == self._seen:
            return {}
        out = {
            name: self._warnings[i].lastinfo
            for (i, name), now, before in zip(WARNINGS.items(), counts, self._seen, strict=True)
            if now != before
        }
        self._seen = counts
        return out

    def rewind(self, data: mujoco.MjData) -> None:
        """Put ``data``'s integration state back to the saved one, keeping its clock (the
        derived quantities are stale until :meth:`settle`)."""
        time = data.time
        mujoco.mj_setState(self._model, data, self._state, _STATE)
        data.time = time

    def settle(self, data: mujoco.MjData, stop_dofs: np.ndarray) -> None:
        """After :meth:`rewind`: zero the velocities of ``stop_dofs`` and any velocity still
        bad; a position still bad (written between ticks) goes back to the model's
        ``qpos0``; recompute the derived quantities (``mj_forward``)."""
        data.qvel[stop_dofs] = 0.0
        data.qvel[~(np.abs(data.qvel) <= MAX_VALUE)] = 0.0
        bad_q = ~(np.abs(data.qpos) <= MAX_VALUE)
        data.qpos[bad_q] = self._model.qpos0[bad_q]
        data.qacc_warmstart[:] = 0.0
        mujoco.mj_forward(self._model, data)
        self.recoveries += 1
        self.sync()

    def recover(
        self, data: mujoco.MjData, owners: dict[str, Owner], tripped: dict[str, int]
    ) -> tuple[tuple[str, ...], str]:
        """Undo the step that raised ``tripped`` (:meth:`tripped`): rewind, find the arms
        involved (:func:`involved_arms`), stop their joints and settle. Returns those arms
        and the reason to give them."""
        bad_ctrl = arms_with_bad(data, owners, ("ctrl",))
        bad_after = arms_with_bad(data, owners, ("qpos", "qvel", "qacc"))
        dt = self._model.opt.timestep
        since = data.time - self._last_time  # (a restored state can put the clock back)
        self.streak = self.streak + 1 if 0.0 < since <= 1.5 * dt else 1
        self._last_time = data.time
        self.rewind(data)
        bad_before = arms_with_bad(data, owners, ("qpos", "qvel"))
        arms = involved_arms(owners, tripped, bad_ctrl, bad_before, bad_after)
        stop = [owners[a].dofs for a in arms]
        # The same step diverging again from the restored state (a needle squeezed between
        # two grips): the free objects are stopped, then put back where they started.
        then = ""
        if self.streak >= OBJECTS_STOPPED_AFTER:
            objects = object_dofs(self._model, owners)
            stop.append(objects)
            then = "; the objects stopped"
            if self.streak >= OBJECTS_RESET_AFTER:
                q = _qpos_of_joints(self._model, objects)
                data.qpos[q] = self._model.qpos0[q]
                then = "; the objects put back where the model starts them"
        self.settle(data, np.concatenate(stop) if stop else np.zeros(0, dtype=int))
        what = ", ".join(tripped)
        if self.streak <= OBJECTS_RESET_AFTER or self.streak % 1000 == 0:
            _log.warning(
                "t = %.3f s: the physics diverged (MuJoCo: bad %s; involved: %s); restored "
                "to the previous tick%s%s",
                data.time, what, ", ".join(arms) or "no arm", then,
                f" ({self.streak} ticks in a row)" if self.streak > 1 else "",
            )  # fmt: skip
        reason = (
            f"the simulation diverged (MuJoCo: bad {what} values on this arm's joints); "
            "the physics was restored to the previous tick and the joints stopped"
        )
        return arms, reason
