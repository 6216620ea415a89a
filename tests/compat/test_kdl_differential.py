"""The PyKDL subset against the real PyKDL: the same random programs run through both.

A program is a list of operations on a shared pool of objects: constructors (numbers,
copies, ``RPY``, ``Quaternion``, ``Rot`` …), reads of ``frame.p``/``frame.M``/``twist.vel``
… (views, kept in the pool), assignments of those attributes, item assignment, in-place
methods (``Normalize``, ``DoRotX``, ``+=`` …), arithmetic, ``Inverse``, ``diff``/``addDelta``,
read-backs (``GetRPY``, ``GetQuaternion``, ``GetRotAngle`` …), ``==``, copies and pickles,
with bad indices and wrong types among them. After every operation its result (or the class
of the exception it raised) and *every object of the pool* must be the same in both
libraries: an assignment that aliases where PyKDL copies shows as a changed object.

The real PyKDL is the system's (Debian's ``python3-pykdl``, which ``scripts/system-deps.sh``
installs; ``davinci_sim.compat.pykdl`` finds it); without it the test is skipped.
"""

from __future__ import annotations

import copy
import math
import operator
import pickle
import random
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from davinci_sim.compat import kdl as ours
from davinci_sim.compat import pykdl

REAL = pykdl.load()
pytestmark = pytest.mark.skipif(
    REAL is None,
    reason="no real PyKDL this interpreter can load (Debian: apt-get install python3-pykdl)",
)


@pytest.fixture(autouse=True, scope="module")
def _real_pykdl_importable():
    """The real one as ``PyKDL`` while these tests run (pickle finds its classes there)."""
    before = sys.modules.get("PyKDL")
    sys.modules["PyKDL"] = REAL
    yield
    if before is None:
        sys.modules.pop("PyKDL", None)
    else:
        sys.modules["PyKDL"] = before


KINDS = ("Vector", "Rotation", "Frame", "Twist", "Wrench")
PARTS = {"Frame": ("p", "M"), "Twist": ("vel", "rot"), "Wrench": ("force", "torque")}


# =========================================================================== one step
def pick(pool: list, kind: str | tuple, i: int):
    """The ``i``-th (cyclically) object of ``kind`` in the pool, or None."""
    kinds = (kind,) if isinstance(kind, str) else kind
    found = [o for o in pool if type(o).__name__ in kinds]
    return found[i % len(found)] if found else None


