"""A guidance law of the user's own, compiled, in the live haptic loop and the console's
compiled ticks: the one interface for laws the simulator does not ship.

A law is a function of the tool tip's velocity ``v`` (3,) m/s and its deviation ``phi``
(3,) m (tip → the path's closest point), both in the path's frame, and of six parameters,
that writes the force (3,) N into ``out``; written so that numba compiles it (arrays and
floats, no Python objects)::

    from davinci_sim.haptics.compiled_law import UserLawGuidance, compiled_law

    @compiled_law
    def pull(v, phi, params, out):  # k·φ − c·v, N
        for i in range(3):
            out[i] = params[0] * phi[i] - params[1] * v[i]

    fixture = UserLawGuidance(path, pull, (300.0, 2.0))
    console.haptics.add_field(FixtureField(fixture), mtm="MTMR")

:func:`compiled_law` compiles it as a C callback (:class:`CompiledLaw`, its ``address``); the
fixture row (:func:`~davinci_sim.haptics.fixture_row.fixture_law_row`) calls it through that
address (:func:`call_law`) after the velocity filter and the closest point, as it computes
the shipped laws, so the field, the haptic loop's compiled tick and the console's compiled
ticks all run it compiled. The same function run by Python on each row is
:meth:`UserLawGuidance.force`, the batch form (the study's engine) and the oracle. A law
written as any other callable (``field(state) -> wrench``) still works, in Python, at
Python's speed: the console then ticks in Python while it is registered.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics.path_query import closest_point

#: How many parameters a law takes (the fixture row's one signature).
N_PARAMS = 6


@dataclass(frozen=True, eq=False)
class CompiledLaw:
    """A law compiled by :func:`compiled_law`: the Python function, its C callback's
    ``address`` (``void(double *v, double *phi, double *params, double *out)``) and the
    callback object (kept alive with the law)."""

    function: Callable
    address: int
    callback: object = field(repr=False)


def compiled_law(function: Callable) -> CompiledLaw:
    """``function(v, phi, params, out)`` (see the module docstring) compiled as a C callback.

    Raises:
        TypeError: if numba cannot compile it (the message says why).
    """
    import numba
    from numba import types

    jitted = numba.njit(function)
    p = types.CPointer(types.float64)

    def entry(v, phi, params, out):
        jitted(numba.carray(v, 3), numba.carray(phi, 3), numba.carray(params, N_PARAMS),
               numba.carray(out, 3))  # fmt: skip

    try:
        callback = numba.cfunc(types.void(p, p, p, p))(entry)
    except Exception as e:  # numba's typing and lowering errors
        raise TypeError(f"compiled_law: numba cannot compile {function.__name__}: {e}") from e
    return CompiledLaw(function, int(callback.address), callback)


def _call_law_intrinsic():
    """numba's intrinsic that calls a law's C callback at an address (int64) with the
    data pointers of four float64 arrays."""
    from llvmlite import ir
    from numba import types
    from numba.extending import intrinsic

    @intrinsic
    def call_law(typingctx, address, v, phi, params, out):
        sig = types.void(types.int64, v, phi, params, out)

        def codegen(context, builder, signature, args):
            double_p = ir.PointerType(ir.DoubleType())
            function = builder.inttoptr(
                args[0], ir.FunctionType(ir.VoidType(), [double_p] * 4).as_pointer()
            )
            pointers = []
            for ty, value in zip(signature.args[1:], args[1:], strict=True):
                array = context.make_array(ty)(context, builder, value)
                pointers.append(builder.bitcast(array.data, double_p))
            builder.call(function, pointers)
            return context.get_dummy_value()

        return sig, codegen

    return call_law


call_law = _call_law_intrinsic()
"""``call_law(address, v, phi, params, out)`` inside a numba kernel: the law's callback."""


@dataclass(frozen=True, eq=False)
class UserLawGuidance:
    """A fixture along ``path`` whose force is ``law`` (a :class:`CompiledLaw`) with
    ``params`` (up to :data:`N_PARAMS` floats, the rest 0): ``force(p, v)`` in the path's
    frame, each row through the law's Python function (the oracle of its compiled form)."""

    path: Polyline
    law: CompiledLaw
    params: tuple = ()

    def __post_init__(self) -> None:
        if not isinstance(self.law, CompiledLaw):
            raise TypeError("UserLawGuidance.law must be a compiled_law(...)")
        values = np.asarray(self.params, dtype=float).ravel()
        if values.size > N_PARAMS or not np.isfinite(values).all():
            raise ValueError(
                f"UserLawGuidance.params: at most {N_PARAMS} finite numbers, got {self.params!r}"
            )

    @property
    def parameters(self) -> np.ndarray:
        """The law's parameters padded to :data:`N_PARAMS` (a new array)."""
        out = np.zeros(N_PARAMS)
        values = np.asarray(self.params, dtype=float).ravel()
        out[: values.size] = values
        return out

    def force(self, position, velocity) -> np.ndarray:
        p = np.asarray(position, dtype=float).reshape(-1, 3)
        v = np.asarray(velocity, dtype=float).reshape(-1, 3)
        phi = np.asarray(closest_point(self.path, p).deviation, dtype=float).reshape(-1, 3)
        out = np.zeros_like(p)
        params = self.parameters
        for i in range(len(p)):
            self.law.function(v[i], phi[i], params, out[i])
        return out.reshape(np.shape(position))
