"""The seed's viscous guidance fixture, equations (1)-(7) with G_max as a cap."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics.viscous import (
    ViscousGuidance,
    viscous_guidance,
    viscous_guidance_terms,
)

finite = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
vec = st.tuples(finite, finite, finite).map(np.array)
B_values = st.floats(0.0, 100.0)
G_values = st.floats(0.0, 10.0)
TRANSITION = 0.0005


def reference(v, phi, B, G_max):
    """Equations (1)-(7) transcribed literally, one state, with scipy's rotation."""
    v_hat = v / np.linalg.norm(v)
    phi_hat = phi / np.linalg.norm(phi)
    b = B * math.sqrt((1 - v_hat @ phi_hat) / 2)  # (3)
    G = min(G_max, np.linalg.norm(b * v))  # (1)-(2), cap
    if v_hat @ phi_hat < 0:  # (4)
        d = phi_hat
    else:
        theta = (1 + v_hat @ phi_hat) * math.pi / 2  # (5)
        n = np.cross(v_hat, phi_hat)  # (6)
        d = Rotation.from_rotvec(theta * n / np.linalg.norm(n)).apply(v_hat)
    return G * d  # (7)


@settings(max_examples=300, deadline=None)
@given(vec, vec, B_values, G_values)
def test_matches_literal_transcription(v, phi, B, G_max):
    """Away from the degenerate cases, the vectorised law equals (1)-(7) computed with a
    rotation matrix about n, and the on-path ramp is inactive beyond ``transition``."""
    assume(np.linalg.norm(v) > 1e-3 and np.linalg.norm(phi) > TRANSITION)
    assume(np.linalg.norm(np.cross(v, phi)) > 1e-3 * np.linalg.norm(v) * np.linalg.norm(phi))
    f = viscous_guidance(v, phi, B=B, G_max=G_max, transition=TRANSITION)
    np.testing.assert_allclose(f, reference(v, phi, B, G_max), atol=1e-9)


@settings(max_examples=300, deadline=None)
@given(vec, vec, B_values, G_values)
def test_magnitude_capped_and_b_in_range(v, phi, B, G_max):
    """‖G‖ ≤ G_max (the erratum: a cap, not a floor), b ∈ [0, B], ‖G‖ ≤ b‖v‖."""
    t = viscous_guidance_terms(v, phi, B=B, G_max=G_max)
    assert np.linalg.norm(t.force) <= G_max + 1e-12
    assert -1e-12 <= t.b <= B + 1e-12
    assert np.linalg.norm(t.force) <= t.b * np.linalg.norm(v) + 1e-12
    assert np.all(np.isfinite(t.force))


@settings(max_examples=200, deadline=None)
@given(vec, vec, B_values, G_values)
def test_direction_is_phi_when_moving_away(v, phi, B, G_max):
    """Moving away from the path (v·φ < 0): the force is along φ̂, of magnitude
    min(G_max, b‖v‖) with b ≥ B/√2."""
    assume(np.linalg.norm(phi) > TRANSITION and np.linalg.norm(v) > 1e-6)
    assume(v @ phi < -1e-6 * np.linalg.norm(v) * np.linalg.norm(phi))
    t = viscous_guidance_terms(v, phi, B=B, G_max=G_max)
    phi_hat = phi / np.linalg.norm(phi)
    np.testing.assert_allclose(t.direction, phi_hat, atol=1e-12)
    assert t.b >= B / math.sqrt(2) - 1e-9
    assert t.magnitude == pytest.approx(min(G_max, t.b * np.linalg.norm(v)), abs=1e-12)


@settings(max_examples=100, deadline=None)
@given(vec, B_values, G_values)
def test_zero_when_static(phi, B, G_max):
    """No velocity, no force, wherever the tool is (the seed relies on it)."""
    np.testing.assert_array_equal(viscous_guidance(np.zeros(3), phi, B=B, G_max=G_max), 0.0)


