"""The PyKDL values without a rotation: :class:`Vector`, :class:`Twist`, :class:`Wrench`,
:class:`JntArray`, and what every value shares (copies, ``==``, indices, numbers taken as
pybind11 takes them). Part of :mod:`davinci_sim.compat.kdl` (see there for the semantics);
scripts import that one.
"""

from __future__ import annotations

import numpy as np

from davinci_sim.compat import kdl_math as km
from davinci_sim.compat.kdl_math import EPSILON


def _float(x) -> float:
    """A number as pybind11 takes a C++ double: ints, floats, numpy numbers; not strings."""
    if isinstance(x, str | bytes) or x is None:
        raise TypeError(f"expected a number, got {x!r}")
    return float(x)


def _num(x) -> bool:
    return isinstance(x, int | float | np.floating | np.integer)


def _index(i, n: int, name: str) -> int:
    if not isinstance(i, int | np.integer):
        raise TypeError(f"{name} indices are ints, got {i!r}")
    if not 0 <= i < n:
        raise IndexError(f"{name} index out of range")
    return int(i)


def _index2(ij, rows: int, cols: int, name: str) -> tuple[int, int]:
    if not (isinstance(ij, tuple) and len(ij) == 2
            and all(isinstance(k, int | np.integer) for k in ij)):  # fmt: skip
        raise TypeError(f"{name} indices are (row, column) ints, got {ij!r}")
    i, j = ij
    if not (0 <= i < rows and 0 <= j < cols):
        raise IndexError(f"{name} index out of range")
    return int(i), int(j)


def _args(cls: str, args: tuple, kwargs: dict, names: tuple[str, ...]) -> tuple:
    """Positional and keyword arguments (pybind11's names) as one tuple."""
    if not kwargs:
        return args
    if set(kwargs) != set(names[len(args) :]):
        raise TypeError(f"{cls}(): incompatible arguments {args!r} {kwargs!r}")
    return (*args, *(kwargs[n] for n in names[len(args) :]))


class _Value:
    """What every KDL value has: a numpy ``array``, copies, tolerant ``==``, no hash."""

    __slots__ = ("array",)

    def __eq__(self, other) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return Equal(self, other)

    def __ne__(self, other) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return not Equal(self, other)

    __hash__ = None  # mutable, compared with a tolerance

    def __copy__(self):
        return type(self)(self)

    def __deepcopy__(self, memo):
        return type(self)(self)


# =========================================================================== Vector
class Vector(_Value):
    """A 3-vector: ``Vector()`` (zero), ``Vector(x, y, z)``, ``Vector(other)`` (a copy)."""

    __slots__ = ()

    def __init__(self, *args, **kwargs) -> None:
        args = _args("Vector", args, kwargs, ("x", "y", "z"))
        if not args:
            self.array = np.zeros(3)
        elif len(args) == 1 and isinstance(args[0], Vector):
            self.array = args[0].array.copy()
        elif len(args) == 3:
            self.array = np.array([_float(a) for a in args])
        else:
            raise TypeError(f"Vector() takes 0 or 3 numbers or a Vector, got {args!r}")

    @staticmethod
    def Zero() -> Vector:
        return Vector()

    def _coord(self, i: int, value):
        if value is None:
            return float(self.array[i])
        self.array[i] = _float(value)
        return None

    def x(self, value=None):
        return self._coord(0, value)

    def y(self, value=None):
        return self._coord(1, value)

    def z(self, value=None):
        return self._coord(2, value)

    def __getitem__(self, i) -> float:
        return float(self.array[_index(i, 3, "Vector")])

    def __setitem__(self, i, value) -> None:
        self.array[_index(i, 3, "Vector")] = _float(value)

    def Norm(self, eps: float = EPSILON) -> float:
        return km.norm(self.array, eps)

    def Normalize(self, eps: float = EPSILON) -> float:
        """Make unit length, return the former norm; below ``eps``: (1, 0, 0) and 0."""
        self.array[:], n = km.normalized(self.array, eps)
        return n

    def ReverseSign(self) -> None:
        self.array *= -1.0

    def __neg__(self) -> Vector:
        return _vec(-self.array)

    def __add__(self, other) -> Vector:
        return _vec(self.array + other.array) if isinstance(other, Vector) else NotImplemented

    def __sub__(self, other) -> Vector:
        return _vec(self.array - other.array) if isinstance(other, Vector) else NotImplemented

    def __iadd__(self, other) -> Vector:
        if not isinstance(other, Vector):
            return NotImplemented
        self.array += other.array
        return self

    def __isub__(self, other) -> Vector:
        if not isinstance(other, Vector):
            return NotImplemented
        self.array -= other.array
        return self

    def __mul__(self, other):
        if isinstance(other, Vector):  # KDL: the cross product
            return _vec(np.cross(self.array, other.array))
        return _vec(self.array * float(other)) if _num(other) else NotImplemented

    def __rmul__(self, other):
        return _vec(self.array * float(other)) if _num(other) else NotImplemented

    def __truediv__(self, other):
        return _vec(self.array / float(other)) if _num(other) else NotImplemented

    def __repr__(self) -> str:
        return km.vector_text(self.array)

    def __reduce__(self):
        return (Vector, tuple(float(v) for v in self.array))


