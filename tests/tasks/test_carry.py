"""The carried object of a path task (:mod:`davinci_sim.tasks.carry`): the wrist's turn
along the path, its checks, and the ``carry`` section of a task file."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from davinci_sim.geometry.so3 import is_rotation, rotation_vector
from davinci_sim.tasks import load_task
from davinci_sim.tasks.base import TaskError
from davinci_sim.tasks.carry import CarrySpec
from davinci_sim.tasks.task import PathTask

TURN = [[0.0, 0.0, 0.0], [0.0, 0.4, 0.0], [0.2, 0.0, 0.6]]


def _carry(**kw) -> CarrySpec:
    return CarrySpec(**{"torus_radius": 0.0064, "tube_radius": 0.0007,
                        "progress": (0.0, 0.5, 1.0), "turn": TURN, **kw})  # fmt: skip


def test_the_turn_is_linear_between_knots_and_held_beyond_the_ends():
    carry = _carry()
    np.testing.assert_allclose(carry.turn_at(0.25), [0.0, 0.2, 0.0])
    np.testing.assert_allclose(carry.turn_at(0.75), [0.1, 0.2, 0.3])
    np.testing.assert_allclose(carry.turn_at(1.7), TURN[2])
    np.testing.assert_allclose(carry.turn_at(-1.0), TURN[0])
    R = carry.R_turn(0.75)
    assert is_rotation(R)
    np.testing.assert_allclose(rotation_vector(R), [0.1, 0.2, 0.3], atol=1e-12)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"progress": (0.0, 0.6, 0.5)}, "progress"),
        ({"progress": (0.1, 0.5, 1.0)}, "progress"),
        ({"turn": TURN[:2]}, "turn"),
        ({"turn": [[0.0, np.nan, 0.0], *TURN[1:]]}, "turn"),
        ({"tube_radius": 0.007}, "tube_radius"),
    ],
)
def test_a_bad_carry_is_refused(change, match):
    with pytest.raises(TaskError, match=match):
        _carry(**change)


def test_a_task_file_round_trips_its_carry_and_the_schema_names_a_bad_field(tmp_path):
    data = load_task("seed_path").to_dict()
    data["carry"] = _carry().to_dict()
    task = PathTask.from_dict(data)
    again = PathTask.from_dict(task.to_dict())
    np.testing.assert_array_equal(again.carry.turn, TURN)
    assert again.carry.progress == (0.0, 0.5, 1.0) and again.carry.grasp_depth == 0.006
    # the knots are checked besides the view points, turned
    assert len(task.check_points) == len(task.view_points) + 3
    assert np.isnan(task.view_turns[: len(task.view_points)]).all()
    np.testing.assert_array_equal(task.view_turns[len(task.view_points) :], TURN)
    # without carry: the kind's defaults
    assert load_task("seed_path").view_turns is None
    data["carry"]["turn"] = [[0.0, 0.0], *TURN[1:]]
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    with pytest.raises(TaskError, match=r"line \d+: carry\.turn\[0\]: must be 3 numbers"):
        load_task(path)