def step(K, pool: list, op: str, n: list[int], x: list[float]):
    """Run operation ``op`` with PyKDL module ``K`` on ``pool``; ``n`` are small ints, ``x``
    numbers. New objects go into the pool; the value returned is compared."""
    V = lambda i: pick(pool, "Vector", n[i])  # noqa: E731
    if op == "new":  # constructors
        which = n[0] % 22
        R = K.Rotation
        made = [
            lambda: K.Vector(x[0], x[1], x[2]),
            lambda: K.Vector(V(1)),
            lambda: R.RPY(x[0], x[1], x[2]),
            lambda: R.EulerZYX(x[0], x[1], x[2]),
            lambda: R.EulerZYZ(x[0], x[1], x[2]),
            lambda: R.Quaternion(*(np.array(x[:4]) / (np.linalg.norm(x[:4]) or 1.0))),
            lambda: R.Quaternion(x[0], x[1], x[2], x[3]),  # not unit: KDL does not normalise
            lambda: R.Rot(V(1), x[0]),
            lambda: R.Rot2(V(1), x[0]),
            lambda: (R.RotX, R.RotY, R.RotZ)[n[1] % 3](x[0]),
            lambda: R(*x[:9]),
            lambda: R(V(1), V(2), V(3)),
            lambda: R(pick(pool, "Rotation", n[1])),
            lambda: K.Frame(pick(pool, "Rotation", n[1]), V(2)),
            lambda: K.Frame(pick(pool, "Rotation", n[1])),
            lambda: K.Frame(V(1)),
            lambda: K.Frame(pick(pool, "Frame", n[1])),
            lambda: (K.Frame.DH, K.Frame.DH_Craig1989)[n[1] % 2](x[0], x[1], x[2], x[3]),
            lambda: K.Twist(V(1), V(2)),
            lambda: K.Wrench(V(1), V(2)),
            lambda: K.Twist(pick(pool, "Twist", n[1])),
            lambda: (K.Frame(), K.Rotation.Identity(), K.Twist.Zero(), K.Wrench.Zero())[n[1] % 4],
        ][which]
        pool.append(made())
        return None
    if op == "part":  # a view: v = frame.p
        o = pick(pool, tuple(PARTS), n[0])
        if o is None:
            return None
        pool.append(getattr(o, PARTS[type(o).__name__][n[1] % 2]))
        return None
    if op == "assign":  # goal.p = start.p (or a wrong type)
        o = pick(pool, tuple(PARTS), n[0])
        if o is None:
            return None
        name = PARTS[type(o).__name__][n[1] % 2]
        kind = "Rotation" if name == "M" else "Vector"
        value = pick(pool, kind if n[3] % 8 else "Frame", n[2])
        setattr(o, name, value)
        return None
    if op == "setitem":
        o = pool[n[0] % len(pool)]
        if isinstance(o, K.Rotation | K.Frame):
            o[n[1] % 5 - 1, n[2] % 6 - 1] = x[0]  # -1 … 3, -1 … 4: some out of range
        else:
            o[n[1] % 9 - 1] = x[0]  # -1 … 7
        return None
    if op == "inplace":
        i = n[0] % len(pool)
        o = pool[i]
        kind = type(o).__name__
        which = n[1] % 6
        if kind in ("Vector", "Twist", "Wrench") and which >= 4:  # o += other: o itself
            other = pick(pool, kind, n[2])
            pool[i] = operator.iadd(o, other) if which == 4 else operator.isub(o, other)
            return None
        if kind == "Vector":
            return [lambda: o.Normalize(), o.ReverseSign, lambda: K.SetToZero(o),
                    lambda: (o.x, o.y, o.z)[n[2] % 3](x[0])][which]()  # fmt: skip
        if kind in ("Twist", "Wrench"):
            return [o.ReverseSign, lambda: K.SetToZero(o)][which % 2]()
        if kind == "Rotation":
            return [lambda: o.DoRotX(x[0]), lambda: o.DoRotY(x[0]), lambda: o.DoRotZ(x[0]),
                    o.SetInverse, lambda: (o.UnitX, o.UnitY, o.UnitZ)[n[2] % 3](V(2)),
                    lambda: o.DoRotZ(x[1])][which]()  # fmt: skip
        twist = pick(pool, "Twist", n[2])  # a frame
        if twist is not None and which < 3:
            o.Integrate(twist, 1.0 + abs(x[0]))
        return None
    if op == "rebind":  # b = f.p; b *= 2: a new object, f unchanged
        i = n[0] % len(pool)
        if isinstance(pool[i], K.Vector | K.Twist | K.Wrench):
            o = pool[i]
            o *= x[0]
            pool[i] = o
        return None
    if op == "arith":
        a, b = pool[n[0] % len(pool)], pool[n[1] % len(pool)]
        which = n[2] % 9
        s = x[0] if x[0] != 0 else 0.5
        result = [lambda: a + b, lambda: a - b, lambda: a * b, lambda: a * s, lambda: s * a,
                  lambda: a / s, lambda: -a, lambda: a * pick(pool, KINDS[n[3] % 5], n[4]),
                  lambda: pick(pool, ("Rotation", "Frame"), n[3]) * b][which]()  # fmt: skip
        pool.append(result)
        return None
    if op == "inverse":
        o = pick(pool, ("Rotation", "Frame"), n[0])
        if o is None:
            return None
        arg = pick(pool, ("Vector", "Twist", "Wrench"), n[1]) if n[2] % 2 else None
        pool.append(o.Inverse() if arg is None else o.Inverse(arg))
        return None
    if op == "delta":
        a = pool[n[0] % len(pool)]
        b = pick(pool, type(a).__name__, n[1])
        dt = 0.5 + abs(x[0])
        if n[2] % 2:
            pool.append(K.diff(a, b, dt))
        else:
            da = {"Rotation": "Vector", "Frame": "Twist"}.get(type(a).__name__, type(a).__name__)
            pool.append(K.addDelta(a, pick(pool, da, n[1]), dt))
        return None
    if op == "read":  # read-backs, compared
        o = pool[n[0] % len(pool)]
        other = pool[n[1] % len(pool)]
        which = n[2] % 12
        if which == 0:
            return o == other, o != other
        if which == 1 and type(o) is type(other):
            return K.Equal(o, other, 10.0 ** -(n[3] % 8))
        if which == 2:
            return list(o) if isinstance(o, K.Vector | K.Twist | K.Wrench) else None
        if which == 3:
            return o[n[3] % 8 - 1] if isinstance(o, K.Vector | K.Twist | K.Wrench) else None
        if which == 4 and isinstance(o, K.Frame | K.Rotation):
            return o[n[3] % 5 - 1, n[4] % 6 - 1]
        if which == 5 and isinstance(o, K.Vector):
            return o.Norm(), o.x(), o.y(), o.z(), K.dot(o, V(1))
        if which == 6 and isinstance(o, K.Twist | K.Wrench):
            base = V(1)
            return o.RefPoint(base), K.dot(o, pick(pool, {"Twist": "Wrench"}.get(
                type(o).__name__, "Twist"), n[3]))  # fmt: skip
        if isinstance(o, K.Rotation):
            return [o.GetRPY, o.GetEulerZYX, o.GetEulerZYZ, o.GetQuaternion, o.GetRot,
                    lambda: o.GetRotAngle(10.0 ** -(3 + n[3] % 6)), o.UnitX, o.UnitY,
                    o.UnitZ, o.GetRotAngle, o.GetQuaternion, o.GetRPY][which]()  # fmt: skip
        return None
    if op == "copy":
        o = pool[n[0] % len(pool)]
        made = [copy.copy, copy.deepcopy, lambda v: pickle.loads(pickle.dumps(v))][n[1] % 3](o)
        pool.append(made)
        return None
    raise ValueError(op)


