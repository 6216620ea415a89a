"""Optional compilation of the 1 kHz laws with numba, with the plain Python function as the
fallback. (In ``kinematics``, the lowest layer that compiles a law; any layer above may use it.)

:func:`jit` compiles a function written in numba's subset of Python (scalar loops over
arrays) the first time it is called, caching the machine code on disk (``cache=True``), so
tests and processes do not pay the compile time twice. With ``DAVINCI_SIM_JIT=0`` in the
environment, or if compiling fails (reported once as a warning), the same Python function
runs where Python calls it: slower, same results. (numba is a dependency, not an option:
the compiled tick's own kernels, ``sim/live_kernel.py`` and the like, are numba functions
that call these kernels compiled, through their ``dispatcher``, whatever the switch says.)
Compiled code follows IEEE arithmetic operation by operation (no ``fastmath``: no
reassociation, no fused multiply-add), so both paths give the same bits
(``tests/kinematics/test_fk_compiled.py``).
"""

from __future__ import annotations

import functools
import os
import warnings

import numpy as np

try:  # numba is a dependency; the fallback keeps a broken or missing install working
    import numba
except Exception:  # pragma: no cover - depends on the installation
    numba = None

ENABLED = numba is not None and os.environ.get("DAVINCI_SIM_JIT", "1") != "0"
"""Whether :func:`jit` compiles (numba importable and not switched off)."""

# (whatever the switch: the compiled tick's kernels compile, and enter the cache, alike)
if numba is not None and os.environ.get("DAVINCI_SIM_REFPRUNE", "1") != "0":
    from davinci_sim.kinematics.jit_refcounts import install

    install()  # before anything compiles (every module that compiles imports this one)


def kernel_array(a, dtype=float) -> np.ndarray:
    """``a`` as the one kind of array the kernels take: C-ordered, writable, of ``dtype`` (a
    copy only where it is not one). numba compiles a kernel again, for seconds to a minute,
    for a read-only argument (a frozen value's, a module constant's) or a strided one."""
    out = np.ascontiguousarray(a, dtype=dtype)
    return out if out.flags.writeable else out.copy()


KERNELS: list = []
"""Every function :func:`jit` compiled or will compile: each module warms its kernels up at
import (its ``_warm_up``) so that none compiles in a 1 kHz loop; ``ready()`` tells."""


def jit(fn):
    """``fn`` compiled by numba on first call (``nopython``, cached), or ``fn`` itself.

    The wrapper's ``py_func`` is the Python function (tests compare both paths).
    """
    if not ENABLED:
        fn.py_func = fn
        fn.ready = lambda: True
        if numba is not None:  # the compiled tick's kernels still call it compiled
            fn.dispatcher = numba.njit(cache=True)(fn)
        return fn
    compiled = numba.njit(cache=True)(fn)
    current = [None]

    @functools.wraps(fn)
    def call(*args):
        f = current[0]
        if f is not None:
            return f(*args)
        try:
            out = compiled(*args)
        except Exception as e:  # a failed compile: run the Python function from now on
            warnings.warn(
                f"numba could not compile {fn.__qualname__} ({type(e).__name__}: {e}); "
                "running it as plain Python",
                RuntimeWarning,
                stacklevel=2,
            )
            current[0] = fn
            return fn(*args)
        current[0] = compiled
        return out

    call.py_func = fn
    call.ready = lambda: current[0] is not None
    call.dispatcher = compiled  # (its ``signatures``: what has been compiled or loaded)
    KERNELS.append(call)
    return call


def helper(fn):
    """Make ``fn`` callable from :func:`jit` kernels (numba's ``register_jitable``); Python
    callers still call the plain function. A law written once on floats (e.g.
    :func:`~davinci_sim.geometry.so3.rotation_vector_floats`, the PSM IK's pieces) is then
    compiled into the kernels that use it and stays an ordinary function everywhere else.
    Returns ``fn``.

    numba's on-disk cache of a kernel does not notice edits of the helpers it calls in
    other modules: after changing such a helper, delete the ``__pycache__/*.nbi``/``*.nbc``
    files of the kernels' modules (or compare with ``DAVINCI_SIM_JIT=0``).
    """
    # (whenever numba is there: the compiled tick's kernels call helpers with the switch off
    # too; once: a second registration is a second overload)
    if numba is not None and fn not in _HELPERS:
        from numba.extending import register_jitable

        register_jitable(fn)
        _HELPERS.add(fn)
    return fn


_HELPERS: set = set()  # the functions :func:`helper` registered


DEFERRED = os.environ.get("DAVINCI_SIM_DEFER_WARM_UP") == "1"
"""Whether the modules' warm-ups are only collected (:data:`WARM_UPS`), not run, at import:
set by :mod:`davinci_sim.warm_up`'s processes, which run a share of them each, so that a
clean checkout compiles its kernels on every core. Never set in a simulation's process."""

WARM_UPS: list = []
"""The warm-ups imported modules deferred (:data:`DEFERRED`), in import order."""


def warm(warm_up) -> None:
    """Run a module's ``warm_up()`` at import (its kernels compiled or loaded from numba's
    cache), or collect it in :data:`WARM_UPS` when :data:`DEFERRED`."""
    if DEFERRED:
        WARM_UPS.append(warm_up)
    else:
        warm_up()


def warmed_up(warm_up, fallback: str) -> bool:
    """Run a module's ``warm_up()`` (its kernels compiled or loaded from the cache at
    import); if numba cannot compile them, warn (``fallback``: what runs instead) and return
    False, so that the module's callers take their Python path instead of failing to
    import. When :data:`DEFERRED`: collected (:func:`warm`) and True."""
    if DEFERRED:
        warm(warm_up)
        return True
    try:
        warm_up()
    except Exception as e:  # pragma: no cover - a numba that cannot compile the kernel
        warnings.warn(f"{fallback} ({type(e).__name__}: {e})", RuntimeWarning, stacklevel=2)
        return False
    return True
