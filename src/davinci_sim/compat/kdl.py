"""A subset of PyKDL (the Orocos KDL Python bindings) with the same names and semantics.

dVRK Python scripts get Cartesian poses as ``PyKDL.Frame`` and build goals with
``PyKDL.Rotation.RPY``, ``PyKDL.Vector`` … PyKDL is not on PyPI; this module stands in for
it (``davinci-sim run`` puts it on the import path as ``PyKDL`` only when the real one cannot
be imported). Written from KDL's documented behaviour:

* :class:`Vector` — 3 floats; ``v[i]``, ``v.x()`` (``v.x(value)`` sets), ``Norm()``,
  ``Normalize()``, ``+ - * /``, ``Vector * Vector`` is the **cross** product (KDL's), and
  :func:`dot`;
* :class:`Rotation` — 3x3 orthonormal; built from 9 numbers (row after row), 3 column
  vectors, ``RPY(roll, pitch, yaw)`` = ``RotZ(yaw)·RotY(pitch)·RotX(roll)`` (fixed axes),
  ``EulerZYX``, ``EulerZYZ``, ``Quaternion(x, y, z, w)``, ``Rot(axis, angle)``, ``RotX/Y/Z``;
  read back with ``GetRPY``, ``GetEulerZYX``, ``GetEulerZYZ``, ``GetQuaternion`` (x, y, z, w),
  ``GetRot`` (axis·angle), ``GetRotAngle`` (angle, axis); ``Inverse()``, ``r[i, j]``,
  ``UnitX/Y/Z``; ``*`` with a rotation, vector, twist or wrench;
* :class:`Frame` — ``M`` (rotation) and ``p`` (origin, m); ``Inverse()``, ``f[i, j]``
  (``j == 3``: ``p``), ``*`` with a frame, vector, twist (reference point moved) or wrench;
  ``Frame.DH``, ``Frame.DH_Craig1989``;
* :class:`Twist` (``vel``, ``rot``) and :class:`Wrench` (``force``, ``torque``) — 6 values,
  ``t[i]``, ``RefPoint``; :class:`JntArray` — n joint values;
* :func:`diff`, :func:`addDelta`, :func:`Equal` (``==`` is ``Equal`` with KDL's 1e-6).

Every object keeps its numbers in a float numpy array; ``.array`` (not in PyKDL) hands it
out for tests and conversions.

Size: one module, as PyKDL is one module to its users (``import PyKDL``) and its classes
operate on each other (a rotation or frame times a vector, twist or wrench; ``diff`` of every
kind): split, each part would import all the others.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "Equal",
    "Frame",
    "JntArray",
    "Rotation",
    "SetToZero",
    "Twist",
    "Vector",
    "Wrench",
    "addDelta",
    "diff",
    "dot",
]

EPSILON = 1e-6
"""KDL's default tolerance for ``Equal`` and ``==``."""


def _num(x) -> bool:
    return isinstance(x, int | float | np.floating | np.integer) and not isinstance(x, bool)