# =========================================================================== comparing
def plain(v):
    """A value of either library as plain numbers (type name first), to compare."""
    name = type(v).__name__
    if name in ("Vector", "Twist", "Wrench"):
        return (name, *(float(v[i]) for i in range(3 if name == "Vector" else 6)))
    if name == "Rotation":
        return (name, *(float(v[i, j]) for i in range(3) for j in range(3)))
    if name == "Frame":
        return (name, *(float(v[i, j]) for i in range(3) for j in range(4)))
    if isinstance(v, tuple | list):
        return tuple(plain(e) for e in v)
    if isinstance(v, bool) or v is None:
        return v
    return float(v)


def same(a, b) -> bool:
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(same(p, q) for p, q in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float):
        if math.isnan(a) or math.isnan(b):
            return math.isnan(a) and math.isnan(b)
        if math.isclose(abs(a), math.pi, abs_tol=1e-9) and math.isclose(abs(b), math.pi,
                                                                         abs_tol=1e-9):  # fmt: skip
            # (−π and π are one angle: GetRPY's atan2 gives either for a rotation of π, by
            # the sign of a zero; a clean clone's run saw PyKDL's −π against our π)
            return True
        return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-9)
    return a == b


def outcome(K, pool, op, n, x):
    try:
        return ("value", plain(step(K, pool, op, n, x)))
    except (TypeError, IndexError, ValueError, ZeroDivisionError) as e:
        return ("raised", type(e).__name__)


OPS = ("new", "new", "new", "part", "part", "assign", "assign", "setitem", "inplace", "inplace",
       "rebind", "arith", "inverse", "delta", "read", "read", "copy")  # fmt: skip
SPECIAL = (0.0, 1.0, -1.0, math.pi, -math.pi, math.pi / 2, -math.pi / 2, 1e-8)
operation = st.tuples(st.sampled_from(OPS), st.integers(0, 2**32 - 1))
"""An operation and the seed of its arguments (drawn here: hypothesis draws two numbers per
operation, fast, and still shrinks a failing program to its few operations)."""


def arguments(seed: int) -> tuple[list[int], list[float]]:
    """5 small ints and 9 numbers in [-3.5, 3.5], a quarter of them special angles."""
    rng = random.Random(seed)
    n = [rng.randrange(1000) for _ in range(5)]
    x = [rng.choice(SPECIAL) if rng.random() < 0.25 else rng.uniform(-3.5, 3.5) for _ in range(9)]
    return n, x


