"""The simulation state contract: one value that saves, and puts back, everything that
changes while the simulation ticks.

:class:`SimState` (from :meth:`Simulation.get_state
<davinci_sim.sim.simulation.Simulation.get_state>`) holds

- MuJoCo's state: ``physics``, the integration state (``mj_getState`` with
  ``mjSTATE_INTEGRATION``: time, qpos, qvel, act, warm start, ctrl, applied forces, mocap,
  equality activations), and ``data``, a copy of the whole ``MjData``. The copy is what
  :meth:`Simulation.set_state` restores (``mj_copyData``): between two ticks the loop reads
  quantities the last ``mj_step`` computed at the start of that step (the servo's
  ``qfrc_bias``, the hand body's ``xipos``, contacts), and ``mj_forward`` at the restored
  positions would compute them at the new positions instead, so stepping on would not be
  bit-identical. ``physics`` is the compact, documented part (for comparisons and
  records);
- the simulation's own: tick count, the random generator's state, the encoder-noise sample,
  the joint servo's references and gains, the memo of the base frames (exact: the frames
  of the restored joints);
- every arm's (:meth:`Arm.get_state <davinci_sim.sim.arm.Arm.get_state>`) and every
  component's ``get_state()``, in tick order.

A state belongs to a scene: ``signature`` names the compiled model's sizes and names, and a
simulation of another scene refuses it.

Classes write their ``get_state``/``set_state`` explicitly; :func:`capture` and
:func:`restore` do the copying for the attributes they name, and refuse anything that is not
plain data (numbers, strings, arrays, frozen values and containers of them), so a reference
to a live object (the simulation, a device) cannot slip into a state and be deep-copied.
"""

from __future__ import annotations

import copy
import dataclasses
import enum
import hashlib
from collections import deque
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

#: What ``physics`` holds (``mj_getState``): the full physics state and the user inputs.
STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION


@dataclass(frozen=True)
class SimState:
    """Everything of a :class:`~davinci_sim.sim.simulation.Simulation` that changes while it
    ticks (see the module docstring). Treat it as immutable: ``set_state`` copies from it."""

    signature: str
    """The scene's model (sizes and names); a state is only restored into the same."""
    physics: np.ndarray
    """``mj_getState(model, data, mjSTATE_INTEGRATION)`` (read-only)."""
    data: mujoco.MjData
    """A copy of the simulation's ``MjData`` (derived quantities as the last step left them)."""
    tick_count: int
    rng: dict
    """``rng.bit_generator.state``."""
    noisy_qpos: np.ndarray | None
    """The encoder-noise sample of the last tick (None without encoder noise)."""
    servo: dict
    """The joint servo's references, masks and gains (``JointServo`` attributes)."""
    base_frames: dict
    """The simulation's base-frame memo (``Simulation._base_frames``)."""
    arms: dict
    """Arm name -> that arm's ``get_state()``."""
    components: tuple
    """``(name, component.get_state())`` in tick order."""

    @property
    def time(self) -> float:
        """Sim time of the state, s."""
        return float(self.data.time)


def model_signature(model: mujoco.MjModel) -> str:
    """A digest of the model's sizes, time step and body/joint/actuator/geom names: equal
    for two compilations of the same scene, different for another scene or task drawing."""
    h = hashlib.sha1()
    sizes = [getattr(model, n) for n in ("nq", "nv", "nu", "na", "nbody", "njnt", "ngeom")]
    sizes += [getattr(model, n) for n in ("nsite", "nmocap", "nuserdata", "nsensordata")]
    sizes += [model.narena, model.nbuffer]
    h.update(repr((sizes, float(model.opt.timestep))).encode())
    for obj, n in (
        (mujoco.mjtObj.mjOBJ_BODY, model.nbody),
        (mujoco.mjtObj.mjOBJ_JOINT, model.njnt),
        (mujoco.mjtObj.mjOBJ_ACTUATOR, model.nu),
        (mujoco.mjtObj.mjOBJ_GEOM, model.ngeom),
    ):
        h.update("\0".join(mujoco.mj_id2name(model, obj, i) or "" for i in range(n)).encode())
    return h.hexdigest()


