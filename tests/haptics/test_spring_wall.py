"""Spring guidance and forbidden-region walls: laws, continuity, unilateral contact."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics.spring import SpringGuidance, spring_guidance
from davinci_sim.haptics.wall import PlaneWall, SphereWall, wall_force

vec = st.tuples(*[st.floats(-0.05, 0.05)] * 3).map(np.array)
LINE = Polyline([[-0.1, 0.0, 0.0], [0.1, 0.0, 0.0]])


def test_spring_pulls_towards_the_path_and_leaves_tangential_motion_free():
    s = SpringGuidance(LINE, stiffness=200.0, damping=10.0, max_force=5.0)
    p = np.array([0.0, 0.004, 0.0])
    np.testing.assert_allclose(s.force(p, np.zeros(3)), [0, -0.8, 0])
    # Moving along the path: no damping; moving away: damped (adds to the spring).
    np.testing.assert_allclose(s.force(p, [0.05, 0, 0]), [0, -0.8, 0])
    np.testing.assert_allclose(s.force(p, [0, 0.01, 0]), [0, -0.9, 0])
    # Saturation keeps the direction.
    np.testing.assert_allclose(s.force([0.0, 0.05, 0.0], np.zeros(3)), [0, -5.0, 0])


@settings(max_examples=200, deadline=None)
@given(vec, vec, vec, vec, st.floats(1e-9, 1e-6))
def test_spring_bounded_and_continuous(v, phi, dv, dphi, eps):
    kw = dict(stiffness=300.0, damping=20.0, max_force=4.0, transition=0.0005)
    f0 = spring_guidance(v, phi, **kw)
    assert np.linalg.norm(f0) <= 4.0 + 1e-12
    dv = eps * dv / max(np.linalg.norm(dv), 1e-12)
    dphi = eps * dphi / max(np.linalg.norm(dphi), 1e-12)
    f1 = spring_guidance(v + dv, phi + dphi, **kw)
    # Lipschitz: k + c·‖v‖/transition in φ (the damping ramp and direction), c in v.
    L = 300.0 + 20.0 * (np.linalg.norm(v) + eps) / 0.0005 * 3 + 20.0
    assert np.linalg.norm(f1 - f0) <= 3 * L * eps + 1e-12


def test_plane_wall_pushes_out_and_never_pulls():
    wall = PlaneWall(point=(0, 0, 0.8), normal=(0, 0, 2.0), stiffness=500.0, damping=5.0)
    assert wall.normal == (0.0, 0.0, 1.0)
    # Outside: nothing, whatever the velocity.
    np.testing.assert_array_equal(wall.force([0, 0, 0.801], [0, 0, -1.0]), 0.0)
    # 2 mm deep, still: k·g.
    np.testing.assert_allclose(wall.force([0, 0, 0.798], np.zeros(3)), [0, 0, 1.0])
    # Going deeper adds damping; leaving fast never pulls inwards.
    np.testing.assert_allclose(wall.force([0, 0, 0.798], [0, 0, -0.1]), [0, 0, 1.5])
    np.testing.assert_array_equal(wall.force([0, 0, 0.798], [0, 0, 1.0]), 0.0)
    # Capped.
    np.testing.assert_allclose(wall.force([0, 0, 0.7], np.zeros(3)), [0, 0, 5.0])


@settings(max_examples=200, deadline=None)
@given(st.floats(-0.005, 0.005), st.floats(-0.5, 0.5), st.floats(1e-9, 1e-6))
def test_wall_continuous_across_the_surface(g, vn, eps):
    """Entering the wall fast gives no jump (damping ramps in with depth)."""
    n = np.array([0.0, 0.0, 1.0])
    kw = dict(stiffness=500.0, damping=5.0, damping_depth=0.001)
    f0 = wall_force(g, n, vn * n, **kw)
    f1 = wall_force(g + eps, n, vn * n, **kw)
    assert np.linalg.norm(f1 - f0) <= (500.0 + 5.0 * 0.5 / 0.001) * eps * 1.01 + 1e-12


def test_sphere_walls_keep_out_and_keep_in():
    organ = SphereWall(center=(0, 0, 0), radius=0.01, stiffness=1000.0, damping=0.0)
    np.testing.assert_allclose(organ.force([0.008, 0, 0], np.zeros(3)), [2.0, 0, 0])
    np.testing.assert_array_equal(organ.force([0.012, 0, 0], np.zeros(3)), 0.0)
    np.testing.assert_allclose(organ.force([0, 0, 0], np.zeros(3)), [0, 0, 5.0])  # fallback
    box = SphereWall(center=(0, 0, 0), radius=0.01, keep_out=False, stiffness=1000.0, damping=0)
    np.testing.assert_allclose(box.force([0, 0.012, 0], np.zeros(3)), [0, -2.0, 0])
    np.testing.assert_array_equal(box.force([0, 0.008, 0], np.zeros(3)), 0.0)
    batch = organ.force(np.zeros((4, 2, 3)) + [0.009, 0, 0], np.zeros((4, 2, 3)))
    assert batch.shape == (4, 2, 3)


def test_invalid_parameters_are_refused():
    with pytest.raises(ValueError):
        PlaneWall(point=(0, 0, 0), normal=(0, 0, 0))
    with pytest.raises(ValueError):
        SphereWall(center=(0, 0, 0), radius=-1.0)
    with pytest.raises(ValueError):
        SpringGuidance(LINE, stiffness=-1.0)
