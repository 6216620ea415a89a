"""Adaptive guidance at the console (issue 12, item 4): a scripted operator does the short
path twice, badly then well; the session changes the guidance's B between the repetitions by
the rule (never inside one), shows it, and keeps it across get_state/set_state."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from davinci_sim.haptics.adaptive import AdaptiveRule, B_schedule
from davinci_sim.haptics.kinds import fixture_params
from davinci_sim.study.trial import setup_trial
from davinci_sim.tasks import install_task, load_task

SHORT_TASK = str(Path(__file__).resolve().parents[1] / "study" / "short_path.yaml")
ENTRY = {"type": "adaptive", "name": "aan", "mode": "assist_as_needed", "B0": 20.0,
         "G_max": 5.0, "target": 0.0005, "gain": 10000.0, "max_step": 5.0, "window": 1}  # fmt: skip


def _guidance_B(sim, session) -> float:
    """The B of the viscous law in the haptic loop's field now."""
    (viscous,) = sim.components["haptics"].field(session.field_name).fixture.fixtures
    return viscous.B


def test_a_scripted_operator_changes_B_between_repetitions(tmp_path):
    task = load_task(SHORT_TASK)
    setup = setup_trial(task)
    sim, psm = setup.sim, setup.sim.arms[task.teleop.psm]
    log = tmp_path / "reps.csv"
    session = install_task(sim, task, condition=ENTRY, log=log)
    sim.run_for(0.01)
    assert session.snapshot().guidance_B == 20.0 and _guidance_B(sim, session) == 20.0
    setup.teleop.clutch(True)
    T_camera_task = np.linalg.inv(setup.T_task_camera)
    path, goal = task.path, psm.setpoint_cp().T.copy()
    seen_B = []

    def walk(offset, done):
        s = 0.0
        while s < path.length + 0.005 and len(session.results) < done + 1:
            arc = min(s, path.length)
            p = path.point_at(arc) + (offset if path.length / 4 < arc < 3 * path.length / 4 else 0)
            goal[:3, 3] = (T_camera_task @ np.append(p, 1.0))[:3]
            psm.servo_cp(goal)
            sim.step()
            if len(session.results) == done:  # inside the repetition: B does not change
                seen_B.append(_guidance_B(sim, session))
            s += 0.03 * sim.dt

    def back_to_start():
        goal[:3, 3] = (T_camera_task @ np.append(task.start, 1.0))[:3]
        psm.move_cp(goal)
        assert sim.run_until(lambda: session.snapshot().phase == "READY", 5.0)

    walk(np.array([0.0, 0.0, 0.004]), 0)  # 4 mm off for the middle half: a bad repetition
    assert len(session.results) == 1 and set(seen_B) == {20.0}
    first = session.results[0]
    assert first["guidance_B"] == 20.0 and first["deviation_error"] > 0.001
    B2 = session.snapshot().guidance_B
    assert B2 == 25.0  # +5: the step limit (10000·(error − 0.5 mm) is more)
    assert _guidance_B(sim, session) == B2
    saved = sim.get_state()

    back_to_start()
    seen_B.clear()
    walk(np.zeros(3), 1)  # on the path: a good repetition
    assert len(session.results) == 2 and set(seen_B) == {25.0}
    second = session.results[1]
    assert second["guidance_B"] == 25.0 and second["deviation_error"] < 0.0005
    rule = AdaptiveRule.of(fixture_params(ENTRY))
    errors = [r["deviation_error"] for r in session.results]
    want = B_schedule(errors, rule)
    assert [r["guidance_B"] for r in session.results] == want[:2]
    assert session.snapshot().guidance_B == want[2] < 25.0  # fell after the good one
    assert _guidance_B(sim, session) == want[2]
    with open(log) as f:
        logged = list(csv.DictReader(f))
    assert [float(r["guidance_B"]) for r in logged] == want[:2]

    sim.set_state(saved)  # back to after the first repetition: its B with it
    assert session.snapshot().guidance_B == 25.0 and _guidance_B(sim, session) == 25.0
    assert len(session.results) == 1
    sim.close()


def test_conditions_that_are_not_adaptive_show_no_B_and_a_bad_rule_is_refused():
    from davinci_sim.console import install_console
    from davinci_sim.sim.simulation import Simulation

    sim = Simulation("psm1_ecm_mtmr")
    install_console(sim)
    session = install_task(sim, load_task(SHORT_TASK))
    assert session.snapshot().guidance_B is None
    fading = {"type": "adaptive", "mode": "fading", "B0": 30.0, "zero_at": 4}
    assert session.set_condition(fading)
    assert session.snapshot().guidance_B == 30.0
    assert session.condition.startswith("adaptive(mode=fading")
    refused = session.set_condition({"type": "adaptive", "metric": "contact_count"})
    assert not refused and "contact_count" in refused.message
    assert session.snapshot().guidance_B == 30.0  # unchanged
    assert session.set_condition(None)
    assert session.snapshot().guidance_B is None
    sim.close()


@pytest.mark.parametrize("bad", [{"mode": "never"}, {"B_min": 30.0, "B_max": 10.0}])
def test_a_task_file_with_a_bad_adaptive_condition_is_refused(bad, tmp_path):
    import yaml

    from davinci_sim.tasks import TaskError

    data = yaml.safe_load(Path(SHORT_TASK).read_text())
    data["conditions"] = [{"name": "a", "type": "adaptive", **bad}]
    path = tmp_path / "t.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(TaskError):
        load_task(path)
    data["conditions"] = [{"name": "a", "type": "adaptive", "mode": "fading", "zero_at": 5}]
    path.write_text(yaml.safe_dump(data))
    assert load_task(path).condition("a")["zero_at"] == 5


def test_serve_condition_takes_an_adaptive_entry():
    from davinci_sim.system import task_condition

    task = load_task(SHORT_TASK)
    entry = task_condition(task, "{type: adaptive, mode: fading, B0: 40, zero_at: 8}")
    assert entry == {"type": "adaptive", "mode": "fading", "B0": 40, "zero_at": 8}
    task.fixture(entry)
    with pytest.raises(ValueError, match="YAML mapping"):
        task_condition(task, "{type: adaptive, mode: [")