@settings(max_examples=100, deadline=None)
@given(vec, B_values, G_values)
def test_zero_on_the_path(v, B, G_max):
    """No deviation, no force (the ramp), for any velocity."""
    np.testing.assert_array_equal(viscous_guidance(v, np.zeros(3), B=B, G_max=G_max), 0.0)


@settings(max_examples=400, deadline=None)
@given(vec, vec, vec, vec, B_values, G_values, st.floats(1e-9, 1e-6))
@example(  # (moving straight at the path, φ turned by 0.04°: b grows from 0 as sin(δ/2))
    v=np.array([0.0, 0.0, 1.0]), phi=np.array([0.0, 0.0, 0.0015]), dv=np.zeros(3),
    dphi=np.array([0.0, 1.0, 0.0]), B=16.0, G_max=0.25, eps=9.928388996431655e-07,
)  # fmt: skip
def test_continuous_in_velocity_and_deviation(v, phi, dv, dphi, B, G_max, eps):
    """A small change of v or φ changes the force a little, everywhere including v = 0,
    φ = 0 and v̂ = ±φ̂ (a jump would break the bound by orders of magnitude). The law's
    slopes: B in v; G_max/transition from the ramp and from φ̂ turning; and from b = B·sin(δ/2)
    (δ the angle between v̂ and φ̂, which a change of φ turns by up to ‖dφ‖/‖φ‖), a magnitude
    slope of up to B‖v‖/(2·max(‖φ‖, transition)) where the cap does not hold G at G_max."""
    f0 = viscous_guidance(v, phi, B=B, G_max=G_max, transition=TRANSITION)
    dv = eps * dv / max(np.linalg.norm(dv), 1e-12)
    dphi = eps * dphi / max(np.linalg.norm(dphi), 1e-12)
    f1 = viscous_guidance(v + dv, phi + dphi, B=B, G_max=G_max, transition=TRANSITION)
    turning = B * np.linalg.norm(v) / (2.0 * max(np.linalg.norm(phi), TRANSITION))
    bound = 10.0 * (B + G_max / TRANSITION + turning) * eps + 1e-12
    assert np.linalg.norm(f1 - f0) <= bound


@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("speed", [1e-3, 0.05])
def test_velocity_parallel_to_deviation(sign, speed):
    """v̂ = ±φ̂ (n = 0): moving straight away gives min(G_max, B‖v‖) along φ̂; moving straight
    at the path gives zero (b = 0); nearby directions give nearby forces, no NaN."""
    phi = np.array([0.0, 0.0, -0.003])
    v = -sign * speed * phi / np.linalg.norm(phi)
    f = viscous_guidance(v, phi, B=40.0, G_max=5.0)
    if sign > 0:  # away
        np.testing.assert_allclose(f, [0, 0, -min(5.0, 40.0 * speed)], atol=1e-12)
    else:
        np.testing.assert_allclose(f, 0.0, atol=1e-12)
    for tilt in (1e-4, 1e-7, 1e-10):
        v2 = v + tilt * speed * np.array([1.0, 0.0, 0.0])
        f2 = viscous_guidance(v2, phi, B=40.0, G_max=5.0)
        assert np.all(np.isfinite(f2))
        assert np.linalg.norm(f2 - f) < 100 * tilt * 40.0 * speed + 1e-12


def test_sideways_motion_gives_phi_on_both_branches():
    """v ⊥ φ: θ = π/2 rotates v̂ onto φ̂, the same as the 'moving away' branch (the two cases
    of (4) meet continuously), with b = B/√2."""
    phi = np.array([0.0, 0.002, 0.0])
    v = np.array([0.02, 0.0, 0.0])
    t = viscous_guidance_terms(v, phi, B=20.0, G_max=8.0)
    np.testing.assert_allclose(t.direction, [0, 1, 0], atol=1e-12)
    assert t.b == pytest.approx(20 / math.sqrt(2))
    np.testing.assert_allclose(t.force, [0, 0.02 * 20 / math.sqrt(2), 0], atol=1e-12)


