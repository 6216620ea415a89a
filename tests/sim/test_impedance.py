"""The Cartesian impedance law (servo_ci): half planes, deadbands, biases, frames."""

import numpy as np

from davinci_sim.geometry import so3
from davinci_sim.sim.impedance import (
    CartesianImpedance,
    HalfPlaneGains,
    impedance_problem,
    impedance_wrench,
)


def _pose(p, R=None):
    T = np.eye(4)
    T[:3, :3] = np.eye(3) if R is None else R
    T[:3, 3] = p
    return T


def test_a_half_plane_spring_with_deadband_and_bias():
    g = CartesianImpedance(
        force_position=np.array([0.1, 0.0, 0.0]),
        position_positive=HalfPlaneGains(p=np.array([-200.0, 0, 0]),
                                         deadband=np.array([0.01, 0, 0]),
                                         bias=np.array([0.5, 0, 0])),
        position_negative=HalfPlaneGains(d=np.array([-5.0, 0, 0])),
    )  # fmt: skip
    # 3 cm on the positive side: 2 cm past the deadband -> -200 x 0.02 + 0.5
    w = impedance_wrench(g, _pose([0.13, 0, 0]), np.zeros(6))
    assert np.allclose(w, [-3.5, 0, 0, 0, 0, 0])
    # inside the deadband: the bias only
    assert np.allclose(impedance_wrench(g, _pose([0.105, 0, 0]), np.zeros(6))[:3], [0.5, 0, 0])
    # the negative side: no spring, its damper on the velocity
    w = impedance_wrench(g, _pose([0.05, 0, 0]), np.array([0.2, 0, 0, 0, 0, 0]))
    assert np.allclose(w, [-1.0, 0, 0, 0, 0, 0])


def test_the_force_and_torque_frames_orient_the_gains():
    R_z90 = so3.rotation_from_vector([0.0, 0.0, np.pi / 2])
    spring = HalfPlaneGains(p=np.array([-100.0, 0, 0]))  # along the frame's x only
    g = CartesianImpedance(force_orientation=R_z90, position_positive=spring,
                           position_negative=spring)  # fmt: skip
    # the frame's x is the reference's y: a y offset is pulled back, an x offset is not
    assert np.allclose(impedance_wrench(g, _pose([0, 0.01, 0]), np.zeros(6))[:3], [0, -1, 0])
    assert np.allclose(impedance_wrench(g, _pose([0.01, 0, 0]), np.zeros(6))[:3], 0)
    twist = HalfPlaneGains(p=np.array([0, 0, -0.2]))
    g = CartesianImpedance(orientation_positive=twist, orientation_negative=twist)
    R = so3.rotation_from_vector([0.0, 0.0, 0.3])
    assert np.allclose(impedance_wrench(g, _pose([0, 0, 0], R), np.zeros(6))[3:], [0, 0, -0.06])


def test_bad_gains_are_named():
    assert impedance_problem(CartesianImpedance()) == ""
    assert "force_orientation" in impedance_problem(
        CartesianImpedance(force_orientation=2 * np.eye(3))
    )
    assert "deadband" in impedance_problem(
        CartesianImpedance(orientation_negative=HalfPlaneGains(deadband=np.array([0, 0, 1e3])))
    )
    assert "force_position" in impedance_problem(CartesianImpedance(force_position="x"))
