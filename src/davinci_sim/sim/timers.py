"""MuJoCo's library file and its stage timers (``mjData.timer``), off while the simulator
runs.

MuJoCo times each stage of every step (``mj_step``, ``mj_forward``, collision, the solver,
...) through its global clock callback ``mjcb_time``, which MuJoCo's Python bindings point
at a clock of their own when they load: about 30 clock reads a step. On the 2-core VM that
was 0.6 µs of the full scene's ~29 µs ``mj_step`` and 0.7 µs of the one-pair scene's ~15 µs
(medians of 4,000 steps from the same state, the callback set and cleared in turn), and
3.7 % of the study's samples in ``perf``. Nothing in the simulator reads the timers, so a
:class:`~davinci_sim.sim.simulation.Simulation` clears the callback when it is built
(:func:`quiet`): MuJoCo then skips them (``mjData.timer`` stays at zero) and the physics is
otherwise the same, bit for bit (tested). Someone profiling MuJoCo's stages turns them back
on with ``mujoco_timers(True)``; that choice then stands for the process.

The callback is one global of the MuJoCo library the bindings loaded, written here through
``ctypes`` (the bindings' ``set_mjcb_time`` takes a Python callable, not "none at all").
"""

from __future__ import annotations

import ctypes
import glob
import os

import mujoco

_state: dict = {}
"""``callback``: the library's ``mjcb_time`` (a ``ctypes.c_void_p`` in the library);
``clock``: its value as the bindings set it; ``chosen``: the user's choice, once made."""


def library_path() -> str | None:
    """The MuJoCo shared library of the installed wheel (the one the bindings use), or None
    (a wheel without the file beside the bindings)."""
    folder = os.path.dirname(mujoco.__file__)
    found = sorted(glob.glob(os.path.join(folder, "libmujoco.so*")))
    return found[-1] if found else None


def _callback() -> ctypes.c_void_p | None:
    """``mjcb_time`` of the MuJoCo library the bindings use (None: no such library file)."""
    if "callback" not in _state:
        path = library_path()
        callback = None
        if path is not None:
            try:  # (dlopen of the loaded file: the same library, not a second copy)
                callback = ctypes.c_void_p.in_dll(ctypes.CDLL(path), "mjcb_time")
            except (OSError, ValueError):  # pragma: no cover - a library without the symbol
                callback = None
        _state["callback"] = callback
        _state["clock"] = None if callback is None else callback.value
    return _state["callback"]


def mujoco_timers(enabled: bool) -> bool:
    """Turn MuJoCo's stage timers on (the bindings' clock) or off in this process, and keep
    that choice (:func:`quiet` leaves it). Returns whether they are on now (False where the
    library cannot be reached: then they are as the bindings left them)."""
    callback = _callback()
    _state["chosen"] = bool(enabled)
    if callback is None:
        return False
    callback.value = _state["clock"] if enabled else None
    return bool(callback.value)


def quiet() -> None:
    """The timers off, unless :func:`mujoco_timers` chose otherwise in this process."""
    if "chosen" in _state:
        return
    callback = _callback()
    if callback is not None:
        callback.value = None


def timers_on() -> bool:
    """Whether MuJoCo's stage timers run in this process."""
    callback = _callback()
    return callback is not None and bool(callback.value)