def run_both(program) -> None:
    """Run ``program`` through both libraries, comparing after every operation."""
    pools = {}
    for K in (REAL, ours):
        pools[K] = [K.Vector(0.1, -0.2, 0.3), K.Frame(K.Rotation.RPY(0.1, 0.2, 0.3),
                    K.Vector(1.0, 2.0, 3.0)), K.Twist(K.Vector(1, 2, 3), K.Vector(-1, 0.5, 2)),
                    K.Wrench(K.Vector(0, 0, -3), K.Vector(0.1, 0, 0))]  # fmt: skip
    for k, (op, seed) in enumerate(program):
        n, x = arguments(seed)
        got = {K: outcome(K, pools[K], op, n, x) for K in (REAL, ours)}
        where = f"operation {k} {op} {n} {x}"
        assert same(got[REAL], got[ours]), f"{where}: PyKDL {got[REAL]}, ours {got[ours]}"
        real_pool, our_pool = plain(pools[REAL]), plain(pools[ours])
        assert same(real_pool, our_pool), f"after {where}:\nPyKDL {real_pool}\nours  {our_pool}"


@settings(max_examples=200, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])  # fmt: skip
@given(st.lists(operation, min_size=10, max_size=60))
def test_random_programs_give_the_same_results_and_objects(program):
    run_both(program)


# =========================================================================== named cases
def test_what_the_dvrk_scripts_do_with_frames():
    """The assignments of upstream scripts (a goal made from a start pose, then edited;
    ``x = f.p`` followed by ``f.p = …``): the same objects in both."""
    for K in (REAL, ours):
        start = K.Frame(K.Rotation.RPY(0.1, -0.2, 0.3), K.Vector(0.01, 0.02, -0.1))
        goal = K.Frame()
        goal.p = start.p
        goal.M = start.M
        goal.p[2] -= 0.02  # the second move of a move_cp example
        assert start.p[2] == pytest.approx(-0.1) and goal.p[2] == pytest.approx(-0.12)
        view = goal.p
        view[0] = 0.5  # a view: goal changes
        assert goal.p[0] == 0.5 and start.p[0] == pytest.approx(0.01)
        goal.p = K.Vector(1.0, 1.0, 1.0)
        assert view[0] == 1.0  # and follows the assignment
        t = K.Twist()
        vel = t.vel
        vel += K.Vector(3.0, 0.0, 0.0)  # in place
        assert vel.Normalize() == 3.0 and t[0] == 1.0  # a view of t: t too
        scaled = t.rot
        scaled *= 2.0  # a new object: t unchanged
        assert t[0] == 1.0 and scaled is not t.rot


def test_printing_is_the_same():
    for make in (
        lambda K: K.Vector(1.0, -2.5, 3.25e-7),
        lambda K: K.Rotation.RPY(0.1, 0.2, -0.3),
        lambda K: K.Frame(K.Rotation.RotZ(math.pi), K.Vector(1e6, -0.0, 12345.678)),
        lambda K: K.Twist(K.Vector(1, 2, 3), K.Vector(4, 5, 6)) / 3.0,
        lambda K: K.Wrench(K.Vector(-1, 0, 1e-12), K.Vector(7, 8, 9)),
        lambda K: K.JntArray(3),
    ):
        assert repr(make(ours)) == repr(make(REAL)) and str(make(ours)) == str(make(REAL))


def test_errors_are_the_same():
    calls = (
        lambda K: K.Vector(1.0, 2.0),
        lambda K: K.Vector("1", 2, 3),
        lambda K: K.Vector()[3],
        lambda K: K.Vector()[-1],
        lambda K: K.Vector()[1.0],
        lambda K: len(K.Vector()),
        lambda K: hash(K.Vector()),
        lambda K: K.Frame(K.Vector(), K.Rotation()),
        lambda K: K.Twist(K.Wrench()),
        lambda K: K.Rotation()[3, 0],
        lambda K: K.Frame()[2, 4],
        lambda K: K.Vector() + 1.0,
        lambda K: 2.0 / K.Vector(),
        lambda K: K.Vector() * K.Rotation(),
        lambda K: K.Twist() * K.Twist(),
        lambda K: K.dot(K.Twist(), K.Twist()),
        lambda K: K.Equal(K.Vector(), K.Rotation()),
        lambda K: K.JntArray(2)[2],
        lambda K: K.diff(K.Vector(), K.Rotation()),
    )
    for k, call in enumerate(calls):
        errors = []
        for K in (REAL, ours):
            with pytest.raises(Exception) as raised:
                call(K)
            errors.append(type(raised.value))
        assert errors[0] is errors[1], f"call {k}: PyKDL {errors[0]}, ours {errors[1]}"
    for K in (REAL, ours):
        assert (K.Vector() == 1) is False and (K.Vector() != K.Twist()) is True
