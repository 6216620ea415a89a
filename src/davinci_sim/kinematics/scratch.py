"""Scratch arrays of the compiled kernels in the calling function's stack frame.

A per-tick law that needs a few small arrays of its own (a 4×4 frame, an IK's candidates)
allocated them on the heap at every call: a ``malloc``, numba's memory record, reference
counting, a ``free``. The console's compiled ticks made ~80 such allocations a tick, an
environment's step ~340. :func:`local` (float64), :func:`local_int`, :func:`local_bool`
(shapes known when the kernel compiles) and :func:`local_within` (a shape known when it
runs, within a fixed capacity) give such an array in the stack frame of the function that
asks for it instead: space reserved once in the function's entry block (a call in a loop
reuses it), no reference counting.

Called from plain Python (a run without numba, the laws' Python oracles), they return
``np.empty`` of the shape: the same arithmetic on the same values either way.

The overloads are inlined into the caller's code before it is compiled
(``inline="always"``): a called function's frame would end with the call, and the array
with it. The rule that comes with it: such an array lives as long as the function that asked for
it. It is never returned, stored in an argument or kept beyond the call (its memory is
the frame's); pass it down to the laws a function calls, not up.
"""

from __future__ import annotations

import numpy as np

try:
    import numba
except Exception:  # pragma: no cover - depends on the installation
    numba = None

#: The most elements one scratch array may hold (it is a stack frame's space).
MAX_ELEMENTS = 4096


def local(n0: int, n1: int = -1, n2: int = -1) -> np.ndarray:
    """A float64 scratch array (uninitialised) of shape ``(n0,)``, ``(n0, n1)`` or
    ``(n0, n1, n2)`` (−1: that axis left out); each size an integer constant of the calling
    kernel's source (0 allowed)."""
    return np.empty(_shape(n0, n1, n2))


def local_within(capacity: int, n0: int, n1: int = -1, n2: int = -1) -> np.ndarray:
    """:func:`local` of a shape known only when the kernel runs (e.g. an arm's number of
    joints), within ``capacity`` elements (an integer constant of the kernel's source); a
    larger shape raises ValueError."""
    shape = _shape(n0, n1, n2)
    if int(np.prod(shape)) > capacity:
        raise ValueError(f"a scratch array of shape {shape} is over its {capacity} elements")
    return np.empty(shape)


def local_bool(n0: int) -> np.ndarray:
    """A bool scratch array (uninitialised) of shape ``(n0,)``, ``n0`` a constant."""
    return np.empty(n0, dtype=np.bool_)


def local_int(n0: int) -> np.ndarray:
    """An int64 scratch array (uninitialised) of shape ``(n0,)``, ``n0`` a constant."""
    return np.empty(n0, dtype=np.int64)


def _shape(n0: int, n1: int, n2: int) -> tuple[int, ...]:
    if n1 < 0:
        return (n0,)
    if n2 < 0:
        return (n0, n1)
    return (n0, n1, n2)


if numba is not None:
    from llvmlite import ir
    from numba.core import cgutils, types
    from numba.core.errors import TypingError
    from numba.extending import intrinsic, overload

    def _constant(t, name: str) -> int:
        """The value of a literal integer type (an omitted argument: its default)."""
        if isinstance(t, int):
            return t
        if isinstance(t, types.Omitted):
            return int(t.value)
        if isinstance(t, types.IntegerLiteral):
            return int(t.literal_value)
        raise TypingError(f"scratch array: {name} must be an integer constant, got {t}")

    def _stack(dtype):
        """An intrinsic: a pointer to ``count`` (a literal) elements of ``dtype`` reserved
        in the entry block of the function it is compiled into."""

        @intrinsic(prefer_literal=True)
        def stack(typingctx, count):
            if not isinstance(count, types.IntegerLiteral):
                raise TypingError("the scratch array's size must be a constant")
            n = int(count.literal_value)
            if not 0 <= n <= MAX_ELEMENTS:
                raise TypingError(f"a scratch array holds 0 to {MAX_ELEMENTS} elements, not {n}")

            def codegen(context, builder, signature, args):
                element = context.get_data_type(dtype)
                size = ir.Constant(ir.IntType(64), max(n, 1))
                return cgutils.alloca_once(builder, element, size=size)

            return types.CPointer(dtype)(count), codegen

        return stack

    _stack_f64 = _stack(types.float64)
    _stack_bool = _stack(types.boolean)
    _stack_i64 = _stack(types.int64)

    @overload(local, prefer_literal=True, inline="always")
    def _local(n0, n1=-1, n2=-1):
        shape = _shape(_constant(n0, "n0"), _constant(n1, "n1"), _constant(n2, "n2"))
        if min(shape) < 0:
            raise TypingError(f"a scratch array's shape: {shape}")
        count = int(np.prod(shape))

        def impl(n0, n1=-1, n2=-1):
            return numba.carray(_stack_f64(count), shape)

        return impl

    def _absent(t) -> bool:
        """Whether an optional size was left out (its default, −1)."""
        return isinstance(t, int) or isinstance(t, types.Omitted)

    @overload(local_within, prefer_literal=True, inline="always")
    def _local_within(capacity, n0, n1=-1, n2=-1):
        count = _constant(capacity, "capacity")
        if _absent(n1):

            def impl1(capacity, n0, n1=-1, n2=-1):
                if not 0 <= n0 <= count:
                    raise ValueError("a scratch array over its capacity")
                return numba.carray(_stack_f64(count), (n0,))

            return impl1
        if _absent(n2):

            def impl2(capacity, n0, n1=-1, n2=-1):
                if n0 < 0 or n1 < 0 or n0 * n1 > count:
                    raise ValueError("a scratch array over its capacity")
                return numba.carray(_stack_f64(count), (n0, n1))

            return impl2

        def impl3(capacity, n0, n1=-1, n2=-1):
            if n0 < 0 or n1 < 0 or n2 < 0 or n0 * n1 * n2 > count:
                raise ValueError("a scratch array over its capacity")
            return numba.carray(_stack_f64(count), (n0, n1, n2))

        return impl3

    def _one_axis(stack):
        """The compiled form of a one-axis scratch array whose elements ``stack`` reserves."""

        def typed(n0):
            count = _constant(n0, "n0")

            def impl(n0):
                return numba.carray(stack(count), (count,))

            return impl

        return typed

    overload(local_bool, prefer_literal=True, inline="always")(_one_axis(_stack_bool))
    overload(local_int, prefer_literal=True, inline="always")(_one_axis(_stack_i64))
