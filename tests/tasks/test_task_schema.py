"""Task files are checked against the declared schema: one line naming the field and the
line of the file, before any task is built (no numpy traceback)."""

from __future__ import annotations

import json

import pytest

from davinci_sim.cli import main
from davinci_sim.tasks import PathTask, load_task, task_to_dict
from davinci_sim.tasks.base import _data_dir
from davinci_sim.tasks.schema import SchemaError, format_path, line_map, task_schema

SEED = (_data_dir() / "seed_path.yaml").read_text()


def _line(text: str, starts: str) -> int:
    """1-based line of the first line of ``text`` that starts with ``starts``."""
    return next(i for i, x in enumerate(text.splitlines(), 1) if x.startswith(starts))


def _edit(old: str, new: str) -> str:
    assert old in SEED
    return SEED.replace(old, new, 1)


RAGGED = _edit("  - [0.080, 1.170, 0.795]\n", "  - [0.080, 1.170]\n")
MISSING = "\n".join(
    line for line in SEED.splitlines() if not line.startswith(("waypoints:", "  - ["))
)
UNKNOWN = _edit("corner_radius: 0.006", "corner_radius: 0.006\ncolour: red")
WRONG_TYPE = _edit("  scale: 0.6 ", "  scale: fast")
BAD_CONDITION = _edit('{name: "B=60", type: viscous', '{name: "B=60", type: magnetic')
ENGINEERING = _edit("tube_radius: 0.003 ", "tube_radius: 3e-3 ")


@pytest.mark.parametrize(
    "text, field, line, words",
    [
        (RAGGED, "waypoints[2]", _line(RAGGED, "  - [0.080, 1.170]"), "must be 3 numbers"),
        (MISSING, "waypoints", _line(MISSING, "name:"), "required, but missing"),
        (UNKNOWN, "colour", _line(UNKNOWN, "colour:"), "unknown field"),
        (WRONG_TYPE, "teleop.scale", _line(WRONG_TYPE, "  scale:"), "must be a number"),
        (BAD_CONDITION, "conditions[3].type", _line(BAD_CONDITION, '  - {name: "B=60"'),
         "unknown fixture type 'magnetic'"),
        (ENGINEERING, "tube_radius", _line(ENGINEERING, "tube_radius:"), "decimal point"),
    ],
)  # fmt: skip
def test_a_bad_task_file_is_one_line_with_field_and_line(tmp_path, capsys, text, field, line,
                                                          words):  # fmt: skip
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    assert main(["task", "check", str(path)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert f"bad.yaml, line {line}: {field}: " in err and words in err, err


def test_study_serve_and_snapshot_refuse_the_ragged_task_in_one_line(tmp_path, capsys):
    path = tmp_path / "ragged.yaml"
    path.write_text(RAGGED)
    where = f"ragged.yaml, line {_line(RAGGED, '  - [0.080, 1.170]')}: waypoints[2]"
    for argv in (
        ["study", "--task", str(path), "--subjects", "1", "--repetitions", "1",
         "-o", str(tmp_path / "out")],
        ["serve", "--task", str(path), "--duration", "0"],
        ["snapshot", "--task", str(path), "-o", str(tmp_path / "snap")],
    ):  # fmt: skip
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert where in err and len(err.strip().splitlines()) == 1, (argv, err)
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_every_shipped_task_and_its_round_trip_fit_the_schema(tmp_path):
    for name in ("seed_path",):
        task = load_task(name)
        data = task_to_dict(task)
        task_schema(PathTask).check(data, ())
        path = tmp_path / f"{name}.json"  # JSON files are checked too (lines from the composer)
        path.write_text(json.dumps(data, indent=2))
        assert load_task(path).name == task.name


def test_a_json_task_file_gets_its_line_too(tmp_path):
    data = task_to_dict(load_task("seed_path"))
    data["waypoints"][1] = [0.08, "1.2", 0.795]
    text = json.dumps(data, indent=2)
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(ValueError) as e:
        load_task(path)
    line = next(i for i, x in enumerate(text.splitlines(), 1) if '"1.2"' in x)
    assert f"bad.json, line {line}: waypoints[1][1]: must be a number" in str(e.value)


def test_line_map_and_paths():
    lines = line_map("a: 1\nb:\n  - [1, 2]\n  - {c: 3}\n")
    assert lines[("a",)] == 1 and lines[("b", 0)] == 3 and lines[("b", 1, "c")] == 4
    assert format_path(("conditions", 1, "B")) == "conditions[1].B"
    assert line_map("a: [") == {}
    err = SchemaError(("walls", 0, "radius"), "must be a number", 7, "x.yaml")
    assert str(err) == "x.yaml, line 7: walls[0].radius: must be a number"


def test_a_new_fixture_parameter_is_checked_from_the_kind_s_declaration():
    """The fixture part of the schema comes from the kind's FIXTURE_TYPES (and
    FIXTURE_PARAMETERS for a parameter that is not a number)."""
    from davinci_sim.tasks.schema import Flag

    class Custom(PathTask):
        FIXTURE_TYPES = {**PathTask.FIXTURE_TYPES, "magnet": {"strength", "on"}}
        FIXTURE_PARAMETERS = {"on": Flag()}

    data = task_to_dict(load_task("seed_path"))
    schema = task_schema(Custom)
    schema.check({**data, "fixture": {"type": "magnet", "strength": 2.0, "on": True}}, ())
    with pytest.raises(SchemaError, match=r"fixture.on: must be true or false"):
        schema.check({**data, "fixture": {"type": "magnet", "on": 1}}, ())
    with pytest.raises(SchemaError, match=r"fixture.type: unknown fixture type 'magnet'"):
        task_schema(PathTask).check({**data, "fixture": {"type": "magnet"}}, ())


def test_a_mapping_without_a_file_names_the_task_and_a_bad_kind_is_one_error():
    from davinci_sim.tasks import TaskError, task_from_dict

    with pytest.raises(TaskError, match=r"^task 'x': waypoints\[1\]: must be 3 numbers"):
        task_from_dict({"name": "x", "waypoints": [[0, 0, 0], [1, 1]]})
    with pytest.raises(TaskError, match="unknown kind"):
        task_from_dict({"kind": ["path"], "name": "x"})
