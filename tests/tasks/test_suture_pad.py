"""The suture pad and needle driving: the needle's passage read from geometry (entry and
exit errors, trauma) against constructed drives and an independent reference, the skin
denting locally under an instrument and springing back, and the ``needle_drive`` kind's
state machine (one pair, the running suture's four in order)."""

import dataclasses
import math

import mujoco
import numpy as np
import pytest
from compiled_reads import contacts_measured, stops_on_contact
from scripted_operator import Operator

from davinci_sim.console import chunk
from davinci_sim.model.psm import JAW_LENGTH
from davinci_sim.tasks import TaskError, load_task, task_from_dict, task_to_dict
from davinci_sim.tasks.base import Sample
from davinci_sim.tasks.check import check_task
from davinci_sim.tasks.needle_scene import NeedleSpec, driver_grasp, grasp_pose
from davinci_sim.tasks.state import Phase, TaskMonitor
from davinci_sim.tasks.suture_pad import (
    SuturePad,
    circle_deviation,
    drive_pose,
    no_passage,
    passage_step,
    skin_dofs,
)

NEEDLE = NeedleSpec()
PAD = SuturePad(center=(0.0, 0.0), top=0.795)
PSM1_JAWS = 0b1100  # (instruments [PSM2, PSM1])


def rot_y(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def drive(theta, centre=(0.0, 0.0, None), tilt=0.0):
    """The needle's frame in the pad's, turned by ``theta`` about its own centre in the
    pad's x-z plane (the point down into the skin as theta grows); the centre ``h`` above
    the skin so that the circle crosses it at the default marks (±7 mm); ``tilt`` turns the
    needle's plane about the pad's x axis."""
    r = NEEDLE.radius
    h = math.sqrt(r * r - 0.007**2) if centre[2] is None else centre[2]
    # The needle's y axis up, its z along −y of the pad (as in the park), then turned.
    R0 = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    c, s = math.cos(tilt), math.sin(tilt)
    Rx = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    T = np.eye(4)
    T[:3, :3] = Rx @ rot_y(-theta) @ R0
    T[:3, 3] = [centre[0], centre[1], h]
    return T


def run_passage(frames, pad=PAD):
    state = no_passage(1)
    events = []
    for T in frames:
        state, ev = passage_step(state, T[None], NEEDLE, pad)
        events.append(ev)
    return state, events


def first(events, field):
    hits = [e for e in events if getattr(e, field)[0]]
    return hits[0] if hits else None


# ================================================================ passage, pure
def test_a_needle_turned_about_its_centre_passes_the_marks_without_trauma():
    frames = [drive(t) for t in np.linspace(0.0, math.radians(170), 400)]
    state, events = run_passage(frames)
    entered, exited = first(events, "entered"), first(events, "exited")
    assert entered is not None and exited is not None
    assert exited.passed[0] and exited.pair[0] == 0
    # The crossing points are interpolated between samples 0.4° apart on the circle.
    assert exited.entry_error[0] < 1e-4 and exited.exit_error[0] < 1e-4
    # (the entry point is on the chord between two samples: r·(1 − cos 0.2°) off the circle)
    assert exited.trauma[0] < 1e-7
    assert not state.inside[0]


@pytest.mark.parametrize(("dx", "passed"), [(0.001, True), (0.002, True), (0.003, False)])
def test_entry_and_exit_errors_are_the_offset_of_the_needles_bite(dx, passed):
    frames = [drive(t, centre=(dx, 0.0, None)) for t in np.linspace(0.0, math.radians(170), 400)]
    _, events = run_passage(frames)
    exited = first(events, "exited")
    assert exited.entry_error[0] == pytest.approx(dx, abs=1e-4)
    assert exited.exit_error[0] == pytest.approx(dx, abs=1e-4)
    assert bool(exited.passed[0]) is passed


def test_a_needle_pushed_sideways_in_the_tissue_measures_its_trauma():
    """Half way round, the needle is moved 1.5 mm along the pad's y (out of its plane),
    then turned on: the entry point is 1.5 mm off its circle from then on."""
    thetas = np.linspace(0.0, math.radians(170), 400)
    frames = [drive(t, centre=(0.0, 0.0015 if t > math.radians(90) else 0.0, None))
              for t in thetas]  # fmt: skip
    _, events = run_passage(frames)
    exited = first(events, "exited")
    assert exited.trauma[0] == pytest.approx(0.0015, rel=1e-6)


def test_a_needle_backed_out_where_it_went_in_is_withdrawn_not_passed():
    thetas = np.concatenate([np.linspace(0.0, 1.0, 100), np.linspace(1.0, 0.0, 100)])
    _, events = run_passage([drive(t) for t in thetas])
    assert first(events, "entered") is not None
    assert first(events, "withdrawn") is not None
    assert first(events, "exited") is None


def test_a_tip_off_the_pad_does_not_enter_it():
    frames = [drive(t, centre=(0.05, 0.0, None)) for t in np.linspace(0, 3, 200)]
    _, events = run_passage(frames)
    assert first(events, "entered") is None


def test_the_circle_deviation_matches_a_search_over_the_circle():
    """Against an independent reference: the nearest of 200,000 points of the circle."""
    rng = np.random.default_rng(3)
    p = rng.normal(scale=0.01, size=(50, 3))
    phi = np.linspace(0, 2 * np.pi, 200_000, endpoint=False)
    circle = np.stack([NEEDLE.radius * np.cos(phi), NEEDLE.radius * np.sin(phi),
                       np.zeros_like(phi)], axis=1)  # fmt: skip
    ref = np.array([np.linalg.norm(circle - q, axis=1).min() for q in p])
    assert np.allclose(circle_deviation(p, NEEDLE.radius), ref, atol=1e-6)


@pytest.mark.parametrize("tilt", [0.0, 0.7])
def test_the_drive_pose_crosses_the_skin_at_the_marks(tilt):
    """The needle's circle at :func:`drive_pose` meets the skin's rest surface at the
    pair's entry and exit marks (every pair of the running suture), in a plane containing
    them, tilted as asked; turning it is turning about its centre."""
    task = load_task("running_suture")
    pad = task.pad
    T_pad_world = np.linalg.inv(pad.T_world_pad)
    for k in range(len(task.pairs)):
        T = T_pad_world @ drive_pose(pad, k, NEEDLE, 0.3, tilt)
        T2 = T_pad_world @ drive_pose(pad, k, NEEDLE, 1.1, tilt)
        assert np.allclose(T[:3, 3], T2[:3, 3])
        phi = np.linspace(0, 2 * np.pi, 20001)
        circle = (T[:3, :3] @ np.stack([np.cos(phi), np.sin(phi), 0 * phi]) * NEEDLE.radius).T
        circle += T[:3, 3]
        crossings = circle[np.flatnonzero(np.diff(np.sign(circle[:, 2])))]
        assert len(crossings) == 2
        for mark in pad.marks[k]:
            assert np.linalg.norm(crossings - mark, axis=1).min() < 1e-5
        assert abs(math.asin(abs(T[2, 2])) - tilt) < 1e-9  # (the normal's rise)


@pytest.mark.parametrize(
    ("change", "words"),
    [({"spacing": -1.0}, "spacing"), ({"k_normal": 1e5}, "too stiff"),
     ({"pairs": (((0.03, 0.0), (0.0, 0.0)),)}, "inner part"), ({"pairs": ()}, "pair"),
     ({"skin_radius": 0.003}, "skin_radius"), ({"size": (0.003, 0.03)}, "size")],
)  # fmt: skip
def test_a_bad_pad_is_refused_with_the_field_named(change, words):
    with pytest.raises(ValueError, match=words):
        dataclasses.replace(PAD, **change)


# ================================================================ the kind
@pytest.fixture(params=["needle_drive", "running_suture"])
def task(request):
    return load_task(request.param)


class Run:
    """Samples built by hand: the needle in its park, then held by PSM1 and driven
    through pairs (the monitor at 250 Hz)."""

    dt = 0.004

    def __init__(self, task):
        self.task, self.t = task, 0.0
        self.monitor = TaskMonitor(task)
        self.T = task.T_world_start.copy()
        self.grasp = 0
        self.totals = {"passes": 0, "dropped": 0}

    def tick(self, n=1):
        for _ in range(n):
            self.t += self.dt
            p = self.T[:3, 3]
            s = Sample.of(self.t, p + [0, 0, 0.01], objects=p[None], grasp=self.grasp,
                          T_task_object=self.T, tools=np.array([p, p]))  # fmt: skip
            self.monitor.observe(s)
            if self.monitor.phase in (Phase.RUNNING, Phase.FINISHED):
                for k in self.totals:
                    self.totals[k] += int(self.monitor.observations[k][0])

    def drive(self, pair, dx=0.0, steps=120):
        """Turn the needle through ``pair``'s marks (its centre ``dx`` off along the
        pair's line), held by PSM1."""
        entry, exit_ = self.task.pad.marks[pair]
        mid = (entry + exit_) / 2
        yaw = math.atan2(*(exit_ - entry)[1::-1])
        Rz = np.eye(4)
        Rz[:2, :2] = [[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]]
        for t in np.linspace(0.0, math.radians(170), steps):
            T_pad = Rz @ drive(t)
            T_pad[:3, 3] += mid + Rz[:3, 0] * dx
            self.T = self.task.pad.T_world_pad @ T_pad
            self.tick()


def test_driving_through_every_pair_in_order_finishes_the_attempt(task):
    run = Run(task)
    run.tick(40)
    assert run.monitor.phase == Phase.READY
    run.grasp = PSM1_JAWS
    run.tick()
    assert run.monitor.phase == Phase.RUNNING
    k = len(task.pairs)
    for pair in range(k):
        run.drive(pair, dx=0.001)
        assert run.totals["passes"] == pair + 1
    assert run.monitor.phase >= Phase.FINISHED
    row = run.monitor.results.row(0)
    assert (row["passes"], row["missed_targets"], row["drops"]) == (k, 0, 0)
    assert row["entry_error"] == pytest.approx(0.001, abs=2e-4)
    assert row["exit_error"] == pytest.approx(0.001, abs=2e-4)
    assert row["tissue_trauma"] < 1e-6
    assert task.summary(row).startswith(f"{k} of {k} pairs passed")


def test_a_bite_off_its_marks_or_out_of_order_is_not_a_pass():
    task = dataclasses.replace(load_task("running_suture"), time_limit=5.0)
    run = Run(task)
    run.tick(40)
    run.grasp = PSM1_JAWS
    run.tick()
    run.drive(0, dx=0.004)  # 4 mm off: beyond the 2.5 mm marks
    run.drive(2)  # the third pair before the first
    assert run.totals["passes"] == 0
    run.drive(0)
    run.drive(1)
    assert run.totals["passes"] == 2
    assert run.monitor.phase == Phase.RUNNING
    assert task.progress(run.monitor.state) == "enter the tissue at entry mark 3 of 4"
    run.tick(int(task.time_limit / run.dt))
    row = run.monitor.results.row(0)
    assert (row["passes"], row["missed_targets"]) == (2, 2)
    assert row["entry_error"] == pytest.approx(0.004, abs=3e-4)


def test_the_task_files_round_trip_and_pass_the_check(task):
    again = task_from_dict(task_to_dict(task))
    assert again.to_dict() == task.to_dict()
    bad = [c for c in check_task(task) if not c.ok]
    assert not bad, bad


@pytest.mark.parametrize(
    ("change", "words"),
    [({"pairs": [[[0.0, 0.0]]]}, "pair"), ({"pairs": [[[0.05, 0.0], [0.0, 0.0]]]}, "inner"),
     ({"pad_center": [1.0]}, "pad_center"), ({"mark_radius": 0}, "mark_radius"),
     ({"pad_top": 0.7}, "no room for its base"),
     ({"pairs": [[[-0.009, 0.0], [0.009, 0.0]]]}, "diameter")],
)  # fmt: skip
def test_bad_task_files_are_refused_with_the_field_named(change, words):
    task = load_task("needle_drive")
    with pytest.raises(TaskError, match=words):
        task_from_dict({**task_to_dict(task), **change})


# ================================================================ physics
@pytest.fixture(scope="module")
def operator():
    op = Operator(load_task("needle_drive"), counts=("dropped",))
    yield op
    op.sim.close()


def skin(op):
    """The skin's vertices (world, m) now."""
    return op.sim.data.flexvert_xpos.copy()


def test_an_instrument_dents_the_skin_locally_and_it_springs_back(operator):
    """PSM1's closed jaws pressed 2 mm into the skin between the marks: the vertices
    under the jaws sink, those 12 mm away barely move, the force on the tissue is
    measured, and it is no instrument collision; lifted, the skin is back at rest."""
    op, task = operator, operator.task
    m, d = op.sim.model, op.sim.data
    pad = task.pad
    rest = skin(op)
    on = pad.T_world_pad[:3, 3] + [0.0, 0.0015, 0.0]  # between two vertex rows
    x = op.R["PSM1"][:, 0] * [1, 1, 0]
    x /= np.linalg.norm(x)
    op.R["PSM1"] = np.column_stack([x, np.cross([0, 0, -1.0], x), [0, 0, -1.0]])  # jaws down
    op.move("PSM1", on + [0, 0, JAW_LENGTH + 0.015])
    op.jaw("PSM1", -0.35)
    op.move("PSM1", on + [0, 0, JAW_LENGTH + pad.skin_radius - 0.002])  # 2 mm in
    op.sim.run_for(0.3)
    dent = (skin(op) - rest)[:, 2]
    xy = np.linalg.norm(rest[:, :2] - on[:2], axis=1)
    near, far = xy < 0.004, xy > 0.012
    assert dent[near].min() < -0.0008
    assert np.abs(dent[far]).max() < 0.25 * abs(dent[near].min())
    # the force on the skin: each contact with the flex's normal force (MuJoCo's own)
    probe = task.probe(m)
    f6, on_skin = np.zeros(6), 0.0
    for i in range(d.ncon):
        if probe.flex in d.contact.flex[i]:
            mujoco.mj_contactForce(m, d, i, f6)
            on_skin += abs(f6[0])
    assert on_skin > 0.05
    assert probe.read(d).flex_force == pytest.approx(on_skin, rel=1e-12)
    sample = task.scene_fields(m, d, {})
    assert sample["tissue_force"] == probe.read(d).flex_force
    from davinci_sim.tasks.trainer import InstrumentContacts

    contacts = InstrumentContacts(m, "PSM1", task.CONTACT_IGNORE)
    count, _ = contacts.measure(m, d)
    assert count == 0  # (the skin is what the instruments work on)
    if chunk.COMPILED:  # the console's compiled ticks measure the same, bit for bit
        assert not stops_on_contact(d, contacts)
        measured = contacts_measured(m, d, contacts, probe.flex)
        assert measured == (*contacts.measure(m, d), probe.read(d).flex_force)
    op.move("PSM1", on + [0, 0, JAW_LENGTH + 0.015])
    op.sim.run_for(0.5)
    assert np.abs(skin(op) - rest).max() < 2e-4
    assert len(skin_dofs(m)) == int((~pad.border()).sum())  # (one along the normal each)


def test_the_needle_passes_through_the_skin_without_touching_it(operator):
    """The needle put half way through the pad (its passage is geometry): no contact of
    the needle with the skin, and the skin does not move."""
    import mujoco

    op, task = operator, operator.task
    m, d = op.sim.model, op.sim.data
    mujoco.mj_forward(m, d)  # (the positions of the state now, not of the last step's start)
    rest = skin(op)
    T = task.pad.T_world_pad @ drive(math.radians(90))
    j = m.joint("task/needle")
    q = m.jnt_qposadr[j.id]
    d.qpos[q : q + 3] = T[:3, 3]
    mujoco.mju_mat2Quat(d.qpos[q + 3 : q + 7], T[:3, :3].ravel())
    mujoco.mj_forward(m, d)
    assert not (d.contact.flex[: d.ncon] >= 0).any()
    assert np.abs(skin(op) - rest).max() < 1e-9
    task.reset_scene(m, d)
    assert np.allclose(task.probe(m).frame(d), task.T_world_start, atol=1e-9)


def test_a_scripted_surgeon_drives_the_needle_through_and_pulls_it_out():
    """The needle-driving exercise by script, the needle held by friction only: PSM2 picks
    it out of its park and tilts its plane 45°; PSM1 takes it in a needle driver's grip
    (jaws across it, :func:`driver_grasp`) and turns it about its centre
    (:func:`drive_pose`) in at the entry mark and out at the exit; PSM2 takes the point
    that came out and turns it on until the whole needle is through. One pass, the bite
    within 1 mm of both marks, under 1 mm of trauma, nothing dropped; the instruments'
    force on the skin measured (PSM1's jaws ride on it)."""
    task = load_task("needle_drive")
    op = Operator(task, counts=("dropped", "passes", "handoffs"))
    try:
        needle_probe = task.probe(op.sim.model)

        def frame():
            return needle_probe.frame(op.sim.data)

        def carry(n, T_goal):  # (the needle held by n to T_goal, as the jaws hold it)
            G = T_goal @ np.linalg.inv(frame()) @ op.tip(n)
            op.R[n] = G[:3, :3]
            op.move(n, G[:3, 3])

        def take(n, R, pivot):
            op.R[n] = R
            op.jaw(n, 0.8)
            op.move(n, pivot - 0.012 * R[:, 2])
            op.move(n, pivot)
            op.jaw(n, -0.35)

        def let_go(n):
            op.jaw(n, 0.8)
            op.move(n, op.tip(n)[:3, 3] - 0.012 * op.R[n][:, 2])

        tilt = math.radians(45)
        take("PSM2", *grasp_pose(frame(), task.needle, op.tip("PSM2")[:3, :3], 0.6, 0.008))
        lifted = frame()
        lifted[:3, 3] += [0, 0, 0.02]
        c, s = math.cos(tilt), math.sin(tilt)
        lifted[:3, :3] = np.array([[1, 0, 0], [0, c, -s], [0, s, c]]) @ lifted[:3, :3]
        carry("PSM2", lifted)
        take("PSM1", *driver_grasp(frame(), task.needle, op.tip("PSM1")[:3, 2], 0.12, 0.006))
        let_go("PSM2")
        assert needle_probe.grasp(op.sim.data) == PSM1_JAWS

        def pose(deg):
            return drive_pose(task.pad, 0, task.needle, math.radians(deg), tilt)

        above = pose(20)
        above[2, 3] += 0.012
        carry("PSM1", above)
        for deg in np.linspace(20, 195, 30):
            carry("PSM1", pose(deg))
        assert op.totals["passes"] == 1
        # The point out, a few mm above the skin: PSM2 takes it from above (its jaws down
        # the needle's normal, deep in them: their tips clear the skin), and pulls the
        # needle through along its curve.
        down = np.array([0.0, 0.0, -1.0])
        take("PSM2", *driver_grasp(frame(), task.needle, down, 0.92, 0.0085))
        let_go("PSM1")
        for deg in np.linspace(195, 365, 30):
            carry("PSM2", pose(deg))
        lowest = (frame() @ np.c_[task.needle.points(np.linspace(0, 1, 21)), np.ones(21)].T)[2]
        assert lowest.min() > task.pad.top  # all of it out
        assert op.monitor.phase >= Phase.FINISHED
        row = op.monitor.results.row(0)
        assert (row["passes"], row["missed_targets"], row["drops"]) == (1, 0, 0)
        assert row["entry_error"] < 0.001 and row["exit_error"] < 0.001
        assert row["tissue_trauma"] < 0.001
        assert row["tissue_force"] > 0.0
        assert op.totals["dropped"] == 0
    finally:
        op.sim.close()


def test_a_console_session_reads_the_needle_and_the_pad_from_the_scene():
    """``serve --task needle_drive``'s system: the park, the needle and the pad drawn in the
    full scene (every keyframe extended by the needle and the skin), the session sampling
    them each tick; a reset puts the needle back in its park and the skin at rest."""
    import mujoco

    from davinci_sim.system import ConsoleDescription, SystemDescription, build_simulation
    from davinci_sim.system.description import TaskDescription

    console = ConsoleDescription(operator_present=True, teleop_enabled=True)
    sim = build_simulation(SystemDescription("full", console=console,
                                             task=TaskDescription("needle_drive")))  # fmt: skip
    try:
        session = sim.components["task"]
        sim.run_for(0.3)
        assert session.snapshot().phase == "READY"
        assert sim.model.key_qpos.shape[1] == sim.model.nq
        task = session.task
        dofs = skin_dofs(sim.model)
        q = sim.model.jnt_qposadr[dofs]
        sim.data.qpos[q] -= 0.001  # the skin pushed in
        task.reset_scene(sim.model, sim.data)
        assert np.abs(sim.data.qpos[q]).max() == 0.0
        mujoco.mj_forward(sim.model, sim.data)
        assert np.allclose(sim.data.flexvert_xpos[:, 2], task.pad.top, atol=1e-9)
    finally:
        sim.close()