def test_approaching_head_on_brakes():
    """Approaching at a small angle: the force turns towards −v̂ (a brake), θ → π."""
    phi = np.array([0.0, 0.0, 0.003])
    v = 0.05 * np.array([np.sin(0.2), 0.0, np.cos(0.2)])
    t = viscous_guidance_terms(v, phi, B=60.0, G_max=8.0)
    assert t.direction @ (v / np.linalg.norm(v)) < -0.95
    assert t.b == pytest.approx(60.0 * np.sin(0.1))


def test_as_printed_the_law_is_discontinuous_on_the_path():
    """With transition = 0 (the law as printed, the default) the force flips as the tool
    crosses the path sideways: the discontinuity an on-path ramp (an option) removes."""
    v = np.array([0.02, 0.0, 0.0])
    above = viscous_guidance(v, [0, -1e-9, 0], B=40.0, G_max=5.0)
    below = viscous_guidance(v, [0, 1e-9, 0], B=40.0, G_max=5.0, transition=0.0)
    assert np.linalg.norm(above - below) == pytest.approx(2 * 0.02 * 40 / math.sqrt(2))
    ramped = viscous_guidance(v, [0, 1e-9, 0], B=40.0, G_max=5.0, transition=0.0005)
    assert np.linalg.norm(ramped) < 1e-5


def test_erratum_cap_not_floor():
    """A slow tool gets b‖v‖, not G_max (as (1)-(2) are printed, it would get G_max)."""
    f = viscous_guidance([0.0, -0.001, 0.0], [0.0, 0.005, 0.0], B=60.0, G_max=8.0)
    np.testing.assert_allclose(f, [0, 0.06, 0], atol=1e-12)


