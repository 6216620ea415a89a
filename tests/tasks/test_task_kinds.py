"""A new kind of task is one new class: a minimal "reach a target" kind defined here loads
from its file, draws itself, runs through the monitor and a live session at the simulated
console, and its declared metrics are what the session's CSV log, the bridge's
``/task/results`` and the study's rows hold."""

from __future__ import annotations

import asyncio
import csv
import json
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any, NamedTuple

import mujoco
import numpy as np
import pytest
import yaml
from drawn import drawn_visual_only

from davinci_sim.bridge.task_node import TaskNode
from davinci_sim.study.report import COLUMNS, SUMMARY
from davinci_sim.study.trial import TrialSpec, setup_trial, trial_row
from davinci_sim.tasks import (
    Metric,
    PathTask,
    Phase,
    Task,
    TaskError,
    TaskMonitor,
    TeleopSpec,
    install_task,
    load_task,
    save_task,
    task_kinds,
)
from davinci_sim.tasks.base import check_keys, common_fields
from davinci_sim.tasks.metrics import Count, Elapsed, Mean, PairSum, Peak
from davinci_sim.tasks.scoring import SCORE_COLUMNS
from davinci_sim.tasks.session import SESSION_COLUMNS, session_columns


# ---------------------------------------------------------------- the new kind
class ReachState(NamedTuple):
    phase: np.ndarray
    t_start: np.ndarray


def _to_target(task, s, obs):
    return obs["distance"]


def _step(task, prev, s, obs):
    return np.linalg.norm(s.tip - prev.tip, axis=1)


def _force(task, s, obs):
    return np.linalg.norm(s.force, axis=1)


@dataclass(frozen=True, eq=False)
class ReachTask(Task, kind="reach_test"):
    """Move the tool tip from ``start`` into a sphere of ``radius`` around ``target``."""

    METRICS = (
        Metric("reach_time", "s", "lower", "time from leaving the start to the target",
               Elapsed()),
        Metric("mean_distance", "m", "lower", "mean distance to the target", Mean(_to_target)),
        Metric("travel", "m", "lower", "length of the tip's trajectory", PairSum(_step)),
        Metric("peak_force", "N", "neither", "largest guidance force", Peak(_force)),
        Metric("samples", "1", "neither", "samples of the repetition", Count(), integer=True),
    )  # fmt: skip

    name: str
    start: np.ndarray
    target: np.ndarray
    radius: float = 0.002
    start_tolerance: float = 0.002
    frame: str = "world"
    description: str = ""
    teleop: TeleopSpec = field(default_factory=TeleopSpec)
    fixture_spec: dict = field(default_factory=lambda: {"type": "none"})
    conditions: tuple[dict, ...] = ()
    walls: tuple[dict, ...] = ()

    def __post_init__(self) -> None:
        for key in ("start", "target"):
            object.__setattr__(self, key, np.asarray(getattr(self, key), dtype=float))
        self.check()

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ReachTask:
        known = {"name", "description", "frame", "teleop", "fixture", "conditions", "walls",
                 "start", "target", "radius", "start_tolerance"}  # fmt: skip
        check_keys(data, known, required=("name", "start", "target"))
        extra = {k: data[k] for k in ("start", "target", "radius", "start_tolerance") if k in data}
        return cls(**common_fields(data), **extra)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "start": self.start.tolist(), "target": self.target.tolist(),
                "radius": self.radius, "start_tolerance": self.start_tolerance,
                "frame": self.frame, "teleop": vars(self.teleop).copy()}  # fmt: skip

    def draw(self, spec, *, T_world_camera=None, prefix="task/"):
        body = spec.worldbody.add_body(name=f"{prefix}reach")
        for name, p, r in (("start", self.start, self.start_tolerance),
                           ("target", self.target, self.radius)):  # fmt: skip
            g = body.add_geom(name=f"{prefix}{name}", type=mujoco.mjtGeom.mjGEOM_SPHERE,
                              pos=p, size=[r, 0, 0], rgba=[0.1, 0.9, 0.2, 0.5])  # fmt: skip
            g.contype = g.conaffinity = 0
            g.mass = 0.0
        return body

    def initial_state(self, n):
        return ReachState(np.full(n, Phase.IDLE, dtype=np.int8), np.full(n, np.nan))

    def step(self, state, sample):
        phase = state.phase
        at_start = self.at_start(sample.tip)
        d = self.distance(sample.tip)
        new = phase.copy()
        new[(phase == Phase.IDLE) & at_start] = Phase.READY
        begin = (phase == Phase.READY) & ~at_start
        new[begin] = Phase.RUNNING
        new[(phase == Phase.RUNNING) & (d <= self.radius)] = Phase.FINISHED
        new[phase == Phase.FINISHED] = Phase.RESULTS
        return ReachState(new, np.where(begin, sample.time, state.t_start)), {"distance": d}

    def at_start(self, tip):
        return np.linalg.norm(np.reshape(tip, (-1, 3)) - self.start, axis=1) <= self.start_tolerance

    def distance(self, tip):
        return np.linalg.norm(np.reshape(tip, (-1, 3)) - self.target, axis=1)


