"""A subset of PyKDL (the Orocos KDL Python bindings, 1.5) with the same names and semantics.

dVRK Python scripts get Cartesian poses as ``PyKDL.Frame`` and build goals with
``PyKDL.Rotation.RPY``, ``PyKDL.Vector`` … ``davinci-sim run`` uses the real PyKDL when the
platform has one (:mod:`davinci_sim.compat.pykdl`); this module stands in for it otherwise.
Its behaviour is the real one's, checked operation by operation against it
(``tests/compat/test_kdl_differential.py``). This module holds :class:`Rotation`,
:class:`Frame`, :func:`diff` and :func:`addDelta`; :mod:`~.kdl_values` the values without a
rotation; :mod:`~.kdl_math` the numbers.

Value and reference semantics, as pybind11 gives them to PyKDL:

* reading ``frame.p``, ``frame.M``, ``twist.vel``/``rot``, ``wrench.force``/``torque``
  gives a *view* of the owner: ``v = f.p; v[0] = 1`` changes ``f``, and ``v`` follows a
  later ``f.p = …``;
* assigning one (``goal.p = start.p``) and every constructor *copy* the values: changing
  ``goal.p`` afterwards leaves ``start`` alone;
* ``+=``/``-=`` (vectors, twists, wrenches) change the object in place; ``*=``, ``/=`` make
  a new one; ``Normalize``, ``ReverseSign``, ``DoRotX``, ``SetInverse``, ``SetToZero``,
  ``x(value)``, item assignment change it in place;
* indices are ints from 0 (negative ones raise ``IndexError``); ``len()`` is not defined;
  ``==`` is ``Equal`` (|a - b| < 1e-6 for every number), ``False`` against another type;
  the objects are unhashable; ``repr`` prints as KDL's C++ streams.

The classes: :class:`Vector` (``Vector * Vector`` is the cross product, :func:`dot`),
:class:`Rotation` (built from 9 numbers row after row, 3 column vectors, ``RPY``,
``EulerZYX``, ``EulerZYZ``, ``Quaternion(x, y, z, w)``, ``Rot``, ``Rot2``, ``RotX/Y/Z``; read
with ``GetRPY``, ``GetEulerZYX/ZYZ``, ``GetQuaternion``, ``GetRot``, ``GetRotAngle``),
:class:`Frame` (``M``, ``p`` in m; ``DH``, ``DH_Craig1989``, ``Integrate``), :class:`Twist`,
:class:`Wrench`, :class:`JntArray`; :func:`diff`, :func:`addDelta`, :func:`Equal`,
:func:`SetToZero`. Every object keeps its numbers in a float numpy array, ``.array`` (not in
PyKDL; a frame's is its 4x4 matrix, a copy).
"""

from __future__ import annotations

import numpy as np

from davinci_sim.compat import kdl_math as km
from davinci_sim.compat.kdl_math import EPSILON
from davinci_sim.compat.kdl_values import (
    Equal,
    JntArray,
    SetToZero,
    Twist,
    Vector,
    Wrench,
    _args,
    _float,
    _index2,
    _Six,
    _six,
    _Value,
    _vec,
    _vector,
    _view,
    dot,
)

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