def _vec(a) -> Vector:
    """A new vector owning a copy of ``a``."""
    return _view(Vector, np.array(a, dtype=float))


def _view(cls, a: np.ndarray):
    """A ``cls`` whose numbers are ``a`` itself (a part of its owner)."""
    obj = cls.__new__(cls)
    obj.array = a
    return obj


def dot(a, b) -> float:
    """Dot product of two vectors, or the power of a twist and a wrench (either order)."""
    if isinstance(a, Vector) and isinstance(b, Vector):
        return km.dot(a.array, b.array)
    if {type(a), type(b)} == {Twist, Wrench}:
        return km.dot(a.array[:3], b.array[:3]) + km.dot(a.array[3:], b.array[3:])
    raise TypeError(f"dot: {type(a).__name__} and {type(b).__name__}")


def _vector(v) -> Vector:
    if not isinstance(v, Vector):
        raise TypeError(f"expected a Vector, got {v!r}")
    return v


# =========================================================================== Twist, Wrench
class _Six(_Value):
    """Two 3-vectors in one 6-array; the named parts are views of its halves."""

    __slots__ = ()
    _names: tuple[str, str] = ("", "")

    def __init__(self, *args, **kwargs) -> None:
        name = type(self).__name__
        args = _args(name, args, kwargs, self._names)
        if not args:
            self.array = np.zeros(6)
        elif len(args) == 1 and type(args[0]) is type(self):
            self.array = args[0].array.copy()
        elif len(args) == 2 and all(isinstance(a, Vector) for a in args):
            self.array = np.concatenate([args[0].array, args[1].array])
        else:
            raise TypeError(f"{name}() takes 2 Vectors or a {name}, got {args!r}")

    def _part(self, k: int) -> Vector:
        return _view(Vector, self.array[3 * k : 3 * k + 3])

    def _set_part(self, k: int, v) -> None:
        self.array[3 * k : 3 * k + 3] = _vector(v).array

    def __getitem__(self, i) -> float:
        return float(self.array[_index(i, 6, type(self).__name__)])

    def __setitem__(self, i, value) -> None:
        self.array[_index(i, 6, type(self).__name__)] = _float(value)

    @classmethod
    def Zero(cls):
        return cls()

    def ReverseSign(self) -> None:
        self.array *= -1.0

    def _new(self, a: np.ndarray):
        return _view(type(self), np.array(a, dtype=float))

    def __neg__(self):
        return self._new(-self.array)

    def __add__(self, other):
        return self._new(self.array + other.array) if type(other) is type(self) else NotImplemented

    def __sub__(self, other):
        return self._new(self.array - other.array) if type(other) is type(self) else NotImplemented

    def __iadd__(self, other):
        if type(other) is not type(self):
            return NotImplemented
        self.array += other.array
        return self

    def __isub__(self, other):
        if type(other) is not type(self):
            return NotImplemented
        self.array -= other.array
        return self

    def __mul__(self, other):
        return self._new(self.array * float(other)) if _num(other) else NotImplemented

    __rmul__ = __mul__

    def __truediv__(self, other):
        return self._new(self.array / float(other)) if _num(other) else NotImplemented

    def __repr__(self) -> str:
        return km.vector_text(self.array)

    def __reduce__(self):
        return (type(self), (self._part(0), self._part(1)))