def describe_scene(model: mujoco.MjModel) -> str:
    """A short human description of a model for error messages."""
    return f"{model.nbody} bodies, {model.njnt} joints, {model.nu} actuators, {model.ngeom} geoms"


class Unavailable:
    """Stands for a component's state that could not be taken (reported on restore)."""

    def __init__(self, reason: str) -> None:
        self.reason = reason

    def __repr__(self) -> str:
        return f"<state unavailable: {self.reason}>"


def component_states(components: dict, *, strict: bool) -> tuple:
    """``(name, component.get_state())`` of ``components`` in order. ``strict``: raise
    TypeError for a component without ``get_state``; else put an :class:`Unavailable` in its
    place (also when ``get_state`` fails), for the state :meth:`Simulation.reset` keeps,
    taken at the first tick, which must not fail because of it."""
    states = []
    for name, component in components.items():
        get_state = getattr(component, "get_state", None)
        if get_state is None:
            if strict:
                raise TypeError(
                    f"component {name!r} ({type(component).__name__}) has no get_state(): "
                    "its state cannot be saved (see davinci_sim.sim.component)"
                )
            states.append((name, Unavailable("it has no get_state()")))
        elif strict:
            states.append((name, get_state()))
        else:
            try:
                states.append((name, get_state()))
            except Exception as e:  # noqa: BLE001 - reported by reset()/set_state
                states.append((name, Unavailable(f"get_state() failed: {e!r}")))
    return tuple(states)


# ---------------------------------------------------------------- plain-data copies
_ATOMS = (type(None), bool, int, float, complex, str, bytes, np.generic, enum.Enum)


def check_plain(value: Any, where: str) -> None:
    """Raise TypeError unless ``value`` is plain data: None, numbers, strings, enums, numpy
    arrays (not of objects), frozen dataclasses and tuples, lists, deques, dicts and sets of
    plain data. ``where`` names the value in the message."""
    if isinstance(value, _ATOMS):
        return
    if isinstance(value, np.ndarray):
        if value.dtype == object:
            raise TypeError(f"{where}: an array of objects is not plain state data")
        return
    if isinstance(value, tuple | list | deque | set | frozenset):
        for i, v in enumerate(value):
            check_plain(v, f"{where}[{i}]")
        return
    if isinstance(value, dict):
        for k, v in value.items():
            check_plain(k, f"{where} key")
            check_plain(v, f"{where}[{k!r}]")
        return
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        if not value.__dataclass_params__.frozen:
            raise TypeError(f"{where}: {type(value).__name__} is a mutable dataclass")
        for f in dataclasses.fields(value):
            check_plain(getattr(value, f.name), f"{where}.{f.name}")
        return
    raise TypeError(
        f"{where}: {type(value).__name__} is not plain state data (a live object must be "
        "saved by its own get_state, not copied)"
    )


def capture(obj: object, names: tuple[str, ...]) -> dict[str, Any]:
    """``{name: deep copy of obj.name}`` for ``names``, each checked to be plain data."""
    out = {}
    for name in names:
        value = getattr(obj, name)
        check_plain(value, f"{type(obj).__name__}.{name}")
        out[name] = copy.deepcopy(value)
    return out


def restore(obj: object, state: dict[str, Any], names: tuple[str, ...]) -> None:
    """Set ``obj``'s attributes ``names`` to deep copies of ``state``'s (so the state can be
    restored again). Raises ValueError if ``state`` does not have exactly ``names``."""
    if set(state) != set(names):
        missing, extra = sorted(set(names) - set(state)), sorted(set(state) - set(names))
        raise ValueError(
            f"state of {type(obj).__name__} does not match: missing {missing}, unexpected {extra}"
        )
    for name in names:
        setattr(obj, name, copy.deepcopy(state[name]))