# =========================================================================== Rotation
class Rotation(_Value):
    """A 3x3 rotation. ``Rotation()`` is the identity; ``Rotation(Xx, Yx, Zx, Xy, Yy, Zy,
    Xz, Yz, Zz)`` takes the matrix row after row; ``Rotation(x, y, z)`` its three columns;
    ``Rotation(other)`` a copy."""

    __slots__ = ()

    def __init__(self, *args, **kwargs) -> None:
        names9 = ("xx", "yx", "zx", "xy", "yy", "zy", "xz", "yz", "zz")
        args = _args("Rotation", args, kwargs, names9 if len(args) + len(kwargs) == 9
                     else ("x", "y", "z"))  # fmt: skip
        if not args:
            self.array = np.eye(3)
        elif len(args) == 1 and isinstance(args[0], Rotation):
            self.array = args[0].array.copy()
        elif len(args) == 9:
            self.array = np.array([_float(a) for a in args]).reshape(3, 3)
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
        return _rot(km.rot_x(_float(angle)))

    @staticmethod
    def RotY(angle: float) -> Rotation:
        return _rot(km.rot_y(_float(angle)))

    @staticmethod
    def RotZ(angle: float) -> Rotation:
        return _rot(km.rot_z(_float(angle)))

    @staticmethod
    def RPY(roll: float, pitch: float, yaw: float) -> Rotation:
        """Roll about x, then pitch about y, then yaw about z, all fixed axes."""
        return _rot(km.rpy(_float(roll), _float(pitch), _float(yaw)))

    @staticmethod
    def EulerZYX(alpha: float, beta: float, gamma: float) -> Rotation:
        """About z by alpha, then the new y by beta, then the new x by gamma."""
        return Rotation.RPY(gamma, beta, alpha)

    @staticmethod
    def EulerZYZ(alpha: float, beta: float, gamma: float) -> Rotation:
        return _rot(km.euler_zyz(_float(alpha), _float(beta), _float(gamma)))

    @staticmethod
    def Quaternion(x: float, y: float, z: float, w: float) -> Rotation:
        """From (x, y, z, w), not normalised (KDL's: give a unit quaternion)."""
        return _rot(km.quaternion(_float(x), _float(y), _float(z), _float(w)))

    @staticmethod
    def Rot(axis: Vector, angle: float) -> Rotation:
        """About ``axis`` (normalised; a zero axis counts as x) by ``angle`` rad."""
        return _rot(km.rot2(km.normalized(_vector(axis).array)[0], _float(angle)))

    @staticmethod
    def Rot2(axis: Vector, angle: float) -> Rotation:
        """As :meth:`Rot` for a unit ``axis``, taken as given."""
        return _rot(km.rot2(_vector(axis).array, _float(angle)))

    # ---------------------------------------------------------- read back
    def GetRPY(self) -> tuple[float, float, float]:
        return km.get_rpy(self.array)

    def GetEulerZYX(self) -> tuple[float, float, float]:
        roll, pitch, yaw = km.get_rpy(self.array)
        return yaw, pitch, roll

    def GetEulerZYZ(self) -> tuple[float, float, float]:
        return km.get_euler_zyz(self.array)

    def GetQuaternion(self) -> tuple[float, float, float, float]:
        return km.get_quaternion(self.array)

    def GetRotAngle(self, eps: float = EPSILON) -> tuple[float, Vector]:
        """(angle in [0, π], unit axis); the identity gives (0, (0, 0, 1))."""
        angle, axis = km.get_rot_angle(self.array, eps)
        return angle, _vec(axis)

    def GetRot(self) -> Vector:
        """The rotation vector: axis · angle (rad)."""
        angle, axis = km.get_rot_angle(self.array)
        return _vec(axis * angle)

    def _unit(self, j: int, v):
        if v is None:
            return _vec(self.array[:, j])
        self.array[:, j] = _vector(v).array
        return None

    def UnitX(self, v: Vector | None = None):
        """The x axis (column 0); with a vector, set it."""
        return self._unit(0, v)

    def UnitY(self, v: Vector | None = None):
        return self._unit(1, v)

    def UnitZ(self, v: Vector | None = None):
        return self._unit(2, v)

    def Inverse(self, arg=None):
        """The transpose; with a vector, twist or wrench, the transpose applied to it."""
        inv = _rot(self.array.T)
        if arg is None:
            return inv
        if not isinstance(arg, Vector | Twist | Wrench):
            raise TypeError(f"Rotation.Inverse: {type(arg).__name__}")
        return inv * arg

    def SetInverse(self) -> None:
        self.array[:] = self.array.T.copy()

    def DoRotX(self, angle: float) -> None:
        self.array[:] = km.matmul(self.array, km.rot_x(_float(angle)))

    def DoRotY(self, angle: float) -> None:
        self.array[:] = km.matmul(self.array, km.rot_y(_float(angle)))

    def DoRotZ(self, angle: float) -> None:
        self.array[:] = km.matmul(self.array, km.rot_z(_float(angle)))

    # ---------------------------------------------------------- operators
    def __getitem__(self, ij) -> float:
        return float(self.array[_index2(ij, 3, 3, "Rotation")])

    def __setitem__(self, ij, value) -> None:
        self.array[_index2(ij, 3, 3, "Rotation")] = _float(value)

    def __mul__(self, other):
        if isinstance(other, Rotation):
            return _rot(km.matmul(self.array, other.array))
        if isinstance(other, Vector):
            return _vec(km.matmul(self.array, other.array))
        if isinstance(other, Twist | Wrench):
            a, b = km.matmul(self.array, other.array[:3]), km.matmul(self.array, other.array[3:])
            return _six(type(other), a, b)
        return NotImplemented

    def __repr__(self) -> str:
        return km.rotation_text(self.array)

    def __reduce__(self):  # PyKDL pickles a rotation as its roll, pitch, yaw
        return (Rotation.RPY, self.GetRPY())


def _rot(a) -> Rotation:
    return _view(Rotation, np.array(a, dtype=float))


