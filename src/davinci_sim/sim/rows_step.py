"""Many simulations stepped in one compiled call: MuJoCo's ``mj_step`` from numba, per row.

A batch of simulations (the study's trials) keeps its state as arrays with one row per
simulation (``Q`` = every row's ``qpos``, ...). Stepping them from Python costs a call and
five array copies per simulation per tick, as much as a third of MuJoCo's own step for the
study's scene. :class:`RowStepper` does the same in one call: for every given row it writes
the row's ``ctrl`` and one body's ``xfrc_applied`` into that simulation's ``MjData``, calls
``mj_step`` (the MuJoCo library of the installed ``mujoco`` wheel, called from compiled
code), and reads ``qpos``, ``qvel``, ``qfrc_bias``, ``qfrc_gravcomp`` and the body's
``xipos`` back into the rows. The same C function on the same ``MjData``: the same bits
as :func:`mujoco.mj_step` called from Python (tested), so callers change speed, not results.

How: ``MjModel._address`` / ``MjData._address`` are the C pointers MuJoCo's bindings hold;
numba calls ``mj_step`` as an external C function once the wheel's library is loaded into
LLVM's symbol table (``llvmlite.binding.load_library_permanently``), which keeps numba's
on-disk cache valid (a ctypes function pointer would not). Each simulation's arrays are
reached through their buffer addresses (``d.qpos.ctypes.data``), fixed for the ``MjData``'s
life; a :class:`RowStepper` holds its ``MjData`` so that they stay alive. Without numba
(``DAVINCI_SIM_JIT=0``) or without the library file, the same loop runs in Python.
"""

from __future__ import annotations

import warnings

import mujoco
import numpy as np

from davinci_sim.kinematics import jit
from davinci_sim.sim.timers import library_path


def _compiled_kernel():
    """The compiled row loop (:mod:`davinci_sim.sim.rows_kernel`), or None (no numba,
    switched off, or no library to bind)."""
    if not jit.ENABLED:
        return None
    path = library_path()
    if path is None:  # pragma: no cover - a wheel without its library beside the bindings
        return None
    try:
        from llvmlite import binding

        # (before the kernel is compiled or loaded from numba's cache: it links to mj_step)
        binding.load_library_permanently(path)
        from davinci_sim.sim.rows_kernel import step_rows

        return step_rows
    except Exception as e:  # pragma: no cover - a numba or llvmlite that cannot do it
        warnings.warn(
            f"MuJoCo's step cannot be called from compiled code ({type(e).__name__}: {e}); "
            "stepping rows from Python",
            RuntimeWarning,
            stacklevel=2,
        )
        return None


_KERNEL = _compiled_kernel()

COMPILED = _KERNEL is not None
"""Whether :class:`RowStepper` steps in compiled code (else its Python loop, same results)."""


class RowStepper:
    """Steps the simulations ``(models[i], datas[i])`` row by row (see the module docstring).

    Args:
        models, datas: one ``MjModel`` and ``MjData`` per row (models may be shared).
        body: the body whose ``xfrc_applied`` each step sets and whose ``xipos`` it reads,
            or None (no applied force).
    """

    def __init__(self, models: list, datas: list, body: int | None = None) -> None:
        if len(models) != len(datas):
            raise ValueError(f"{len(models)} models for {len(datas)} datas")
        self.models, self.datas, self.body = list(models), list(datas), body
        self._model = np.array([m._address for m in self.models], dtype=np.intp)
        self._data = np.array([d._address for d in self.datas], dtype=np.intp)
        self._address = np.array(
            [
                [
                    x.ctypes.data
                    for x in (
                        d.ctrl,
                        d.xfrc_applied,
                        d.qpos,
                        d.qvel,
                        d.qfrc_bias,
                        d.qfrc_gravcomp,
                        d.xipos,
                    )
                ]  # fmt: skip
                for d in self.datas
            ],
            dtype=np.intp,
        ).reshape(len(self.datas), 7)

    def take(self, keep: np.ndarray) -> RowStepper:
        """The stepper of rows ``keep`` only (the batch dropping ended trials)."""
        return RowStepper([self.models[i] for i in keep], [self.datas[i] for i in keep], self.body)

    def step(self, rows, ctrl, xfrc, Q, V, qfrc_bias, qfrc_gravcomp, xipos, *, out=None,
             gravcomp: bool = True) -> None:  # fmt: skip
        """One ``mj_step`` of each simulation of ``rows`` (row indices), with ``ctrl``
        (rows, nu) and ``xfrc`` (rows, 6: the body's ``xfrc_applied``; None without a body)
        read at those rows; ``Q`` (nq), ``V``, ``qfrc_bias``, ``qfrc_gravcomp`` (nv; only
        with ``gravcomp``) and ``xipos`` (3, the body's; None without a body) written in
        place at the rows ``out`` (default ``rows``: a batch's own rows; a caller gathering
        a subset passes its positions). Safe to call from several threads on disjoint rows
        (the compiled loop releases the GIL, as ``mujoco.mj_step`` does)."""
        rows = np.asarray(rows, dtype=np.intp)
        out = rows if out is None else np.asarray(out, dtype=np.intp)
        body = -1 if self.body is None else self.body
        if _KERNEL is not None:
            none = _NONE
            _KERNEL(self._model, self._data, self._address, body, rows, out, ctrl,
                    none if xfrc is None else xfrc, Q, V, qfrc_bias,
                    none if qfrc_gravcomp is None else qfrc_gravcomp,
                    none if xipos is None else xipos, gravcomp)  # fmt: skip
            return
        for i, o in zip(rows.tolist(), out.tolist(), strict=True):
            d = self.datas[i]
            d.ctrl[:] = ctrl[i]
            if body >= 0:
                d.xfrc_applied[body] = xfrc[i]
            mujoco.mj_step(self.models[i], d)
            Q[o] = d.qpos
            V[o] = d.qvel
            qfrc_bias[o] = d.qfrc_bias
            if gravcomp:
                qfrc_gravcomp[o] = d.qfrc_gravcomp
            if body >= 0:
                xipos[o] = d.xipos[body]


_NONE = np.zeros((0, 0))
"""Stands for an array a step does not use (one compiled signature)."""


def _warm_up() -> None:
    """Compile (or load from numba's cache) at import with the callers' one signature, on
    no rows (no simulation is touched): never in the middle of a batch's first tick, and
    once for the processes started after this one (:mod:`davinci_sim.kinematics.jit`)."""
    if _KERNEL is None:
        return
    none, rows = _NONE, np.zeros(0, dtype=np.intp)
    addresses = np.zeros((0, 7), dtype=np.intp)
    _KERNEL(rows, rows, addresses, -1, rows, rows, none, none, none, none, none, none, none,
            True)  # fmt: skip


if not jit.warmed_up(_warm_up, "MuJoCo's step cannot be compiled: rows step from Python"):
    _KERNEL, COMPILED = None, False
