"""The trainer metrics (davinci_sim.tasks.trainer) on constructed cases with known answers."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

from davinci_sim.model.cameras import CameraConfig, in_left_image, project_left
from davinci_sim.tasks import MetricsAccumulator, PathTask, Sample, TaskMonitor
from davinci_sim.tasks.trainer import (
    DROPS,
    ECONOMY,
    EXCESSIVE_FORCE,
    INSTRUMENT_COLLISIONS,
    MASTER_WORKSPACE,
    MISSED_TARGETS,
    OUT_OF_VIEW,
    TIME,
    InstrumentContacts,
)

DT = 0.001
ALL = (TIME, ECONOMY, INSTRUMENT_COLLISIONS, EXCESSIVE_FORCE, OUT_OF_VIEW, MASTER_WORKSPACE,
       DROPS, MISSED_TARGETS)  # fmt: skip
TASK = SimpleNamespace(scoring=SimpleNamespace(force_threshold=2.0))


def _run(tips, *, obs=None, metrics=ALL, task=TASK, **fields):
    """One repetition of every sample (k, 3) tips at 1 kHz; ``fields`` per sample (k, ...)."""
    acc = MetricsAccumulator(metrics, 1, task)
    for i, tip in enumerate(tips):
        extra = {k: (None if v is None else v[i]) for k, v in fields.items()}
        o = {"distance": np.zeros(1), **({} if obs is None else {k: v[i] for k, v in obs.items()})}
        acc.update(np.ones(1, dtype=bool), Sample.of(i * DT, tip, **extra), o)
    return acc.result().row(0)


def _line(length, k):
    return np.stack([np.linspace(0.0, length, k), np.zeros(k), np.zeros(k)], axis=1)


def test_economy_of_motion_of_a_straight_line_is_its_length_in_cm():
    row = _run(_line(0.05, 501))
    assert row["path_length"] == pytest.approx(0.05)
    unit, scale = ECONOMY.display
    assert (unit, row["path_length"] * scale) == ("cm", pytest.approx(5.0))
    assert row["completion_time"] == pytest.approx(0.5)


def test_excessive_force_is_the_time_above_the_threshold():
    """A contact force above 2 N on exactly 37 samples (not the first) → 37 ticks = 37 ms;
    at the threshold itself it is not excessive."""
    k = 200
    force = np.full(k, 1.0)
    force[50:87] = 2.5
    force[120:130] = 2.0  # at the threshold: not above
    row = _run(np.zeros((k, 3)), tool_force=force, contacts=(force > 0).astype(int))
    assert row["excessive_force"] == pytest.approx(37 * DT)
    strict = SimpleNamespace(scoring=SimpleNamespace(force_threshold=0.5))
    row = _run(np.zeros((k, 3)), tool_force=force, contacts=np.ones(k, int), task=strict)
    assert row["excessive_force"] == pytest.approx((k - 1) * DT)  # every pair


def test_collisions_count_contact_onsets():
    contacts = np.array([0, 0, 1, 3, 0, 2, 0, 0, 1, 1])
    row = _run(np.zeros((len(contacts), 3)), contacts=contacts, tool_force=np.zeros(10))
    assert row["instrument_collisions"] == 3 and isinstance(row["instrument_collisions"], int)


def test_out_of_view_is_the_distance_travelled_outside_the_left_image():
    """Along +x (the image's left) at 10 cm depth in 1 mm steps: the left image's edge is
    at x = b/2 + z·(w/2)/f; every step ending beyond it counts, 1 mm each."""
    cam = CameraConfig()
    z = 0.10
    f = 0.5 * cam.height / math.tan(math.radians(cam.fovy_deg) / 2)
    edge = cam.baseline_m / 2 + z * (cam.width / 2) / f  # u = 0 there
    x = np.arange(0.0, 0.0801, 0.001)
    p_camera = np.stack([x, np.zeros_like(x), np.full_like(x, z)], axis=1)
    visible = in_left_image(p_camera, cam)
    outside_steps = int(np.sum(x[1:] > edge))
    assert outside_steps > 10
    row = _run(p_camera, visible=visible)
    assert row["out_of_view"] == pytest.approx(0.001 * outside_steps)
    # and back in: only the steps ending outside count
    back = np.concatenate([p_camera, p_camera[::-1]])
    row = _run(back, visible=in_left_image(back, cam))
    assert row["out_of_view"] == pytest.approx(0.001 * (2 * outside_steps - 1))


def test_in_left_image_is_project_left_for_each_point():
    rng = np.random.default_rng(1)
    cam = CameraConfig()
    p = rng.uniform([-0.2, -0.2, -0.05], [0.2, 0.2, 0.3], size=(500, 3))
    got = in_left_image(p, cam)
    for pi, g in zip(p, got, strict=True):
        uv = project_left(pi, cam)
        want = uv is not None and 0 <= uv[0] < cam.width and 0 <= uv[1] < cam.height
        assert g == want
    assert 50 < got.sum() < 450


def test_master_workspace_is_the_diagonal_of_the_box_the_handle_spans():
    """3 cm along x, then 4 cm along y: the box is 3 x 4 cm, its diagonal 5 cm."""
    master = np.concatenate([_line(0.03, 31), _line(0.04, 41)[:, [1, 0, 2]] + [0.03, 0, 0]])
    master += [0.1, -0.2, 0.3]  # anywhere in HRSV
    row = _run(np.zeros((len(master), 3)), master=master)
    assert row["master_workspace"] == pytest.approx(0.05)


def test_a_metric_without_its_sample_field_is_unavailable_not_zero():
    row = _run(_line(0.01, 11))  # no visible, master, contacts or force sampled
    for name in ("instrument_collisions", "excessive_force", "out_of_view", "master_workspace"):
        assert math.isnan(row[name]), name
    assert row["path_length"] == pytest.approx(0.01)
    assert row["drops"] == 0 and row["missed_targets"] == 0  # nothing observed: none


def test_drops_and_missed_targets_count_the_tasks_events():
    k = 20
    dropped = np.zeros((k, 1), dtype=int)
    dropped[[4, 11]] = 1
    missed = np.zeros((k, 1), dtype=int)
    missed[7] = 1
    row = _run(np.zeros((k, 3)), obs={"dropped": dropped, "missed": missed})
    assert row["drops"] == 2 and row["missed_targets"] == 1


def test_path_missed_targets_are_the_numbered_points_never_reached():
    """An L-shaped path 1→2→3→4: a run straight from 1 to 4 passes 1 cm from points 2 and 3
    (both missed); one along the path misses none."""
    task = PathTask("L", [[0, 0, 0], [0.02, 0, 0], [0.02, 0.02, 0], [0.04, 0.02, 0]],
                    corner_radius=0.0, tube_radius=0.003)  # fmt: skip
    cut = np.linspace([0, 0, 0], [0.04, 0.02, 0], 400)
    along = task.path.point_at(np.linspace(0, task.path.length, 600))
    for tips, missed in ((cut, 2), (along, 0)):
        monitor = TaskMonitor(task)
        monitor.update(0.0, tips[0])
        for i, p in enumerate(tips[1:], start=1):
            monitor.update(i * DT, p)
        assert monitor.results is not None
        row = monitor.results.row(0)
        assert row["missed_targets"] == missed and row["drops"] == 0
    # and the seed path declares every trainer metric
    names = [m.name for m in PathTask.METRICS]
    for m in ALL:
        assert m.name in names


# ---------------------------------------------------------------- MuJoCo contacts
CONTACT_XML = """
<mujoco>
  <option timestep="0.001" gravity="0 0 -9.81"/>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="PSM1/roll" pos="0 0 0.02">
      <freejoint/>
      <geom type="sphere" size="0.02" mass="{mass}"/>
      <body name="PSM1/jaw_1" pos="0.1 0 0"><geom type="sphere" size="0.01" mass="0.01"
        contype="0" conaffinity="0"/></body>
    </body>
    <body name="PSM1/base" pos="-0.1 0 0.02"><freejoint/>
      <geom type="sphere" size="0.02" mass="0.1"/></body>
    <body name="object/peg" pos="0.2 0 0.02"><freejoint/>
      <geom type="sphere" size="0.02" mass="0.1"/></body>
  </worldbody>
</mujoco>
"""


def test_instrument_contacts_count_and_weigh_the_tools_contacts():
    """A 0.3 kg instrument body resting on the floor: one contact carrying m·g; the arm's
    own body resting beside it, and a task object, are not the instrument's contacts."""
    mass = 0.3
    model = mujoco.MjModel.from_xml_string(CONTACT_XML.format(mass=mass))
    data = mujoco.MjData(model)
    for _ in range(2000):
        mujoco.mj_step(model, data)
    probe = InstrumentContacts(model, "PSM1")
    count, force = probe.measure(model, data)
    assert data.ncon >= 3  # the tool, the arm's base and the object, each on the floor
    assert count >= 1
    assert force == pytest.approx(mass * 9.81 + 0.01 * 9.81, rel=0.02)  # tool + its jaw
    lifted = mujoco.MjData(model)
    lifted.qpos[2] = 0.5  # the tool in the air
    mujoco.mj_forward(model, lifted)
    assert probe.measure(model, lifted) == (0, 0.0)


def test_instrument_contacts_leave_out_ignored_objects():
    xml = CONTACT_XML.format(mass=0.3).replace('pos="0.2 0 0.02"', 'pos="0 0 0.0595"')
    model = mujoco.MjModel.from_xml_string(xml)  # the object touching the tool's top
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    with_object = InstrumentContacts(model, "PSM1").measure(model, data)
    without = InstrumentContacts(model, "PSM1", ignore=("object/",)).measure(model, data)
    assert with_object[0] == without[0] + 1


TWO_ARMS_XML = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="PSM1/roll" pos="0 0 0.015"><freejoint/><geom type="sphere" size="0.02"/></body>
    <body name="PSM1/base" pos="0.1 0 0.3"><freejoint/><geom type="sphere" size="0.02"/></body>
    <body name="PSM2/roll" pos="0.1 0 0.33"><freejoint/><geom type="sphere" size="0.02"/></body>
    <body name="PSM2/base" pos="0.3 0 0.3"><freejoint/><geom type="sphere" size="0.02"/>
      </body>
    <body name="PSM2/pitch" pos="0.3 0 0.33"><freejoint/><geom type="sphere" size="0.02"/>
      </body>
  </worldbody>
</mujoco>
"""


def test_a_two_handed_tasks_contacts_count_each_instruments_collisions():
    """PSM1's tool on the floor, PSM2's tool on PSM1's arm, PSM2's arm on its own arm:
    PSM1's contacts alone see the floor only; both instruments' see the floor and PSM2's
    tool on PSM1's arm (not an arm touching itself); the task's metering is both's."""
    model = mujoco.MjModel.from_xml_string(TWO_ARMS_XML)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert data.ncon == 3
    assert InstrumentContacts(model, "PSM1").measure(model, data)[0] == 1
    both = InstrumentContacts(model, ("PSM1", "PSM2"))
    assert both.measure(model, data)[0] == 2
    assert InstrumentContacts(model, "PSM2").measure(model, data)[0] == 1
    # The compiled ticks' watch: a superset of what is counted.
    g = data.contact.geom[: data.ncon]
    watched = (both.tool_geom[g[:, 0]] & both.other_geom[g[:, 1]]) | (
        both.tool_geom[g[:, 1]] & both.other_geom[g[:, 0]]
    )
    assert watched.sum() >= 2
    from davinci_sim.tasks import load_task
    from davinci_sim.tasks.trainer import task_instruments

    assert task_instruments(load_task("needle_pickup")) == ("PSM1", "PSM2")
    assert task_instruments(load_task("seed_path")) == ("PSM1",)


def test_the_live_sample_sees_the_instruments_contacts_at_the_console():
    """At the console with the patient side of the scene, the tool (clutched, moved by the
    PSM) driven down onto the bead on the scene's post: the live sample has the jaws'
    contacts and their force, the tip in view, the master's position; before, none."""
    import dataclasses

    from davinci_sim.model.config import SceneConfig
    from davinci_sim.study.trial import trial_description
    from davinci_sim.system import install_console_of, new_simulation
    from davinci_sim.tasks import load_task
    from davinci_sim.tasks.session import live_sample

    task = load_task(str(Path(__file__).resolve().parents[1] / "study" / "short_path.yaml"))
    scene = SceneConfig(arms=("PSM1", "ECM", "MTMR"), include_patient=True)
    description = dataclasses.replace(trial_description(task), scene=scene)
    sim = new_simulation(description)
    try:
        psm = sim.arms["PSM1"]
        psm.state_command("enable")
        psm.state_command("home")
        assert sim.run_until(lambda: psm.is_homed() and not psm.is_busy(), 30.0)
        console = install_console_of(sim, description)
        teleop = console.psm_teleops["MTMR_PSM1"]
        assert sim.run_until(teleop.is_following, 30.0)
        T_task_camera = task.T_task_camera(sim.T_cart_camera())

        def sample():
            return live_sample(task, T_task_camera, teleop, console, sim.time)

        before = sample()
        assert before.contacts[0] == 0 and before.tool_force[0] == 0.0
        assert before.visible[0] and np.all(np.isfinite(before.master))
        teleop.clutch(True)
        goal = psm.setpoint_cp().T.copy()
        goal[:3, 3] = (np.linalg.inv(T_task_camera) @ [0.02, 1.2, 0.755, 1.0])[:3]
        assert psm.move_cp(goal)
        touched = None
        for _ in range(3000):
            sim.tick()
            s = sample()
            if s.contacts[0] > 0:
                touched = s
                break
        assert touched is not None, "the tool never touched the bead"
        assert touched.tool_force[0] > 0.0
        probe = InstrumentContacts(sim.model, "PSM1", ignore=("object/",))
        assert probe.measure(sim.model, sim.data) == (0, 0.0)  # the bead is an object/
    finally:
        sim.close()


def test_unmeasured_samples_skip_only_what_they_leave_unchanged():
    """Between repetitions (no trial measured) the accumulator skips the reducers that
    declare an unmeasured sample leaves them unchanged: the same state and results, bit for
    bit, as running every reducer on every sample (optional fields coming and going)."""
    from davinci_sim.tasks import load_task

    task = load_task("seed_path")
    rng = np.random.default_rng(2)
    fast = task.metrics_accumulator(1)
    slow = task.metrics_accumulator(1)
    slow.unchanged_checks = (None,) * len(slow.metrics)  # every add runs
    for i in range(400):
        measured = (i // 37) % 2 == 1  # runs of measured and unmeasured samples
        sample = Sample.of(
            0.001 * i, rng.normal(0, 0.01, 3), rng.normal(0, 1, 3), bool(rng.random() < 0.1),
            visible=bool(rng.random() < 0.8), contacts=int(rng.integers(0, 3)),
            tool_force=float(rng.uniform(0, 6)),
            master=None if i % 50 < 5 else rng.normal(0, 0.05, 3),
        )  # fmt: skip
        obs = {"distance": np.array([rng.uniform(0, 0.01)]), "arc_length": np.array([0.01])}
        for acc in (fast, slow):
            acc.update(np.array([measured]), sample, obs)
    a, b = fast.result(), slow.result()
    for m in task.METRICS:
        np.testing.assert_array_equal(a[m.name], b[m.name], strict=True)
    sa, sb = fast.get_state(), slow.get_state()
    assert sa["_missing"] == sb["_missing"]
    for x, y in zip(sa["_acc"], sb["_acc"], strict=True):
        for u, v in zip(x if isinstance(x, tuple) else (x,), y if isinstance(y, tuple) else (y,),
                        strict=True):  # fmt: skip
            if u is not None or v is not None:
                np.testing.assert_array_equal(u, v, strict=True)