# =========================================================================== Frame
class Frame(_Value):
    """A rigid transform: rotation ``M`` and origin ``p`` (m). ``Frame(R, p)``, ``Frame(R)``,
    ``Frame(p)``, ``Frame(other)`` (copies), ``Frame()`` (the identity)."""

    __slots__ = ("_M", "_p")

    def __init__(self, *args, **kwargs) -> None:
        args = _args("Frame", args, kwargs, ("R", "V"))
        self._M, self._p = Rotation(), Vector()
        if len(args) == 1 and isinstance(args[0], Frame):
            self.M, self.p = args[0].M, args[0].p
        elif len(args) == 1 and isinstance(args[0], Rotation):
            self.M = args[0]
        elif len(args) == 1 and isinstance(args[0], Vector):
            self.p = args[0]
        elif len(args) == 2 and isinstance(args[0], Rotation) and isinstance(args[1], Vector):
            self.M, self.p = args
        elif args:
            raise TypeError(f"Frame() takes (Rotation, Vector), one of them or a Frame: {args!r}")

    @property
    def M(self) -> Rotation:
        return self._M

    @M.setter
    def M(self, value: Rotation) -> None:
        if not isinstance(value, Rotation):
            raise TypeError(f"Frame.M is a Rotation, got {value!r}")
        self._M.array[:] = value.array

    @property
    def p(self) -> Vector:
        return self._p

    @p.setter
    def p(self, value: Vector) -> None:
        self._p.array[:] = _vector(value).array

    @staticmethod
    def Identity() -> Frame:
        return Frame()

    @staticmethod
    def DH(a: float, alpha: float, d: float, theta: float) -> Frame:
        """Standard Denavit–Hartenberg: RotZ(θ)·TransZ(d)·TransX(a)·RotX(α)."""
        R, p = km.dh(_float(a), _float(alpha), _float(d), _float(theta))
        return Frame(_rot(R), _vec(p))

    @staticmethod
    def DH_Craig1989(a: float, alpha: float, d: float, theta: float) -> Frame:
        """Modified (Craig) Denavit–Hartenberg: RotX(α)·TransX(a)·RotZ(θ)·TransZ(d)."""
        R, p = km.dh_craig1989(_float(a), _float(alpha), _float(d), _float(theta))
        return Frame(_rot(R), _vec(p))

    @property
    def array(self) -> np.ndarray:
        """The 4x4 homogeneous matrix, a copy (not in PyKDL)."""
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = self._M.array, self._p.array
        return T

    def __getitem__(self, ij) -> float:
        i, j = _index2(ij, 3, 4, "Frame")
        return self._p[i] if j == 3 else self._M[i, j]

    def __setitem__(self, ij, value) -> None:
        i, j = _index2(ij, 3, 4, "Frame")
        if j == 3:
            self._p[i] = value
        else:
            self._M[i, j] = value

    def Inverse(self, arg=None):
        """The inverse transform; with a vector, twist or wrench, it applied to that."""
        if arg is None:
            return Frame(self.M.Inverse(), -(self.M.Inverse() * self.p))
        if isinstance(arg, Vector):
            return self.M.Inverse(arg - self.p)
        if isinstance(arg, Twist):
            return Twist(self.M.Inverse(arg.vel - self.p * arg.rot), self.M.Inverse(arg.rot))
        if isinstance(arg, Wrench):
            return Wrench(self.M.Inverse(arg.force),
                          self.M.Inverse(arg.torque - self.p * arg.force))  # fmt: skip
        raise TypeError(f"Frame.Inverse: {type(arg).__name__}")

    def Integrate(self, twist: Twist, samplefrequency: float) -> None:
        """Move by ``twist`` (in this frame's own axes) for one sample of ``samplefrequency``
        Hz, in place."""
        n = twist.rot.Norm() / samplefrequency
        if n < EPSILON:
            self.p = self.p + self.M * (twist.vel / samplefrequency)
        else:
            moved = self * Frame(Rotation.Rot(twist.rot, n), twist.vel / samplefrequency)
            self.M, self.p = moved.M, moved.p

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

    def __repr__(self) -> str:
        return f"[{self.M!r}\n{self.p!r}]"

    def __reduce__(self):
        return (Frame, (self.M, self.p))


# =========================================================================== functions
def diff(a, b, dt: float = 1.0):
    """The change from ``a`` to ``b`` over ``dt``: vectors ``(b - a)/dt``; rotations the
    rotation vector of ``a⁻¹·b`` expressed in the reference frame, ``/dt``; frames a
    :class:`Twist` of both; twists and wrenches part by part."""
    if type(a) is not type(b) or not isinstance(a, Vector | Rotation | Frame | _Six):
        raise TypeError(f"diff: {type(a).__name__} and {type(b).__name__}")
    if isinstance(a, Rotation):
        return a * (a.Inverse() * b).GetRot() / dt
    if isinstance(a, Frame):
        return Twist(diff(a.p, b.p, dt), diff(a.M, b.M, dt))
    return (b - a) / dt


def addDelta(a, da, dt: float = 1.0):
    """The inverse of :func:`diff`: ``a`` moved by ``da · dt``."""
    if isinstance(a, Vector | _Six) and type(da) is type(a):
        return a + da * dt
    if isinstance(a, Rotation) and isinstance(da, Vector):
        return _rot(km.rotation_vector_matrix(da.array * dt)) * a
    if isinstance(a, Frame) and isinstance(da, Twist):
        return Frame(addDelta(a.M, da.rot, dt), addDelta(a.p, da.vel, dt))
    raise TypeError(f"addDelta: {type(a).__name__} and {type(da).__name__}")
