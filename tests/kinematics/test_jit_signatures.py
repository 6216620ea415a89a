"""A kernel's callers give it one kind of array per argument: numba compiles a kernel again,
for seconds to a minute, for a read-only or strided variant of an argument it was warmed up
with (a clean clone's `make test` compiled eight such variants after the warm-up, one of them
the path's closest point in every loop process, whose pickled paths had come back writable).
"""

from __future__ import annotations

import pickle

import numpy as np

from davinci_sim.geometry.path import Polyline
from davinci_sim.haptics import path_query
from davinci_sim.kinematics import psm_ik
from davinci_sim.kinematics.arms import load_arm
from davinci_sim.kinematics.fk import forward_kinematics
from davinci_sim.kinematics.ik import inverse_kinematics
from davinci_sim.operators.noise import Tremor


def _kinds(args) -> list[tuple]:
    """What numba types each array argument by: dtype, dimensions, C order, writable."""
    return [(a.dtype.str, a.ndim, a.flags.c_contiguous, a.flags.writeable)
            for a in args if isinstance(a, np.ndarray)]  # fmt: skip


def _spy(monkeypatch, module, name: str) -> list:
    seen: list = []
    real = getattr(module, name)

    def spy(*args):
        seen.append(_kinds(args))
        return real(*args)

    monkeypatch.setattr(module, name, spy)
    return seen


def test_a_pickled_path_gives_the_closest_point_kernel_the_arrays_of_the_original(monkeypatch):
    seen = _spy(monkeypatch, path_query, "closest_point_row")
    path = Polyline(np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.01, 0.01, 0.0]]))
    copy = pickle.loads(pickle.dumps(path))  # (what a loop process or a Ray worker holds)
    assert not copy.vertices.flags.writeable
    a = path_query.closest_point(path, [0.006, 0.002, 0.0])
    b = path_query.closest_point(copy, [0.006, 0.002, 0.0])
    assert len(seen) == 2 and seen[0] == seen[1], seen
    np.testing.assert_array_equal(a.point, b.point)
    assert a.arc_length == b.arc_length == 0.006  # (on the first segment, 2 mm off it)


def test_the_psm_ik_gives_its_kernel_writable_arrays_whatever_it_is_given(monkeypatch):
    seen = _spy(monkeypatch, psm_ik, "closed_form_rows")
    kin = load_arm("PSM1")
    T = forward_kinematics(kin.chain, kin.home + 0.1)
    frozen_T, frozen_seed = T.copy(), kin.home.copy()
    frozen_T.setflags(write=False)
    frozen_seed.setflags(write=False)  # (an arm's home, a frozen value's array, is read-only)
    free = inverse_kinematics(kin, T, kin.home.copy(), method="closed_form")
    frozen = inverse_kinematics(kin, frozen_T, frozen_seed, method="closed_form")
    assert len(seen) == 2 and seen[0] == seen[1], seen
    assert all(writable for *_, writable in seen[0])
    np.testing.assert_array_equal(free.q, frozen.q)


def test_the_trainees_taken_rows_keep_their_tremor_state_c_ordered():
    tremor = Tremor(np.linspace(8.0, 10.0, 5), bandwidth_hz=2.0, dt=0.001)
    part = tremor.take([0, 2, 4])
    for whole, taken in zip((tremor._x, tremor._y1, tremor._y2), (part._x, part._y1, part._y2),
                            strict=True):  # fmt: skip
        assert taken.flags.c_contiguous and taken.flags.writeable
        np.testing.assert_array_equal(taken, whole[:, [0, 2, 4]])
