"""A compiled call's arguments bound once (numba only): :class:`Bound` and :func:`bind`.

numba unboxes every array argument of a call from its Python object (~40 ns an array here):
a kernel called with a few hundred arrays spends ~10 µs a call on that alone, more than a
tick of its laws, though the arrays are the same objects call after call (the live objects'
own, updated in place). A :class:`Bound` holds such a tuple of arguments in one compiled
structure, built once (:func:`bind`, one unboxing); a kernel's wrapper takes the
:class:`Bound` and calls the kernel on its fields, so a call unboxes one object. The arrays
are shared, not copied: what the kernel writes, the objects see.

Module-level functions, so that numba's on-disk cache keeps them between processes.
"""

from __future__ import annotations

import numba
from numba.core import types
from numba.experimental import structref

__all__ = ["Bound", "bind"]


@structref.register
class BoundType(types.StructRef):
    """The compiled type of a :class:`Bound`: one field, ``args``, a tuple."""

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(t)) for name, t in fields)


class Bound(structref.StructRefProxy):
    """A tuple of a kernel's arguments (``args``) held in one compiled structure."""


structref.define_proxy(Bound, BoundType, ["args"])


@numba.njit(cache=True, nogil=True)
def bind(args):
    """``args`` (a tuple, as a kernel takes it) as a :class:`Bound`."""
    return Bound(args)