# =========================================================================== Vector
class Vector:
    """A 3-vector (``Vector()`` is zero)."""

    __slots__ = ("array",)

    def __init__(self, *args) -> None:
        if not args:
            self.array = np.zeros(3)
        elif len(args) == 1 and isinstance(args[0], Vector):
            self.array = args[0].array.copy()
        elif len(args) == 3:
            self.array = np.array([float(a) for a in args])
        else:
            raise TypeError(f"Vector() takes 0 or 3 numbers or a Vector, got {args!r}")

    @staticmethod
    def Zero() -> Vector:
        return Vector()

    def _coord(self, i: int, value):
        if value is None:
            return float(self.array[i])
        self.array[i] = float(value)
        return None

    def x(self, value=None):
        return self._coord(0, value)

    def y(self, value=None):
        return self._coord(1, value)

    def z(self, value=None):
        return self._coord(2, value)

    def __getitem__(self, i: int) -> float:
        if not -3 <= i < 3:
            raise IndexError("Vector index out of range")
        return float(self.array[i])

    def __setitem__(self, i: int, value) -> None:
        if not -3 <= i < 3:
            raise IndexError("Vector index out of range")
        self.array[i] = float(value)

    def __len__(self) -> int:
        return 3

    def __iter__(self):
        return iter(float(v) for v in self.array)

    def Norm(self) -> float:
        return float(np.linalg.norm(self.array))

    def Normalize(self, eps: float = 1e-10) -> float:
        """Make unit length and return the former norm; a norm below ``eps`` gives (1, 0, 0)
        and 0 (KDL's rule)."""
        n = self.Norm()
        if n < eps:
            self.array = np.array([1.0, 0.0, 0.0])
            return 0.0
        self.array = self.array / n
        return n

    def ReverseSign(self) -> None:
        self.array = -self.array

    def __neg__(self) -> Vector:
        return _vec(-self.array)

    def __add__(self, other: Vector) -> Vector:
        if not isinstance(other, Vector):
            return NotImplemented
        return _vec(self.array + other.array)

    def __sub__(self, other: Vector) -> Vector:
        if not isinstance(other, Vector):
            return NotImplemented
        return _vec(self.array - other.array)

    def __mul__(self, other):
        if isinstance(other, Vector):  # KDL: the cross product
            return _vec(np.cross(self.array, other.array))
        if _num(other):
            return _vec(self.array * float(other))
        return NotImplemented

    def __rmul__(self, other):
        if _num(other):
            return _vec(self.array * float(other))
        return NotImplemented

    def __truediv__(self, other):
        if _num(other):
            return _vec(self.array / float(other))
        return NotImplemented

    def __eq__(self, other) -> bool:
        return isinstance(other, Vector) and Equal(self, other)

    def __ne__(self, other) -> bool:
        return not self == other

    __hash__ = None  # mutable, compared with a tolerance

    def __repr__(self) -> str:
        return "[" + ",".join(f"{v:12.6f}" for v in self.array) + "]"

    def __reduce__(self):
        return (Vector, tuple(float(v) for v in self.array))


def _vec(a) -> Vector:
    v = Vector.__new__(Vector)
    v.array = np.asarray(a, dtype=float).copy()
    return v


def dot(a, b) -> float:
    """Dot product of two vectors (or of two twists/wrenches, as KDL's ``dot(Twist,
    Wrench)``: the power)."""
    return float(np.dot(_six(a) if not isinstance(a, Vector) else a.array,
                        _six(b) if not isinstance(b, Vector) else b.array))  # fmt: skip


# =========================================================================== Rotation
def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' formula for a unit ``axis``."""
    x, y, z = axis
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)