@dataclass(frozen=True, eq=False)
class ReachWithForce(ReachTask, kind="reach_test_force"):
    """The same kind with one more metric: adding it is this one entry."""

    METRICS = (
        *ReachTask.METRICS,
        Metric("mean_force", "N", "neither", "mean guidance force", Mean(_force)),
    )


# ---------------------------------------------------------------- loading and drawing
REACH_YAML = """
kind: reach_test
name: reach_short
start: [-0.004, 1.206, 0.845]
target: [0.004, 1.206, 0.841]
radius: 0.0015
start_tolerance: 0.002
teleop: {psm: PSM1, mtm: MTMR, scale: 0.6, keyframe: surgical}
"""


def test_kind_selects_the_class_and_path_files_keep_loading(tmp_path):
    (tmp_path / "reach.yaml").write_text(REACH_YAML)
    task = load_task(tmp_path / "reach.yaml")
    assert isinstance(task, ReachTask) and task.kind == "reach_test"
    assert {"path", "reach_test"} <= set(task_kinds())
    save_task(task, tmp_path / "again.yaml")
    assert (tmp_path / "again.yaml").read_text().startswith("kind: reach_test")
    again = load_task(tmp_path / "again.yaml")
    assert isinstance(again, ReachTask)
    np.testing.assert_array_equal(again.target, task.target)
    seed = load_task("seed_path")  # no kind: the path kind, file unchanged
    assert isinstance(seed, PathTask)
    save_task(seed, tmp_path / "seed.yaml")
    assert "kind" not in (tmp_path / "seed.yaml").read_text()
    (tmp_path / "bad.yaml").write_text(REACH_YAML.replace("reach_test", "juggle"))
    with pytest.raises(TaskError, match="unknown kind 'juggle'.*reach_test"):
        load_task(tmp_path / "bad.yaml")
    (tmp_path / "bad2.yaml").write_text(REACH_YAML + "waypoints: []\n")
    with pytest.raises(TaskError, match="unknown keys"):
        load_task(tmp_path / "bad2.yaml")
    with pytest.raises(TaskError, match="unknown fixture type 'viscous'"):
        ReachTask("r", [0, 0, 0], [1, 0, 0], fixture_spec={"type": "viscous", "B": 1.0})


def test_the_kind_draws_itself_visual_only():
    task = ReachTask("r", [0.0, 1.2, 0.8], [0.01, 1.2, 0.8])
    _, ours = drawn_visual_only(task)
    assert len(ours) == 2


def test_monitor_runs_the_new_kind_and_its_declared_metrics():
    """A straight run at 1 cm/s from the start to the target, sampled at 1 kHz: the
    reach time is the time from leaving the start sphere to entering the target's; the
    metrics agree with the same numbers computed from the recorded samples."""
    task = ReachTask("r", [0.0, 0.0, 0.0], [0.02, 0.0, 0.0], radius=0.002, start_tolerance=0.002)
    monitor = TaskMonitor(task)
    assert monitor.update(0.0, [0.0, 0.0, 0.01]) == Phase.IDLE
    assert monitor.update(0.001, [0.0, 0.0, 0.0]) == Phase.READY
    t = 0.002 + np.arange(3000) * 0.001
    x = 0.01 * (t - 0.002)
    phases, tips = [], []
    for tk, xk in zip(t, x, strict=True):
        tips.append([xk, 0.0, 0.0])
        phases.append(monitor.update(tk, tips[-1], force=[0.0, 0.3 * xk, 0.0]))
        if phases[-1] == Phase.FINISHED:
            break
    first, last = phases.index(Phase.RUNNING), len(phases) - 1
    assert x[first] > 0.002 >= x[first - 1]  # left the start sphere
    assert 0.018 - 1e-12 <= x[last] and x[last - 1] < 0.018  # entered the target sphere
    r = monitor.results
    assert r is not None and r._fields == tuple(m.name for m in ReachTask.METRICS)
    p = np.array(tips[first : last + 1])
    assert r.reach_time[0] == pytest.approx(t[last] - t[first])
    assert r.mean_distance[0] == pytest.approx(np.mean(np.linalg.norm(p - task.target, axis=1)))
    assert r.travel[0] == pytest.approx(p[-1, 0] - p[0, 0])
    assert r.peak_force[0] == pytest.approx(0.3 * x[last])
    assert r.samples[0] == last - first + 1
    assert r.row(0) == {m.name: r[m.name][0] for m in ReachTask.METRICS}
    assert isinstance(r.row(0)["samples"], int)


