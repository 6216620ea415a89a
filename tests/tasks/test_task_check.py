"""A task's points checked before any work: reachable by its PSM, in the endoscope's view
(issue 11, 1), from the API and the command line; study refuses such a task at once."""

from pathlib import Path

import pytest
import yaml

from davinci_sim.cli import main
from davinci_sim.tasks import load_task
from davinci_sim.tasks.check import check_task, task_problem

SEED = Path(__file__).resolve().parents[2] / "src" / "davinci_sim" / "tasks" / "data"


def test_the_seed_path_is_reachable_and_in_view():
    checks = check_task(load_task("seed_path"))
    assert len(checks) == 5 and all(c.ok for c in checks)
    assert task_problem(load_task("seed_path")) is None


@pytest.fixture
def bad_task(tmp_path) -> Path:
    """The seed's path 40 cm higher: out of the PSM's reach."""
    data = yaml.safe_load((SEED / "seed_path.yaml").read_text())
    data["name"] = "bad_path"
    data["waypoints"] = [[x, y, z + 0.4] for x, y, z in data["waypoints"]]
    path = tmp_path / "bad_path.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_an_unreachable_point_is_named(bad_task):
    checks = check_task(load_task(bad_task))
    assert [c.index for c in checks if not c.reachable] == [1, 2, 3, 4, 5]
    assert "point 3 unreachable" in task_problem(load_task(bad_task))


def test_task_check_prints_each_point_and_fails_for_a_bad_task(bad_task, capsys):
    assert main(["task", "check", "seed_path"]) == 0
    assert capsys.readouterr().out.rstrip().endswith("ok")
    assert main(["task", "check", str(bad_task)]) == 1
    out = capsys.readouterr().out
    assert "point 3:" in out and "UNREACHABLE" in out and "point(s) fail" in out
    assert main(["task", "check", "no_such_task"]) == 2


def test_study_refuses_a_bad_task_before_any_trial(bad_task, tmp_path, capsys):
    assert main(["study", "--task", str(bad_task), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "point 3 unreachable" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()
    assert main(["study", "--task", "nope.yaml", "-o", str(tmp_path / "out")]) == 2
    assert "nope.yaml" in capsys.readouterr().err
