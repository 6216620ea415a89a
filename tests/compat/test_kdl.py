"""The PyKDL subset against independent references: scipy's rotations and
``davinci_sim.geometry.se3`` transforms (with KDL's documented conventions)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation as R

from davinci_sim.compat import kdl as K
from davinci_sim.geometry.se3 import invert_transform, rot_x, rot_y, rot_z, transform

rng = np.random.default_rng(7)
ROTATIONS = R.random(40, random_state=3)


def frame(T: np.ndarray) -> K.Frame:
    M = K.Rotation(*T[:3, :3].ravel())
    return K.Frame(M, K.Vector(*T[:3, 3]))


def random_T() -> np.ndarray:
    return transform(R.random(random_state=int(rng.integers(1 << 30))).as_matrix(),
                     rng.normal(size=3))  # fmt: skip


def test_rpy_is_fixed_axes_xyz():
    for r, p, y in rng.uniform(-3.0, 3.0, size=(30, 3)) * [1, 0.5, 1]:
        expected = R.from_euler("xyz", [r, p, y]).as_matrix()  # extrinsic x, then y, then z
        assert np.allclose(K.Rotation.RPY(r, p, y).array, expected)
        assert np.allclose(K.Rotation.RPY(r, p, y).array, rot_z(y) @ rot_y(p) @ rot_x(r))
        assert np.allclose(K.Rotation.RPY(r, p, y).GetRPY(), (r, p, y))
        assert np.allclose(K.Rotation.EulerZYX(y, p, r).array, expected)
        assert np.allclose(K.Rotation.EulerZYX(y, p, r).GetEulerZYX(), (y, p, r))


def test_get_rpy_at_gimbal_lock_gives_zero_roll():
    M = K.Rotation.RPY(0.3, math.pi / 2, 0.5)
    roll, pitch, yaw = M.GetRPY()
    assert roll == 0.0 and pitch == pytest.approx(math.pi / 2)
    assert np.allclose(K.Rotation.RPY(roll, pitch, yaw).array, M.array)


def test_quaternion_both_ways_as_scipy():
    for rot in ROTATIONS:
        x, y, z, w = rot.as_quat()  # scipy: (x, y, z, w), as KDL
        M = K.Rotation.Quaternion(x, y, z, w)
        assert np.allclose(M.array, rot.as_matrix())
        q = np.array(M.GetQuaternion())
        assert np.isclose(np.linalg.norm(q), 1.0)
        assert np.allclose(q, rot.as_quat()) or np.allclose(q, -rot.as_quat())
        if np.trace(rot.as_matrix()) > 0:
            assert q[3] > 0  # KDL's branch for a positive trace
    # KDL does not normalise: a quaternion of norm n gives n² times the rotation
    assert np.allclose(
        K.Rotation.Quaternion(0, 0, 2, 0).array, 4 * R.from_quat([0, 0, 1, 0]).as_matrix()
    )
    assert np.allclose(K.Rotation.Quaternion(0, 0, 0, 0).array, 0.0)


def test_axis_angle_and_rotation_vector_as_scipy():
    for rot in ROTATIONS:
        rv = rot.as_rotvec()
        angle = np.linalg.norm(rv)
        M = K.Rotation.Rot(K.Vector(*(rv * 3.0)), angle)  # any axis length
        assert np.allclose(M.array, rot.as_matrix())
        assert np.allclose(M.GetRot().array, rv)
        a, axis = M.GetRotAngle()
        assert a == pytest.approx(angle) and np.allclose(axis.array * a, rv)
    for f, ref in ((K.Rotation.RotX, rot_x), (K.Rotation.RotY, rot_y), (K.Rotation.RotZ, rot_z)):
        assert np.allclose(f(0.7).array, ref(0.7))
    # a zero axis normalises to x, as KDL's Vector::Normalize
    assert np.allclose(K.Rotation.Rot(K.Vector(), 1.0).array, rot_x(1.0))
    assert K.Rotation().GetRotAngle()[0] == 0.0


def test_rotation_constructors_inverse_and_products():
    A, B = ROTATIONS[0].as_matrix(), ROTATIONS[1].as_matrix()
    MA = K.Rotation(*A.ravel())  # row after row
    assert np.allclose(
        K.Rotation(K.Vector(*A[:, 0]), K.Vector(*A[:, 1]), K.Vector(*A[:, 2])).array, A
    )
    assert MA[1, 2] == A[1, 2]
    assert np.allclose(MA.Inverse().array, A.T)
    assert np.allclose((MA * K.Rotation(*B.ravel())).array, A @ B)
    v = K.Vector(1.0, -2.0, 0.5)
    assert np.allclose((MA * v).array, A @ v.array)
    assert np.allclose(MA.Inverse(v).array, A.T @ v.array)
    assert np.allclose(MA.UnitY().array, A[:, 1])
    assert K.Rotation(MA) == MA and not (K.Rotation(MA) != MA)
    M = K.Rotation(MA)
    M.DoRotZ(0.4)
    assert np.allclose(M.array, A @ rot_z(0.4))


def test_vector_semantics():
    a, b = K.Vector(1.0, 2.0, 3.0), K.Vector(-1.0, 0.5, 2.0)
    assert np.allclose((a * b).array, np.cross(a.array, b.array))  # KDL: * is the cross product
    assert K.dot(a, b) == pytest.approx(np.dot(a.array, b.array))
    assert (a + b)[2] == 5.0 and (a - b).x() == 2.0 and (2 * a).z() == 6.0 and (a / 2)[0] == 0.5
    a.x(4.0)
    a[1] = 0.0
    assert list(a) == [4.0, 0.0, 3.0] and a.Norm() == 5.0
    assert a.Normalize() == 5.0 and a.Norm() == pytest.approx(1.0)
    zero = K.Vector()
    assert zero.Normalize() == 0.0 and list(zero) == [1.0, 0.0, 0.0]
    assert K.Vector(1, 2, 3) == K.Vector(1, 2, 3 + 1e-9) and K.Vector(1, 2, 3) != K.Vector(
        1, 2, 3.1
    )
    with pytest.raises(IndexError):
        a[3]
    with pytest.raises(TypeError):
        K.Vector(1.0, 2.0)


def test_frames_compose_and_invert_as_matrices():
    for _ in range(20):
        Ta, Tb = random_T(), random_T()
        Fa, Fb = frame(Ta), frame(Tb)
        assert np.allclose((Fa * Fb).array, Ta @ Tb)
        assert np.allclose(Fa.Inverse().array, invert_transform(Ta))
        p = rng.normal(size=3)
        assert np.allclose((Fa * K.Vector(*p)).array, (Ta @ [*p, 1.0])[:3])
        assert np.allclose(Fa.Inverse(K.Vector(*p)).array, (invert_transform(Ta) @ [*p, 1.0])[:3])
        assert Fa[0, 3] == Ta[0, 3] and Fa[2, 1] == Ta[2, 1]
    F = K.Frame(K.Vector(1, 2, 3))
    assert np.allclose(F.M.array, np.eye(3)) and F.p[2] == 3.0
    F.p[2] += 0.5  # scripts edit goals in place
    assert F.p.z() == 3.5


def _adjoint(T: np.ndarray) -> np.ndarray:
    """The 6x6 map of a twist (v, ω) from frame b to frame a, T = T_a_b."""
    Rm, p = T[:3, :3], T[:3, 3]
    P = np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
    Ad = np.zeros((6, 6))
    Ad[:3, :3], Ad[:3, 3:], Ad[3:, 3:] = Rm, P @ Rm, Rm
    return Ad


def test_twist_and_wrench_change_frames_as_the_adjoint():
    for _ in range(10):
        T = random_T()
        t = rng.normal(size=6)
        tw = K.Twist(K.Vector(*t[:3]), K.Vector(*t[3:]))
        assert np.allclose((frame(T) * tw).array, _adjoint(T) @ t)
        w = K.Wrench(K.Vector(*t[:3]), K.Vector(*t[3:]))
        # a wrench (f, τ) maps with the dual: f' = R f, τ' = R τ + p × R f
        Rm, p = T[:3, :3], T[:3, 3]
        assert np.allclose(
            (frame(T) * w).array, [*(Rm @ t[:3]), *(Rm @ t[3:] + np.cross(p, Rm @ t[:3]))]
        )
        # power is frame-independent
        assert K.dot(frame(T) * tw, frame(T) * w) == pytest.approx(K.dot(tw, w))
        v = K.Vector(*rng.normal(size=3))
        assert np.allclose(tw.RefPoint(v).vel.array, t[:3] + np.cross(t[3:], v.array))
    tw = K.Twist(K.Vector(1, 2, 3), K.Vector(4, 5, 6))
    assert (
        tw[4] == 5.0
        and (tw * 2)[0] == 2.0
        and (-tw).rot[2] == -6.0
        and list(tw) == [1, 2, 3, 4, 5, 6]
    )
    assert K.Twist.Zero() == K.Twist()


def test_diff_and_add_delta_round_trip():
    for _ in range(10):
        Fa, Fb = frame(random_T()), frame(random_T())
        d = K.diff(Fa, Fb)
        assert isinstance(d, K.Twist)
        assert K.Equal(K.addDelta(Fa, d), Fb, 1e-9)
        # diff of rotations: the rotation vector of Ra⁻¹·Rb, expressed in the reference
        rv = R.from_matrix(Fa.M.array.T @ Fb.M.array).as_rotvec()
        assert np.allclose(d.rot.array, Fa.M.array @ rv)


def test_jntarray():
    q = K.JntArray(3)
    q[1] = 0.5
    assert q.rows() == 3 and list(q) == [0.0, 0.5, 0.0]
    q.resize(4)
    assert q.rows() == 4 and list(q) == [0.0, 0.5, 0.0, 0.0]
    with pytest.raises(TypeError):
        len(q)  # as PyKDL: no len()


def test_pickles():
    import pickle

    F = frame(random_T())
    assert pickle.loads(pickle.dumps(F)) == F
