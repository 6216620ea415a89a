"""Polylines, rounded corners and closest-point queries against plain references."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from davinci_sim.geometry.path import Polyline, closest_point_brute, rounded_polyline

STAPLE = np.array(
    [
        [0.0, 0.0, 0.0],
        [0.03, 0.0, 0.0],
        [0.03, -0.03, 0.0],
        [0.03, -0.03, 0.025],
        [0.06, -0.03, 0.025],
    ]
)


def naive_closest(vertices: np.ndarray, q: np.ndarray) -> tuple[float, np.ndarray]:
    """Distance and point, by a loop over segments with a scalar projection."""
    best, point = math.inf, None
    for a, b in zip(vertices[:-1], vertices[1:], strict=True):
        e = b - a
        u = min(1.0, max(0.0, float((q - a) @ e) / float(e @ e)))
        c = a + u * e
        d = float(np.linalg.norm(q - c))
        if d < best:
            best, point = d, c
    return best, point


polylines = st.integers(2, 12).flatmap(
    lambda n: st.lists(st.tuples(*[st.floats(-0.05, 0.05)] * 3), min_size=n, max_size=n).map(
        np.array
    )
)


@settings(max_examples=80, deadline=None)
@given(polylines, st.integers(0, 2**31 - 1))
def test_brute_and_tree_match_a_plain_loop(vertices, seed):
    """Both query methods give the distance and point of the naive per-segment loop."""
    if np.any(np.linalg.norm(np.diff(vertices, axis=0), axis=1) < 1e-6):
        return
    path = Polyline(vertices)
    q = np.random.default_rng(seed).normal(0, 0.05, (50, 3))
    ref = [naive_closest(vertices, x) for x in q]
    for method in ("brute", "tree"):
        cp = path.closest_point(q, method=method)
        np.testing.assert_allclose(cp.distance, [d for d, _ in ref], atol=1e-12)
        # The point may differ only where two segments are equally close.
        np.testing.assert_allclose(np.linalg.norm(cp.point - q, axis=1), cp.distance, atol=1e-12)
        np.testing.assert_allclose(cp.deviation, cp.point - q, atol=1e-15)
        np.testing.assert_allclose(path.point_at(cp.arc_length), cp.point, atol=1e-12)


def test_tree_on_a_long_dense_curve():
    """A 3000-segment helix: the tree agrees with the brute force (and is what auto uses)."""
    t = np.linspace(0, 6 * np.pi, 3001)
    path = Polyline(np.stack([0.02 * np.cos(t), 0.02 * np.sin(t), 0.002 * t], axis=1))
    q = np.random.default_rng(3).normal(0, 0.03, (2000, 3))
    a = path.closest_point(q, method="tree")
    b = closest_point_brute(path, q)
    np.testing.assert_allclose(a.distance, b.distance, atol=1e-13)
    auto = path.closest_point(q)
    np.testing.assert_allclose(auto.distance, b.distance, atol=1e-13)


def test_batch_shapes_and_arc_length():
    path = Polyline(STAPLE)
    assert path.length == pytest.approx(0.115)
    np.testing.assert_allclose(path.cumulative_length, [0, 0.03, 0.06, 0.085, 0.115])
    q = np.zeros((2, 3, 3))
    cp = path.closest_point(q)
    assert cp.point.shape == (2, 3, 3) and cp.distance.shape == (2, 3)
    cp = path.closest_point([0.01, 0.002, 0.0])
    assert cp.distance == pytest.approx(0.002)
    assert cp.arc_length == pytest.approx(0.01)
    np.testing.assert_allclose(cp.deviation, [0, -0.002, 0], atol=1e-15)
    np.testing.assert_allclose(path.tangent_at(0.07), [0, 0, 1])
    np.testing.assert_allclose(path.point_at([-1.0, 10.0]), STAPLE[[0, -1]])


def test_rigid_transform_and_resampling_keep_the_geometry():
    path = Polyline(STAPLE)
    c, s = math.cos(0.7), math.sin(0.7)
    T = np.array([[c, -s, 0, 0.1], [s, c, 0, -0.2], [0, 0, 1, 0.3], [0, 0, 0, 1.0]])
    moved = path.transformed(T)
    q = np.random.default_rng(5).normal(0, 0.03, (100, 3))
    d0 = path.closest_point(q).distance
    d1 = moved.closest_point(q @ T[:3, :3].T + T[:3, 3]).distance
    np.testing.assert_allclose(d0, d1, atol=1e-12)
    fine = path.resampled(0.001)
    assert fine.length == pytest.approx(path.length)
    assert len(fine.vertices) >= 116
    assert np.max(path.closest_point(fine.vertices).distance) < 1e-12
    np.testing.assert_allclose(fine.closest_point(q).distance, d0, atol=1e-12)


@pytest.mark.parametrize("radius", [0.0, 0.003, 0.006])
def test_rounded_polyline_fillets(radius):
    """Fillets of radius r: ends kept, the path tangent-continuous (turns of at most the arc
    step per vertex), a 90° corner cut by r(√2 − 1), each corner's two tangent runs of r
    replaced by the arc's chords."""
    path, s = rounded_polyline(STAPLE, radius, arc_step_deg=5.0)
    np.testing.assert_allclose(path.vertices[[0, -1]], STAPLE[[0, -1]])
    assert s[0] == 0 and s[-1] == pytest.approx(path.length)
    assert np.all(np.diff(s) > 0)
    chords = 18 * 2 * radius * math.sin(math.radians(2.5))  # the arc, sampled every 5°
    assert path.length == pytest.approx(0.115 - 3 * (2 * radius - chords), abs=1e-12)
    marks = path.point_at(s)
    cut = np.linalg.norm(marks[1:4] - STAPLE[1:4], axis=1)
    np.testing.assert_allclose(cut, radius * (math.sqrt(2) - 1), atol=1e-5)
    t = path.edges / path.segment_lengths[:, None]
    turn = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", t[:-1], t[1:]), -1, 1)))
    assert turn.max() <= (5.0 if radius > 0 else 90.0) + 1e-6