def test_batched_conditions_broadcast():
    """A batch of trials with one (B, G_max) each equals the trials computed one by one."""
    rng = np.random.default_rng(1)
    v = rng.normal(0, 0.05, (4, 3))
    phi = rng.normal(0, 0.004, (4, 3))
    B = np.array([0.0, 20.0, 40.0, 60.0])
    G = np.array([0.0, 2.0, 5.0, 8.0])
    batch = viscous_guidance(v, phi, B=B, G_max=G)
    for i in range(4):
        np.testing.assert_allclose(batch[i], viscous_guidance(v[i], phi[i], B=B[i], G_max=G[i]))
    assert viscous_guidance(v[None, None], phi[None, None], B=20.0, G_max=2.0).shape == (1, 1, 4, 3)
    path = Polyline([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    p = rng.normal(0, 0.004, (4, 3))
    fixture = ViscousGuidance(path, B=B, G_max=G)
    for i in range(4):
        one = ViscousGuidance(path, B=B[i], G_max=G[i])
        np.testing.assert_allclose(fixture.force(p, v)[i], one.force(p[i], v[i]))


def test_rejects_negative_parameters():
    with pytest.raises(ValueError):
        viscous_guidance([0, 0, 1], [0, 1, 0], B=-1.0, G_max=1.0)
    with pytest.raises(ValueError):
        ViscousGuidance(Polyline([[0, 0, 0], [1, 0, 0]]), B=20.0, G_max=-2.0)


def test_fig4_qualitative_shape():
    """The situation of the seed's Fig. 4: a curved reference path, an unguided operation
    path oscillating around it; where the tool drifts away (above the path, moving up and
    back), G points from the tip to the foot of the perpendicular on the path (along φ,
    normal to the path's tangent), with magnitude min(G_max, b‖v‖), b ≥ B/√2. Along the
    whole operation path the force is never larger than G_max, vanishes where the tool
    crosses the reference, and pulls towards the path whenever the tool moves away."""
    x = np.linspace(-0.05, 0.05, 2001)
    reference_path = np.stack([x, 0.01 * np.tanh(-x / 0.01), np.zeros_like(x)], axis=1)
    path = Polyline(reference_path)
    fixture = ViscousGuidance(path, B=40.0, G_max=5.0)
    # Unguided operation path: the reference plus a sinusoidal error, traversed at 2 cm/s.
    t = np.linspace(0.0, 5.0, 5001)
    xs = -0.05 + 0.02 * t
    tip = np.stack(
        [xs, 0.01 * np.tanh(-xs / 0.01) + 0.004 * np.sin(2 * np.pi * xs / 0.03), 0 * xs], 1
    )
    vel = np.gradient(tip, t, axis=0)
    terms = fixture.terms(tip, vel)
    cp = path.closest_point(tip)
    assert np.all(np.linalg.norm(terms.force, axis=1) <= 5.0 + 1e-12)
    away = np.einsum("ij,ij->i", vel, cp.deviation) < -1e-9
    assert away.sum() > 1000
    pulls = np.einsum("ij,ij->i", terms.force[away], cp.deviation[away])
    assert np.all(pulls >= 0)
    # Fig. 4's instant: the tip above the path, moving up and back (blue arrow).
    k = np.argmax(np.where(away & (cp.distance > 0.003), cp.distance, 0))
    f = terms.force[k]
    tangent = path.tangent_at(cp.arc_length[k])
    assert abs(f @ tangent) < 1e-6 * np.linalg.norm(f)  # perpendicular to the path
    np.testing.assert_allclose(f / np.linalg.norm(f), cp.deviation[k] / cp.distance[k], atol=1e-9)
    assert terms.b[k] >= 40.0 / math.sqrt(2)
    assert np.linalg.norm(f) == pytest.approx(min(5.0, terms.b[k] * np.linalg.norm(vel[k])))
    # Crossing the reference: the force vanishes with the deviation.
    crossing = cp.distance < 1e-5
    assert crossing.any()
    assert np.all(np.linalg.norm(terms.force[crossing], axis=1) < 5.0 * 1e-5 / 0.0005 + 1e-9)


@pytest.mark.parametrize("transition", [0.0, 0.002])
def test_one_tip_compiled_row_gives_the_batch_laws_bits(transition):
    """The live haptic tick's one tool tip runs the compiled row (``viscous_force_row``), a
    batch the compiled rows (``viscous_force_rows``); both give exactly the bits of the
    batch law (``viscous_guidance_terms``), degenerate cases included."""
    rng = np.random.default_rng(3)
    path = Polyline(np.cumsum(rng.normal(0, 0.01, (30, 3)), axis=0))
    fixture = ViscousGuidance(path, B=40.0, G_max=5.0, transition=transition)
    tips = path.vertices.mean(axis=0) + rng.normal(0, 0.02, (400, 3))
    velocities = rng.normal(0, 0.05, (400, 3)) * rng.uniform(0, 1, (400, 1)) ** 4
    velocities[:20] = 0.0  # static tool
    tips[20:40] = path.vertices[rng.integers(0, 30, 20)]  # on the path: φ = 0
    phi = path.closest_point(tips[40:60]).deviation
    velocities[40:50] = phi[:10] * 3.0  # straight away from the path
    velocities[50:60] = -phi[10:] * 3.0  # straight at it
    velocities[60:100] *= 100.0  # fast: the force at its cap G_max
    for shape in [(3,), (1, 3)]:
        for p, v in zip(tips, velocities, strict=True):
            fast = fixture.force(p.reshape(shape), v.reshape(shape))
            batch = fixture.terms(p.reshape(shape), v.reshape(shape)).force
            assert fast.shape == batch.shape
            np.testing.assert_array_equal(fast, batch, strict=True)
            assert (np.signbit(fast) == np.signbit(batch)).all()
    # A batch of tips (the study's trials under one condition): the compiled rows, the same
    # bits as the batch law.
    fast = fixture.force(tips, velocities)
    batch = fixture.terms(tips, velocities).force
    np.testing.assert_array_equal(fast, batch, strict=True)
    assert (np.signbit(fast) == np.signbit(batch)).all()