# ---------------------------------------------------------------- session, bridge, study
class _Bridge:
    def __init__(self):
        self.published: dict[str, list[dict]] = {}

    def advertise(self, topic, msg_type, **kw):
        return topic

    def listen(self, *args, **kw):
        pass

    def publish(self, topic, msg):
        self.published.setdefault(topic, []).append(json.loads(msg["data"]))

    def remove_node(self, node):
        pass


def _bridge_messages(session) -> dict[str, list[dict]]:
    """What :class:`TaskNode` publishes for ``session`` (a handle and bridge stand-in)."""
    handle = SimpleNamespace(snapshot=lambda: SimpleNamespace(extras={"task": session.snapshot()}))
    bridge = _Bridge()

    async def run():
        node = TaskNode(handle)
        node.attach(bridge)
        await node.detach()

    asyncio.run(run())
    return bridge.published


@pytest.mark.parametrize("kind", [ReachTask, ReachWithForce])
def test_a_session_of_the_new_kind_logs_and_publishes_its_declared_metrics(kind, tmp_path):
    """At the simulated console, the tool brought from the start to the target (clutched,
    by the PSM's own move) is one repetition; the session's CSV log, its row, the bridge's
    /task/results and /task/state and a study row all have exactly the kind's declared
    metrics, in the declared order."""
    data = {k: v for k, v in yaml.safe_load(REACH_YAML).items() if k != "kind"}
    task = kind.from_dict(data)
    names = [m.name for m in kind.METRICS]
    setup = setup_trial(task)
    sim = setup.sim
    log = tmp_path / "reps.csv"
    session = install_task(sim, task, log=log)
    sim.run_for(0.01)
    assert session.snapshot().phase == "READY"
    setup.teleop.clutch(True)
    psm = sim.arms["PSM1"]
    T = psm.setpoint_cp().T.copy()
    T[:3, 3] = (np.linalg.inv(setup.T_task_camera) @ np.append(task.target, 1.0))[:3]
    assert psm.move_cp(T)
    assert sim.run_until(lambda: bool(session.results), 10.0)
    row = session.results[0]
    assert list(row) == [*SESSION_COLUMNS, *names, *SCORE_COLUMNS] == list(session_columns(task))
    # The kind scores nothing: no score, nothing to pass.
    assert row["score"] is None and row["passed"] is None
    assert row["task"] == "reach_short" and row["condition"] == "none"
    assert 0 < row["reach_time"] < 5 and row["samples"] > 10
    assert row["mean_distance"] < np.linalg.norm(task.target - task.start)
    with open(log) as f:
        reader = csv.DictReader(f)
        assert reader.fieldnames == list(session_columns(task))
        assert float(next(reader)["reach_time"]) == pytest.approx(row["reach_time"])
    published = _bridge_messages(session)
    assert published["/task/results"] == [row]
    state = published["/task/state"][-1]
    assert state["completed"] == 1 and list(state["last"]) == list(row)
    spec = TrialSpec("reach", subject=0, condition=0, B=0.0, G_max=0.0, repetition=1, order=1,
                     practice=1, seed=0)  # fmt: skip
    study_row = trial_row(spec, task, session.monitor.results, 0, True)
    assert list(study_row)[-len(names) - 2 :] == [*names, *SCORE_COLUMNS]
    assert {k: study_row[k] for k in names} == {k: row[k] for k in names}
    sim.close()


def test_the_study_columns_and_report_come_from_the_path_declaration():
    names = [m.name for m in PathTask.METRICS]
    first = COLUMNS.index(names[0])
    assert list(COLUMNS[first : first + len(names)]) == names
    assert [m.name for m in SUMMARY] == [m.name for m in PathTask.METRICS if m.report]
    assert "deviation_error" in names and "clutch_count" not in [m.name for m in SUMMARY]