def test_rounded_polyline_rejects_bad_input():
    with pytest.raises(ValueError, match="too large"):
        rounded_polyline(STAPLE, 0.02)
    with pytest.raises(ValueError, match="reverses"):
        rounded_polyline([[0, 0, 0], [1, 0, 0], [0, 0, 0]], 0.1)
    with pytest.raises(ValueError):
        Polyline([[0, 0, 0], [0, 0, 0]])
    with pytest.raises(ValueError):
        Polyline(np.zeros((1, 3)))
    with pytest.raises(ValueError, match="method"):
        Polyline(STAPLE).closest_point([0, 0, 0], method="octree")


@settings(max_examples=200, deadline=None)
@given(st.floats(0.0, 1.0), st.tuples(*[st.floats(-1, 1)] * 3), st.tuples(*[st.floats(-1, 1)] * 3))
def test_deviation_continuous_inside_the_tube(u, offset, step):
    """Within the fillet radius of a rounded path the closest point is unique, so φ moves
    by at most the query's move (the projection on a convex-enough curve is 1-Lipschitz in
    the reach)."""
    path, _ = rounded_polyline(STAPLE, 0.006, arc_step_deg=2.0)
    base = path.point_at(u * path.length)
    off = np.array(offset)
    q = base + 0.004 * off / max(1.0, np.linalg.norm(off))
    d = 1e-6 * np.array(step)
    a = path.closest_point(q)
    b = path.closest_point(q + d)
    # Chord polygon of the arcs: slightly more than 1-Lipschitz near the arc vertices, and
    # on the inner side of a vertex the closest point may move to the next chord, a jump
    # of at most the distance (≤ 4 mm) times the chord's turn (2°): 0.14 mm.
    jump = 0.004 * math.radians(2.0)
    assert np.linalg.norm(b.deviation - a.deviation) <= 3.0 * np.linalg.norm(d) + jump
