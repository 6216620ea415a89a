"""The score rule and pass marks (davinci_sim.tasks.scoring) on constructed inputs, and the
shipped expert reference."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from davinci_sim.tasks import PathTask, TaskError, load_task, save_task
from davinci_sim.tasks.scoring import (
    Reference,
    ReferenceValue,
    ScoreItem,
    Scoring,
    load_reference,
    meets,
    metric_score,
    reference_from_rows,
    task_digest,
)


def test_a_metric_maps_linearly_from_expert_to_failing_threshold():
    assert metric_score(2.0, expert=2.0, fail=10.0) == 100.0
    assert metric_score(10.0, expert=2.0, fail=10.0) == 0.0
    assert metric_score(4.0, expert=2.0, fail=10.0) == pytest.approx(75.0)
    assert metric_score(1.0, expert=2.0, fail=10.0) == 100.0  # better than expert: clipped
    assert metric_score(30.0, expert=2.0, fail=10.0) == 0.0
    # higher is better: 0 % at a low failing value
    assert metric_score(0.03, expert=0.04, fail=0.0, better="higher") == pytest.approx(75.0)
    # expert = fail: all or nothing
    assert metric_score(0, expert=0, fail=0) == 100.0
    assert metric_score(1, expert=0, fail=0) == 0.0
    assert math.isnan(metric_score(math.nan, 0.0, 1.0))
    assert meets(3.0, 3.0) and not meets(3.0001, 3.0)
    assert meets(3.0, 3.0, "higher") and not meets(2.9, 3.0, "higher")


def _scoring(**kw):
    ref = Reference("t", "d", {
        "time": ReferenceValue(10.0, 2.0, 45),
        "errors": ReferenceValue(1.0, 0.5, 45),
        "speed": ReferenceValue(0.03, 0.005, 45),
    })  # fmt: skip
    items = (
        ScoreItem("time", 1.0, fail=60.0),
        ScoreItem("errors", 3.0, fail=5.0),
        ScoreItem("speed", 1.0, fail=0.0, better="higher"),
    )
    return Scoring(items, reference=ref, **kw)


def test_expert_values_score_100_and_failing_values_0():
    s = _scoring()
    expert = {"time": 10.0, "errors": 1.0, "speed": 0.03}
    got = s.score(expert)
    assert got.score == pytest.approx(100.0) and got.passed is True
    failing = {"time": 60.0, "errors": 5.0, "speed": 0.0}
    assert s.score(failing).score == pytest.approx(0.0) and s.score(failing).passed is False


def test_the_overall_score_is_the_weighted_mean_of_the_available_metrics():
    s = _scoring()
    values = {"time": 35.0, "errors": 2.0, "speed": 0.015}  # 50 %, 75 %, 50 %
    got = s.score(values)
    assert got.parts == pytest.approx({"time": 50.0, "errors": 75.0, "speed": 50.0})
    assert got.score == pytest.approx((50 + 3 * 75 + 50) / 5)
    # a metric the engine could not sample is left out, the weights renormalised
    got = s.score({**values, "speed": math.nan})
    assert got.score == pytest.approx((50 + 3 * 75) / 4) and "speed" not in got.parts


def test_pass_marks_are_expert_mean_plus_one_sd_and_every_metric_must_meet_its_own():
    s = _scoring()
    assert s.score({}).marks == pytest.approx({"time": 12.0, "errors": 1.5, "speed": 0.025})
    at_marks = {"time": 12.0, "errors": 1.5, "speed": 0.025}
    assert s.score(at_marks).passed is True
    for name, worse in (("time", 12.01), ("errors", 1.51), ("speed", 0.0249)):
        assert s.score({**at_marks, name: worse}).passed is False, name
    assert s.score(at_marks, finished=False).passed is False


def test_a_programme_sets_its_own_marks_and_overall_pass_score():
    base = _scoring()
    strict = Scoring(
        (ScoreItem("time", 1.0, fail=60.0, pass_mark=11.0), *base.items[1:]),
        reference=base.reference,
        pass_score=95.0,
    )
    values = {"time": 11.5, "errors": 1.0, "speed": 0.03}
    assert base.score(values).passed is True
    assert strict.score(values).passed is False  # time over the programme's mark
    good = {**values, "time": 10.5}
    assert strict.score(good).score == pytest.approx((99 + 300 + 100) / 5)
    assert strict.score(good).passed is True
    # errors 1.4 meets its mark (1.5) but scores 90 %: overall 93.8 % < 95 %
    assert strict.score({**good, "errors": 1.4}).passed is False


def test_without_reference_or_marks_there_is_nothing_to_pass():
    s = Scoring((ScoreItem("time", 1.0, fail=60.0),))
    got = s.score({"time": 10.0})
    assert math.isnan(got.score) and got.passed is None
    assert s.row({"time": 10.0}) == {"score": None, "passed": None}
    with_expert = Scoring((ScoreItem("time", 1.0, fail=60.0, expert=10.0),))
    assert with_expert.row({"time": 35.0}) == {"score": pytest.approx(50.0), "passed": None}


# ---------------------------------------------------------------- task files
def _seed_dict():
    from davinci_sim.tasks.base import task_to_dict

    return task_to_dict(load_task("seed_path"))


def test_a_task_file_updates_the_kinds_scoring(tmp_path):
    data = _seed_dict()
    data["scoring"] = {
        "pass_score": 70,
        "force_threshold": 1.5,
        "metrics": {"completion_time": {"pass_mark": 20.0}, "drops": {"weight": 0}},
    }
    (tmp_path / "t.yaml").write_text(yaml.safe_dump(data))
    task = load_task(tmp_path / "t.yaml")
    scoring = task.scoring
    items = {i.metric: i for i in scoring.items}
    assert scoring.pass_score == 70 and scoring.force_threshold == 1.5
    assert items["completion_time"].pass_mark == 20.0
    assert items["completion_time"].fail == pytest.approx(task.path.length / 0.005)  # kept
    assert scoring.reference is not None  # the scoring does not change the digest
    save_task(task, tmp_path / "again.yaml")
    assert load_task(tmp_path / "again.yaml").scoring_spec == data["scoring"]


@pytest.mark.parametrize(
    ("scoring", "message"),
    [
        ({"metrics": {"juggles": {"weight": 1, "fail": 1}}}, "no metric 'juggles'"),
        ({"metrics": {"peak_force": {"weight": 1, "fail": 1}}}, "no better direction"),
        ({"metrics": {"samples": {"weight": 1, "fail": 1}}}, "no better direction"),
        ({"metrics": {"drops": {"weight": 1}}}, "needs 'fail'"),
        ({"metrics": {"drops": {"weight": -1, "fail": 1}}}, "weight must be >= 0"),
        ({"metrics": {"drops": {"fail": "many"}}}, "drops.fail: must be a number"),
        ({"pass_score": 120}, "pass_score"),
        ({"force_threshold": -1}, "force_threshold"),
        ({"marks": {}}, "scoring.marks: unknown field"),
        ("all", "scoring: must be a mapping"),
    ],
)
def test_a_bad_scoring_is_refused_with_what_to_fix(scoring, message, tmp_path):
    data = {**_seed_dict(), "scoring": scoring}
    (tmp_path / "t.yaml").write_text(yaml.safe_dump(data))
    with pytest.raises(TaskError, match=message):
        load_task(tmp_path / "t.yaml")


# ---------------------------------------------------------------- the expert reference
def test_the_shipped_reference_loads_and_gives_the_seed_task_its_pass_marks():
    task = load_task("seed_path")
    ref = load_reference("seed_path")
    assert ref.task == "seed_path" and ref.digest == task_digest(task)
    assert ref.meta["population"] == "expert" and ref.meta["engine"] == "batch"
    assert ref.meta["subjects"] * ref.meta["repetitions"] == ref.meta["attempts"] == 45
    scoring = task.scoring
    assert scoring.reference == ref and scoring.note == ""
    marks = scoring.score({}).marks
    for item in scoring.items:
        r = ref.metrics[item.metric]
        assert r.n == 45
        assert marks[item.metric] == pytest.approx(r.mean + r.sd)  # all lower-is-better
        assert scoring.expert_value(item) == r.mean
        assert item.fail > r.mean  # the failing threshold is worse than the experts
    means = {k: v.mean for k, v in ref.metrics.items()}
    assert scoring.score(means).score == pytest.approx(100.0)
    assert scoring.score(means).passed is True
    # plausible experts: faster than 10 s, well inside the task's 3 mm tolerance (the expert
    # profile is a trainee at the plateau, with the calibrated trainees' noise: ~1 mm)
    assert 1.0 < means["completion_time"] < 10.0 and means["deviation_error"] < 2e-3


def test_a_task_changed_since_its_reference_does_not_use_it(tmp_path):
    data = _seed_dict()
    data["waypoints"][-1][0] += 0.005
    (tmp_path / "seed_path.yaml").write_text(yaml.safe_dump(data))
    task = load_task(tmp_path / "seed_path.yaml")
    assert task.scoring.reference is None and "another task" in task.scoring.note
    assert task.score({m.name: 0.0 for m in task.METRICS}) == {"score": None, "passed": None}


def test_reference_from_rows_is_mean_and_sample_sd_of_finished_attempts():
    task = PathTask("p", [[0, 0, 0], [0.01, 0, 0]])
    names = [m.name for m in task.METRICS]
    rows = [{**dict.fromkeys(names, v), "finished": True} for v in (1.0, 2.0, 4.0)]
    rows.append({**dict.fromkeys(names, 100.0), "finished": False})
    rows[0]["out_of_view"] = math.nan  # unavailable: left out
    data = reference_from_rows(task, rows, population="expert")
    assert data["attempts"] == 4 and data["finished"] == 3
    m = data["metrics"]["completion_time"]
    assert m["mean"] == pytest.approx(7 / 3) and m["n"] == 3
    assert m["sd"] == pytest.approx(np.std([1.0, 2.0, 4.0], ddof=1))
    assert data["metrics"]["out_of_view"]["n"] == 2
    json.dumps(data, allow_nan=False)  # valid JSON