class Rotation:
    """A 3x3 rotation. ``Rotation()`` is the identity; ``Rotation(Xx, Yx, Zx, Xy, Yy, Zy,
    Xz, Yz, Zz)`` takes the matrix row after row; ``Rotation(x, y, z)`` its three columns."""

    __slots__ = ("array",)

    def __init__(self, *args) -> None:
        if not args:
            self.array = np.eye(3)
        elif len(args) == 1 and isinstance(args[0], Rotation):
            self.array = args[0].array.copy()
        elif len(args) == 9:
            self.array = np.array([float(a) for a in args]).reshape(3, 3)
        elif len(args) == 3 and all(isinstance(a, Vector) for a in args):
            self.array = np.column_stack([a.array for a in args])
        else:
            raise TypeError(
                f"Rotation() takes 0 or 9 numbers, 3 Vectors or a Rotation, got {args!r}"
            )

    # ---------------------------------------------------------- constructors
    @staticmethod
    def Identity() -> Rotation:
        return Rotation()

    @staticmethod
    def RotX(angle: float) -> Rotation:
        return _rot(_rx(angle))

    @staticmethod
    def RotY(angle: float) -> Rotation:
        return _rot(_ry(angle))

    @staticmethod
    def RotZ(angle: float) -> Rotation:
        return _rot(_rz(angle))

    @staticmethod
    def RPY(roll: float, pitch: float, yaw: float) -> Rotation:
        """Roll about x, then pitch about y, then yaw about z, all fixed axes:
        ``RotZ(yaw) * RotY(pitch) * RotX(roll)``."""
        return _rot(_rz(yaw) @ _ry(pitch) @ _rx(roll))

    @staticmethod
    def EulerZYX(alpha: float, beta: float, gamma: float) -> Rotation:
        """About z by alpha, then the new y by beta, then the new x by gamma:
        ``RPY(gamma, beta, alpha)``."""
        return Rotation.RPY(gamma, beta, alpha)

    @staticmethod
    def EulerZYZ(alpha: float, beta: float, gamma: float) -> Rotation:
        return _rot(_rz(alpha) @ _ry(beta) @ _rz(gamma))

    @staticmethod
    def Quaternion(x: float, y: float, z: float, w: float) -> Rotation:
        q = np.array([x, y, z, w], dtype=float)
        n = np.linalg.norm(q)
        if not n > 0:
            raise ValueError("Quaternion: a zero quaternion has no rotation")
        x, y, z, w = q / n
        return _rot(np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]))  # fmt: skip

    @staticmethod
    def Rot(axis: Vector, angle: float) -> Rotation:
        """About ``axis`` (any length; a zero axis gives the identity) by ``angle`` rad."""
        a = axis.array
        n = float(np.linalg.norm(a))
        if n < 1e-12:
            return Rotation()
        return _rot(_axis_angle(a / n, angle))

    @staticmethod
    def Rot2(axis: Vector, angle: float) -> Rotation:
        """As :meth:`Rot` for a unit ``axis`` (not normalised, as KDL)."""
        return _rot(_axis_angle(axis.array, angle))

    # ---------------------------------------------------------- read back
    def GetRPY(self) -> tuple[float, float, float]:
        """(roll, pitch, yaw) with :meth:`RPY`'s convention; at pitch ±π/2 roll is 0."""
        R = self.array
        pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
        if abs(pitch) > math.pi / 2 - 1e-12:
            return 0.0, pitch, math.atan2(-R[0, 1], R[1, 1])
        return math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])

    def GetEulerZYX(self) -> tuple[float, float, float]:
        roll, pitch, yaw = self.GetRPY()
        return yaw, pitch, roll

    def GetEulerZYZ(self) -> tuple[float, float, float]:
        R = self.array
        if abs(R[2, 2]) > 1 - 1e-12:
            beta = 0.0 if R[2, 2] > 0 else math.pi
            alpha = math.atan2(R[1, 0], R[0, 0]) if R[2, 2] > 0 else math.atan2(-R[1, 0], -R[0, 0])
            return alpha, beta, 0.0
        alpha = math.atan2(R[1, 2], R[0, 2])
        beta = math.atan2(math.hypot(R[2, 0], R[2, 1]), R[2, 2])
        gamma = math.atan2(R[2, 1], -R[2, 0])
        return alpha, beta, gamma

    def GetQuaternion(self) -> tuple[float, float, float, float]:
        """(x, y, z, w), unit; w >= 0 whenever the trace is positive (the branch KDL takes)."""
        R = self.array
        tr = R[0, 0] + R[1, 1] + R[2, 2]
        if tr > 0:
            s = 0.5 / math.sqrt(tr + 1.0)
            w, x = 0.25 / s, (R[2, 1] - R[1, 2]) * s
            y, z = (R[0, 2] - R[2, 0]) * s, (R[1, 0] - R[0, 1]) * s
        elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
            s = 2.0 * math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
            w, x = (R[2, 1] - R[1, 2]) / s, 0.25 * s
            y, z = (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s
        elif R[1, 1] > R[2, 2]:
            s = 2.0 * math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
            w, x = (R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s
            y, z = 0.25 * s, (R[1, 2] + R[2, 1]) / s
        else:
            s = 2.0 * math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
            w, x = (R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s
            y, z = (R[1, 2] + R[2, 1]) / s, 0.25 * s
        q = np.array([x, y, z, w])
        q /= np.linalg.norm(q)
        return tuple(float(v) for v in q)

    def GetRotAngle(self, eps: float = 1e-6) -> tuple[float, Vector]:
        """(angle in [0, π], unit axis); the identity gives (0, (0, 0, 1)) as KDL."""
        x, y, z, w = self.GetQuaternion()
        s = math.sqrt(x * x + y * y + z * z)
        if s < eps * 0.5:
            return 0.0, Vector(0.0, 0.0, 1.0)
        angle = 2.0 * math.atan2(s, w)
        axis = np.array([x, y, z]) / s
        if angle > math.pi:
            angle, axis = 2 * math.pi - angle, -axis
        return angle, _vec(axis)

    def GetRot(self) -> Vector:
        """The rotation vector: axis · angle (rad)."""
        angle, axis = self.GetRotAngle()
        return axis * angle

    def UnitX(self) -> Vector:
        return _vec(self.array[:, 0])

    def UnitY(self) -> Vector:
        return _vec(self.array[:, 1])

    def UnitZ(self) -> Vector:
        return _vec(self.array[:, 2])

    def Inverse(self, arg=None):
        """The transpose; with an argument, the inverse applied to it."""
        inv = _rot(self.array.T)
        return inv if arg is None else inv * arg

    def SetInverse(self) -> None:
        self.array = self.array.T.copy()

    def DoRotX(self, angle: float) -> None:
        self.array = self.array @ _rx(angle)

    def DoRotY(self, angle: float) -> None:
        self.array = self.array @ _ry(angle)

    def DoRotZ(self, angle: float) -> None:
        self.array = self.array @ _rz(angle)

    # ---------------------------------------------------------- operators
    def __getitem__(self, ij) -> float:
        i, j = ij
        return float(self.array[i, j])

    def __setitem__(self, ij, value) -> None:
        i, j = ij
        self.array[i, j] = float(value)

    def __mul__(self, other):
        if isinstance(other, Rotation):
            return _rot(self.array @ other.array)
        if isinstance(other, Vector):
            return _vec(self.array @ other.array)
        if isinstance(other, Twist):
            return Twist(self * other.vel, self * other.rot)
        if isinstance(other, Wrench):
            return Wrench(self * other.force, self * other.torque)
        return NotImplemented

    def __eq__(self, other) -> bool:
        return isinstance(other, Rotation) and Equal(self, other)

    def __ne__(self, other) -> bool:
        return not self == other

    __hash__ = None

    def __repr__(self) -> str:
        rows = ";\n ".join(",".join(f"{v:12.6f}" for v in r) for r in self.array)
        return f"[{rows}]"

    def __reduce__(self):
        return (Rotation, tuple(float(v) for v in self.array.ravel()))


def _rot(a) -> Rotation:
    r = Rotation.__new__(Rotation)
    r.array = np.asarray(a, dtype=float).copy()
    return r


# =========================================================================== Twist, Wrench
class _Six:
    """Two 3-vectors seen as 6 values (``t[0:3]`` the first, ``t[3:6]`` the second)."""

    __slots__ = ("_a", "_b")
    _names = ("", "")

    def __init__(self, a: Vector | None = None, b: Vector | None = None) -> None:
        self._a = Vector(a) if a is not None else Vector()
        self._b = Vector(b) if b is not None else Vector()

    def __getitem__(self, i: int) -> float:
        if not 0 <= i < 6:
            raise IndexError(f"{type(self).__name__} index out of range")
        return self._a[i] if i < 3 else self._b[i - 3]

    def __setitem__(self, i: int, value) -> None:
        if not 0 <= i < 6:
            raise IndexError(f"{type(self).__name__} index out of range")
        if i < 3:
            self._a[i] = value
        else:
            self._b[i - 3] = value

    def __len__(self) -> int:
        return 6

    def __iter__(self):
        return iter([*self._a, *self._b])

    @property
    def array(self) -> np.ndarray:
        return np.concatenate([self._a.array, self._b.array])

    @classmethod
    def Zero(cls):
        return cls()

    def _new(self, a: Vector, b: Vector):
        return type(self)(a, b)

    def __neg__(self):
        return self._new(-self._a, -self._b)

    def __add__(self, other):
        if type(other) is not type(self):
            return NotImplemented
        return self._new(self._a + other._a, self._b + other._b)

    def __sub__(self, other):
        if type(other) is not type(self):
            return NotImplemented
        return self._new(self._a - other._a, self._b - other._b)

    def __mul__(self, other):
        if _num(other):
            return self._new(self._a * other, self._b * other)
        return NotImplemented

    __rmul__ = __mul__

    def __truediv__(self, other):
        if _num(other):
            return self._new(self._a / other, self._b / other)
        return NotImplemented

    def __eq__(self, other) -> bool:
        return type(other) is type(self) and Equal(self, other)

    def __ne__(self, other) -> bool:
        return not self == other

    __hash__ = None

    def __repr__(self) -> str:
        return f"[{self._a!r},{self._b!r}]"

    def __reduce__(self):
        return (type(self), (self._a, self._b))


class Twist(_Six):
    """Linear velocity ``vel`` (m/s) and angular velocity ``rot`` (rad/s) of a point."""

    __slots__ = ()

    @property
    def vel(self) -> Vector:
        return self._a

    @vel.setter
    def vel(self, v: Vector) -> None:
        self._a = Vector(v)

    @property
    def rot(self) -> Vector:
        return self._b

    @rot.setter
    def rot(self, v: Vector) -> None:
        self._b = Vector(v)

    def RefPoint(self, v_base_AB: Vector) -> Twist:
        """The same motion seen at a point moved by ``v_base_AB``: ``vel + rot × v``."""
        return Twist(self.vel + self.rot * v_base_AB, self.rot)


class Wrench(_Six):
    """Force ``force`` (N) and torque ``torque`` (N·m) at a point."""

    __slots__ = ()

    @property
    def force(self) -> Vector:
        return self._a

    @force.setter
    def force(self, v: Vector) -> None:
        self._a = Vector(v)

    @property
    def torque(self) -> Vector:
        return self._b

    @torque.setter
    def torque(self, v: Vector) -> None:
        self._b = Vector(v)

    def RefPoint(self, v_base_AB: Vector) -> Wrench:
        """The same wrench about a point moved by ``v_base_AB``: ``torque + force × v``."""
        return Wrench(self.force, self.torque + self.force * v_base_AB)


def _six(x) -> np.ndarray:
    if isinstance(x, _Six):
        return x.array
    raise TypeError(f"expected a Twist or Wrench, got {type(x).__name__}")


# =========================================================================== Frame
class Frame:
    """A rigid transform: rotation ``M`` and origin ``p`` (m). ``Frame(R, p)``, ``Frame(R)``,
    ``Frame(p)``, ``Frame()`` (the identity)."""

    __slots__ = ("M", "p")

    def __init__(self, *args) -> None:
        self.M, self.p = Rotation(), Vector()
        if len(args) == 1 and isinstance(args[0], Frame):
            self.M, self.p = Rotation(args[0].M), Vector(args[0].p)
            return
        if len(args) > 2:
            raise TypeError(f"Frame() takes a Rotation and/or a Vector, got {args!r}")
        for a in args:
            if isinstance(a, Rotation):
                self.M = Rotation(a)
            elif isinstance(a, Vector):
                self.p = Vector(a)
            else:
                raise TypeError(f"Frame() takes a Rotation and/or a Vector, got {a!r}")

    @staticmethod
    def Identity() -> Frame:
        return Frame()

    @staticmethod
    def DH(a: float, alpha: float, d: float, theta: float) -> Frame:
        """Standard Denavit–Hartenberg: RotZ(θ)·TransZ(d)·TransX(a)·RotX(α)."""
        R = _rz(theta) @ _rx(alpha)
        p = np.array([a * math.cos(theta), a * math.sin(theta), d])
        return Frame(_rot(R), _vec(p))

    @staticmethod
    def DH_Craig1989(a: float, alpha: float, d: float, theta: float) -> Frame:
        """Modified (Craig) Denavit–Hartenberg: RotX(α)·TransX(a)·RotZ(θ)·TransZ(d)."""
        R = _rx(alpha) @ _rz(theta)
        p = np.array([a, 0.0, 0.0]) + _rx(alpha) @ np.array([0.0, 0.0, d])
        return Frame(_rot(R), _vec(p))

    @property
    def array(self) -> np.ndarray:
        """The 4x4 homogeneous matrix (not in PyKDL)."""
        T = np.eye(4)
        T[:3, :3] = self.M.array
        T[:3, 3] = self.p.array
        return T

    def __getitem__(self, ij) -> float:
        i, j = ij
        if j == 3:
            return self.p[i]
        return self.M[i, j]

    def __setitem__(self, ij, value) -> None:
        i, j = ij
        if j == 3:
            self.p[i] = value
        else:
            self.M[i, j] = value

    def Inverse(self, arg=None):
        inv = Frame(self.M.Inverse(), -(self.M.Inverse() * self.p))
        return inv if arg is None else inv * arg

    def __mul__(self, other):
        if isinstance(other, Frame):
            return Frame(self.M * other.M, self.M * other.p + self.p)
        if isinstance(other, Vector):
            return self.M * other + self.p
        if isinstance(other, Twist):
            rot = self.M * other.rot
            return Twist(self.M * other.vel + self.p * rot, rot)
        if isinstance(other, Wrench):
            force = self.M * other.force
            return Wrench(force, self.M * other.torque + self.p * force)
        return NotImplemented

    def __eq__(self, other) -> bool:
        return isinstance(other, Frame) and Equal(self, other)

    def __ne__(self, other) -> bool:
        return not self == other

    __hash__ = None

    def __repr__(self) -> str:
        return f"{self.M!r}\n{self.p!r}"

    def __reduce__(self):
        return (Frame, (self.M, self.p))


# =========================================================================== JntArray
class JntArray:
    """``n`` joint values (zeros at first)."""

    __slots__ = ("array",)

    def __init__(self, arg=0) -> None:
        if isinstance(arg, JntArray):
            self.array = arg.array.copy()
        else:
            self.array = np.zeros(int(arg))

    def rows(self) -> int:
        return len(self.array)

    def columns(self) -> int:
        return 1

    def resize(self, n: int) -> None:
        self.array = np.resize(self.array, int(n))

    def __len__(self) -> int:
        return len(self.array)

    def __getitem__(self, i: int) -> float:
        return float(self.array[i])

    def __setitem__(self, i: int, value) -> None:
        self.array[i] = float(value)

    def __iter__(self):
        return iter(float(v) for v in self.array)

    def __eq__(self, other) -> bool:
        return (isinstance(other, JntArray) and len(other) == len(self)
                and bool(np.all(np.abs(self.array - other.array) < EPSILON)))  # fmt: skip

    __hash__ = None

    def __repr__(self) -> str:
        return "[" + ", ".join(f"{v:g}" for v in self.array) + "]"


# =========================================================================== functions
def Equal(a, b, eps: float = EPSILON) -> bool:
    """Every component of ``a`` and ``b`` (same type) within ``eps``."""
    if type(a) is not type(b):
        raise TypeError(f"Equal: {type(a).__name__} and {type(b).__name__}")
    return bool(np.all(np.abs(a.array - b.array) <= eps))


def diff(a, b, dt: float = 1.0):
    """The change from ``a`` to ``b`` over ``dt``: vectors ``(b - a)/dt``; rotations the
    rotation vector of ``a⁻¹·b`` expressed in the reference frame, ``/dt``; frames a
    :class:`Twist` of both; twists and wrenches component-wise."""
    if isinstance(a, Vector) and isinstance(b, Vector):
        return (b - a) / dt
    if isinstance(a, Rotation) and isinstance(b, Rotation):
        return a * (a.Inverse() * b).GetRot() / dt
    if isinstance(a, Frame) and isinstance(b, Frame):
        return Twist(diff(a.p, b.p, dt), diff(a.M, b.M, dt))
    if isinstance(a, _Six) and type(a) is type(b):
        return (b - a) / dt
    raise TypeError(f"diff: {type(a).__name__} and {type(b).__name__}")


def addDelta(a, da, dt: float = 1.0):
    """The inverse of :func:`diff`: ``a`` moved by ``da · dt``."""
    if isinstance(a, Vector):
        return a + da * dt
    if isinstance(a, Rotation):
        return Rotation.Rot(da, da.Norm() * dt) * a
    if isinstance(a, Frame):
        return Frame(addDelta(a.M, da.rot, dt), addDelta(a.p, da.vel, dt))
    raise TypeError(f"addDelta: {type(a).__name__}")


def SetToZero(x) -> None:
    """Zero a vector, twist, wrench or joint array in place."""
    if isinstance(x, Vector | JntArray):
        x.array[:] = 0.0
    elif isinstance(x, _Six):
        x._a.array[:] = 0.0
        x._b.array[:] = 0.0
    else:
        raise TypeError(f"SetToZero: {type(x).__name__}")