def _six(cls, a, b):
    return _view(cls, np.concatenate([a, b]).astype(float))


class Twist(_Six):
    """Linear velocity ``vel`` (m/s) and angular velocity ``rot`` (rad/s) of a point."""

    __slots__ = ()
    _names = ("vel", "rot")
    vel = property(lambda self: self._part(0), lambda self, v: self._set_part(0, v))
    rot = property(lambda self: self._part(1), lambda self, v: self._set_part(1, v))

    def RefPoint(self, base: Vector) -> Twist:
        """The same motion seen at a point moved by ``base``: ``vel + rot × base``."""
        return Twist(self.vel + self.rot * _vector(base), self.rot)


class Wrench(_Six):
    """Force ``force`` (N) and torque ``torque`` (N·m) about a point."""

    __slots__ = ()
    _names = ("force", "torque")
    force = property(lambda self: self._part(0), lambda self, v: self._set_part(0, v))
    torque = property(lambda self: self._part(1), lambda self, v: self._set_part(1, v))

    def RefPoint(self, base: Vector) -> Wrench:
        """The same wrench about a point moved by ``base``: ``torque + force × base``."""
        return Wrench(self.force, self.torque + self.force * _vector(base))


# =========================================================================== JntArray
class JntArray(_Value):
    """``n`` joint values (zeros at first); ``JntArray(other)`` copies."""

    __slots__ = ()

    def __init__(self, arg=0) -> None:
        if isinstance(arg, JntArray):
            self.array = arg.array.copy()
        elif isinstance(arg, int | np.integer) and arg >= 0:
            self.array = np.zeros(int(arg))
        else:
            raise TypeError(f"JntArray() takes a size or a JntArray, got {arg!r}")

    def rows(self) -> int:
        return len(self.array)

    def columns(self) -> int:
        return 1

    def resize(self, n: int) -> None:
        """``n`` values: the first ones kept, new ones 0."""
        a = np.zeros(int(n))
        k = min(len(a), len(self.array))
        a[:k] = self.array[:k]
        self.array = a

    def __getitem__(self, i) -> float:
        return float(self.array[_index(i, len(self.array), "JntArray")])

    def __setitem__(self, i, value) -> None:
        self.array[_index(i, len(self.array), "JntArray")] = _float(value)

    def __repr__(self) -> str:
        return "[" + "".join(km.fmt(v) for v in self.array) + "]"


# =========================================================================== functions
def Equal(a, b, eps: float = EPSILON) -> bool:
    """Every number of ``a`` and ``b`` (same type) strictly within ``eps``."""
    if type(a) is not type(b) or not isinstance(a, _Value):
        raise TypeError(f"Equal: {type(a).__name__} and {type(b).__name__}")
    if a.array.shape != b.array.shape:
        return False
    return bool(np.all(np.abs(a.array - b.array) < eps))


def SetToZero(x) -> None:
    """Zero a vector, twist, wrench or joint array in place."""
    if not isinstance(x, Vector | _Six | JntArray):
        raise TypeError(f"SetToZero: {type(x).__name__}")
    x.array[:] = 0.0
