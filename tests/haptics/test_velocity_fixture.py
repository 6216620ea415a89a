"""The tip velocity filter, fixture sums and the force-field adapter of the haptic loop."""

from __future__ import annotations

import math

import numpy as np
import pytest

from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics.combine import FixtureSum, combine
from davinci_sim.haptics.field import ForceField, HapticState, as_wrench
from davinci_sim.haptics.fixture import Fixture, FixtureField
from davinci_sim.haptics.spring import SpringGuidance
from davinci_sim.haptics.velocity import VelocityFilter, lowpass_alpha
from davinci_sim.haptics.viscous import ViscousGuidance
from davinci_sim.haptics.wall import PlaneWall

LINE = Polyline([[-0.1, 0.0, 0.0], [0.1, 0.0, 0.0]])


def test_filter_tracks_a_ramp_and_has_the_documented_gain():
    """Constant velocity is recovered exactly (after the transient); a sinusoid at the
    cut-off comes out with gain ≈ 1/√2 (first-order low-pass of the derivative)."""
    dt, fc = 0.001, 20.0
    f = VelocityFilter((2,), dt=dt, cutoff_hz=fc)
    assert f.alpha == pytest.approx(1 - math.exp(-2 * math.pi * fc * dt))
    t = np.arange(2000) * dt
    v_true = np.array([[0.01, -0.02, 0.0], [0.0, 0.0, 0.05]])
    for k, tk in enumerate(t):
        v = f.update(v_true * tk)
        if k == 0:
            np.testing.assert_array_equal(v, 0.0)  # no predecessor
    np.testing.assert_allclose(v, v_true, rtol=1e-9)
    g = VelocityFilter(dt=dt, cutoff_hz=fc)
    amp = []
    for tk in t:
        amp.append(g.update([math.sin(2 * math.pi * fc * tk), 0, 0])[0])
    measured = np.max(np.abs(amp[1000:])) / (2 * math.pi * fc)
    assert measured == pytest.approx(1 / math.sqrt(2), rel=0.03)


def test_filter_reset_per_track_and_noise_reduction():
    rng = np.random.default_rng(0)
    f = VelocityFilter((500,), dt=0.001)
    sigma = 1e-6
    raw, out, prev = [], [], None
    for _ in range(400):
        p = sigma * rng.standard_normal((500, 3))
        out.append(f.update(p))
        if prev is not None:
            raw.append((p - prev) / 0.001)
        prev = p
    ratio = np.std(np.array(out[100:])) / np.std(np.array(raw[100:]))
    a = lowpass_alpha(20.0, 0.001)
    assert ratio == pytest.approx(a / math.sqrt(2 - a), rel=0.05)
    mask = np.zeros(500, dtype=bool)
    mask[:10] = True
    f.reset(mask)
    v = f.update(np.ones((500, 3)))
    np.testing.assert_array_equal(v[:10], 0.0)
    assert np.all(np.abs(v[10:]) > 1.0)
    with pytest.raises(ValueError):
        f.update(np.zeros((3,)))


def test_combine_sums_and_flattens():
    viscous = ViscousGuidance(LINE, B=40.0, G_max=5.0)
    spring = SpringGuidance(LINE, stiffness=100.0)
    wall = PlaneWall(point=(0, 0, -0.002), normal=(0, 0, 1))
    total = combine(combine(viscous, spring), wall)
    assert isinstance(total, FixtureSum) and len(total.fixtures) == 3
    assert isinstance(total, Fixture)
    rng = np.random.default_rng(2)
    p = rng.normal(0, 0.005, (10, 3))
    v = rng.normal(0, 0.05, (10, 3))
    expected = viscous.force(p, v) + spring.force(p, v) + wall.force(p, v)
    np.testing.assert_allclose(total.force(p, v), expected)
    with pytest.raises(TypeError):
        combine(viscous, object())


def _state(p_camera, v_camera, T_world_camera=None, psm="PSM1"):
    T = np.eye(4)
    T[:3, 3] = p_camera
    twist = np.concatenate([v_camera, np.zeros(3)])
    return HapticState.from_values(
        T_camera_tip=T, twist_camera_tip=twist, T_world_camera=T_world_camera, psm=psm
    )


def test_fixture_field_is_a_force_field_in_camera_axes():
    """A world-frame fixture seen from a rotated camera: the field returns the world force
    rotated into camera (= HRSV) axes, a valid wrench for the haptic loop."""
    fixture = ViscousGuidance(LINE, B=40.0, G_max=5.0)
    c, s = math.cos(0.5), math.sin(0.5)
    T_wc = np.array([[1, 0, 0, 0.0], [0, c, -s, 0.01], [0, s, c, -0.02], [0, 0, 0, 1.0]])
    p_world, v_world = np.array([0.01, 0.003, 0.001]), np.array([0.0, 0.03, 0.0])
    R = T_wc[:3, :3]
    p_cam = R.T @ (p_world - T_wc[:3, 3])
    field = FixtureField(fixture, frame="world", velocity="measured")
    assert isinstance(field, ForceField)
    f_cam = field(_state(p_cam, R.T @ v_world, T_wc))
    np.testing.assert_allclose(R @ f_cam, fixture.force(p_world, v_world), atol=1e-12)
    assert as_wrench(f_cam).shape == (6,)
    cam_field = FixtureField(fixture, frame="camera", velocity="measured")
    np.testing.assert_allclose(
        cam_field(_state(p_world, v_world)), fixture.force(p_world, v_world), atol=1e-12
    )


def test_fixture_field_filtered_velocity_is_per_psm_and_resettable():
    """With the filtered velocity, a still tool gives no viscous force, a moving one does
    once the filter has seen it move; the filters of two PSMs do not mix."""
    field = FixtureField(ViscousGuidance(LINE, B=40.0, G_max=5.0), frame="camera")
    p = np.array([0.0, 0.004, 0.0])
    np.testing.assert_array_equal(field(_state(p, np.zeros(3))), 0.0)
    forces = []
    for k in range(1, 200):
        forces.append(field(_state(p + [0, 1e-5 * k, 0], np.zeros(3))))  # away at 1 cm/s
    np.testing.assert_allclose(forces[-1], [0, -0.4, 0], rtol=1e-6)
    other = field(_state(p, np.zeros(3), psm="PSM2"))
    np.testing.assert_array_equal(other, 0.0)
    field.reset()
    np.testing.assert_array_equal(field(_state(p, np.zeros(3))), 0.0)
    with pytest.raises(ValueError):
        FixtureField(ViscousGuidance(LINE, B=1.0, G_max=1.0), frame="cart")


def test_fixture_field_state_is_its_filters_memory():
    """Saved mid-motion and restored, the field gives the forces it gave after the save; a
    fresh field (no memory) gives others."""
    field = FixtureField(ViscousGuidance(LINE, B=40.0, G_max=5.0), frame="camera")
    p = np.array([0.0, 0.004, 0.0])
    for k in range(50):
        field(_state(p + [0, 1e-5 * k, 0], np.zeros(3)))
    state = field.get_state()
    after = [field(_state(p + [0, 1e-5 * k, 0], np.zeros(3))) for k in range(50, 60)]
    field.set_state(state)
    again = [field(_state(p + [0, 1e-5 * k, 0], np.zeros(3))) for k in range(50, 60)]
    np.testing.assert_array_equal(after, again)
    fresh = FixtureField(ViscousGuidance(LINE, B=40.0, G_max=5.0), frame="camera")
    assert not np.array_equal(after[0], fresh(_state(p + [0, 5e-4, 0], np.zeros(3))))
