"""The compiled one-tip closest point (haptics/path_query) gives the bits of the path's own
brute-force query, which the study's batches use: live and batched rows stay identical."""

import numpy as np
import pytest

from davinci_sim.geometry.path import Polyline, closest_point_brute
from davinci_sim.haptics.path_query import closest_point, closest_point_row


def _same(a, b) -> None:
    for x, y in zip(a, b, strict=True):
        assert type(x) is type(y)
        assert np.shape(x) == np.shape(y)
        np.testing.assert_array_equal(x, y, strict=True)
        assert (np.signbit(np.asarray(x)) == np.signbit(np.asarray(y))).all()


@pytest.mark.parametrize("shape", [(3,), (1, 3)])
def test_one_tip_equals_the_brute_force_query_bit_for_bit(shape):
    rng = np.random.default_rng(7)
    for _ in range(60):
        n = int(rng.integers(2, 80))
        path = Polyline(np.cumsum(rng.normal(0, 0.01, (n, 3)), axis=0) + rng.normal(0, 0.1, 3))
        tips = path.vertices.mean(axis=0) + rng.normal(0, 0.03, (40, 3))
        tips[:5] = path.vertices[rng.integers(0, n, 5)]  # on vertices: u at 0 or 1 exactly
        for tip in tips:
            _same(
                closest_point(path, tip.reshape(shape)),
                closest_point_brute(path, tip.reshape(shape)),
            )


def test_ties_and_nan_follow_argmin():
    # A square loop: a tip at its centre is equally far from all four sides (ties go to
    # the first segment); a NaN tip gives the first segment as np.argmin does.
    path = Polyline([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 0]])
    for tip in ([0.5, 0.5, 0.0], [np.nan, 0.5, 0.0], [0.0, 0.0, 0.0]):
        _same(closest_point(path, tip), closest_point_brute(path, tip))


def test_python_and_compiled_kernel_agree():
    path = Polyline([[0.0, 0, 0], [0.02, 0.01, 0], [0.03, -0.01, 0.005]])
    from davinci_sim.geometry.path import brute_force_constants

    args = (np.array([0.011, 0.002, -0.001]), path.centre, *brute_force_constants(path),
            path.starts, path.edges, path.cumulative_length, path.segment_lengths)  # fmt: skip
    out, out_py = np.empty(8), np.empty(8)
    assert closest_point_row(*args, out) == closest_point_row.py_func(*args, out_py)
    np.testing.assert_array_equal(out, out_py, strict=True)


def test_a_batch_equals_the_brute_force_query_bit_for_bit():
    # The study's trials: n tips at once through the compiled rows, each row the bits of the
    # path's own batch query (ties, vertices and a NaN tip included).
    rng = np.random.default_rng(11)
    for _ in range(30):
        n = int(rng.integers(2, 60))
        path = Polyline(np.cumsum(rng.normal(0, 0.01, (n, 3)), axis=0))
        tips = path.vertices.mean(axis=0) + rng.normal(0, 0.03, (int(rng.integers(2, 90)), 3))
        tips[0] = path.vertices[int(rng.integers(0, n))]
        tips[1, 0] = np.nan
        _same(closest_point(path, tips), closest_point_brute(path, tips))
    square = Polyline([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 0]])
    tips = np.array([[0.5, 0.5, 0.0], [0.2, 0.3, 0.0], [0.9, 0.8, 0.1]])
    _same(closest_point(square, tips), closest_point_brute(square, tips))


def test_other_shapes_go_to_the_path():
    path = Polyline([[0.0, 0, 0], [1, 0, 0], [1, 1, 0]])
    tips = np.array([[[0.2, 0.3, 0.0], [0.9, 0.8, 0.1]]])
    _same(closest_point(path, tips), closest_point_brute(path, tips))
