"""The console's compiled ticks (``console/chunk.py``) are the Python ticks bit for bit: what
``make run`` ticks (the full scene, the seed's path with its viscous fixture, both web-console
hands holding the handles, both pairs following) run from one state both ways — the chunker's
calls and one ``Simulation.tick`` at a time — leave the same physics, servo, arms' and
components' states and the same events at the same times; ticks the kernel has no form of
(a key held, a contact of the instrument, a repetition's end) go to Python in the middle."""

from __future__ import annotations

import gc

import numpy as np
import pytest

from bits import assert_same_bits
from davinci_sim.console import chunk
from davinci_sim.operators.guide import guide_tool
from davinci_sim.system import (
    ConsoleDescription,
    SystemDescription,
    TaskDescription,
    build_simulation,
)
from davinci_sim.tasks.session import VIEW_DISTANCE
from davinci_sim.tasks.state import Phase

pytestmark = pytest.mark.skipif(not chunk.COMPILED, reason="numba is off")


SIGNATURES: list = []
BEFORE_CONTROL: list = []


def _serve(task: str, before_control: list | None = None, signatures: list | None = None):
    """What ``serve --task <task> --home`` ticks, the person holding both handles after
    taking control: ``(sim, its chunker, the state then)``; ``before_control`` gets the
    state before, ``signatures`` the kernel's compiled signatures once the system is
    built (its install compiled or loaded it), before any tick."""
    from davinci_sim.console.chunk_kernel import console_chunk

    sim = build_simulation(
        SystemDescription(
            scene="full", keyframe="surgical",
            console=ConsoleDescription(hand_inputs=("MTML", "MTMR")),
            task=TaskDescription(task, frame_view=VIEW_DISTANCE), home=True,
            runner="none", real_time=False,
        )
    )  # fmt: skip
    if signatures is not None:
        signatures.append(list(console_chunk.signatures))
    sim.run_for(8.0)  # homing, the endoscope framed on the task, the tool brought to it
    if before_control is not None:
        before_control.append(sim.get_state())
    console = sim.components["console"]
    console.press("operator_present")
    console.teleop_enable(True)
    sim.components["MTMR/hand"].grasp()
    sim.components["MTML/hand"].grasp()
    teleops = [t for t in console.psm_teleops.values() if t.selected]
    assert sim.run_until(lambda: all(t.is_following() for t in teleops), 30)
    sim.run_for(0.3)
    return sim, sim._chunker, sim.get_state()


@pytest.fixture(scope="module")
def served():
    """What ``make run`` ticks, the person holding both handles after taking control."""
    return _serve("seed_path", BEFORE_CONTROL, SIGNATURES)


class _Calls:
    """The chunker with its calls counted: (ticks run whole, post-steps left)."""

    def __init__(self, chunker) -> None:
        self.chunker, self.answers = chunker, []

    def __call__(self, n, changed=True):
        answer = self.chunker(n, changed)
        self.answers.append(answer)
        return answer


def _events(sim) -> tuple[list, list]:
    """Every event and message of every component and arm from now on, in order (messages
    carry their time), and the functions that end the subscriptions."""
    seen: list = []
    ends = []
    for owner in (*sim.components.values(), *sim.arms.values()):
        channels = getattr(owner, "channels", None)
        if channels is not None:
            ends.append(channels.subscribe(lambda event, payload, name=owner.name: seen.append(
                (name, event, repr(payload)))))  # fmt: skip
    return seen, ends


def _both_ways(served, ticks: int, before=None):
    """From the served state: ``ticks`` ticks one at a time in Python, then the same ticks
    from the same state through the chunker; each run's state, events and the chunker's
    answers."""
    sim, chunker, start = served
    out = []
    calls = _Calls(chunker)
    for use in (None, calls):
        sim.set_state(start)
        chunker._cooldown = 0
        sim.set_chunker(use)
        if before is not None:
            before(sim)
        events, ends = _events(sim)
        sim.advance(ticks)
        out.append((sim.get_state(), list(events), sim.data.qpos.copy()))
        for end in ends:
            end()
    sim.set_chunker(chunker)
    return out, calls.answers


def _assert_same_run(a, b) -> None:
    (sa, ea, qa), (sb, eb, qb) = a, b
    assert_same_bits(qa, qb, "qpos")
    assert_same_bits(np.asarray(sa.physics), np.asarray(sb.physics), "physics")
    for name in ("qfrc_bias", "xfrc_applied", "ctrl", "actuator_force", "qacc_warmstart"):
        assert_same_bits(getattr(sa.data, name), getattr(sb.data, name), f"data.{name}")
    assert_same_bits(sa.tick_count, sb.tick_count, "tick_count")
    assert_same_bits(sa.servo, sb.servo, "servo")
    assert_same_bits(sa.base_frames["frames"][0], sb.base_frames["frames"][0], "frames key")
    assert_same_bits(sa.arms, sb.arms, "arms")
    assert_same_bits(sa.components, sb.components, "components")
    assert ea == eb


def test_the_console_before_anyone_takes_control_ticks_compiled_as_in_python(served):
    """``make run`` before the page takes control: no teleoperation follows, the session
    samples the idle PSM1 (no guidance force requested yet), the MTMs hold their handles."""
    sim, chunker, _ = served
    runs, answers = _both_ways((sim, chunker, BEFORE_CONTROL[0]), 300)
    _assert_same_run(*runs)
    whole = sum(a[0] for a in answers)
    assert whole >= 290, answers[:20]  # (compiled, not Python ticks)
    sim.set_state(BEFORE_CONTROL[0])
    plan = chunker.plan()
    assert plan is not None and plan.teleops == []
    assert not any(row[-1][0] for row in plan.teleop_rows)  # (none followed)


@pytest.mark.parametrize("start", ["following", "before control"])
def test_another_arm_moving_is_sampled_in_python(served, start):
    """A script's ``move_jp`` of an arm no teleoperation drives (PSM3) while the console
    ticks: its trajectory is sampled every tick, as in Python (the kernel has no form of
    it), and the arm gets there."""
    sim, chunker, state = served
    if start == "before control":
        state = BEFORE_CONTROL[0]
    goal = {}

    def move(sim):
        arm = sim.arms["PSM3"]
        q = arm.setpoint_js().position.copy()
        q[0] += 0.05
        goal["q"] = q
        assert arm.move_jp(q)

    runs, _ = _both_ways((sim, chunker, state), 1500, before=move)
    _assert_same_run(*runs)
    assert not sim.arms["PSM3"].is_busy()
    assert abs(sim.arms["PSM3"].measured_js().position[0] - goal["q"][0]) < 2e-3


def test_the_steady_console_ticks_compiled_as_in_python(served):
    runs, answers = _both_ways(served, 400)
    _assert_same_run(*runs)
    whole = sum(a[0] for a in answers)
    assert whole >= 390, answers  # the kernel ran (nearly) every tick, in calls of at most 4
    assert max(a[0] for a in answers) <= chunk.MAX_TICKS


def test_a_repetition_runs_and_ends_in_the_compiled_ticks_as_in_python(served):
    def move(sim):  # the tool off point 1: a repetition runs, its metrics every tick
        device = sim.components["MTMR/device"]
        T = device.input().T_hrsv_tip.copy()
        T[2, 3] += 0.03
        device.move_hand(T)

    runs, answers = _both_ways(served, 1500, before=move)
    _assert_same_run(*runs)
    assert sum(a[0] for a in answers) > 1000
    sim = served[0]
    assert sim.components["task"].monitor.phase in (Phase.RUNNING, Phase.FINISHED)


@pytest.mark.parametrize("speed", [0.02, 0.2])
def test_a_key_held_moves_the_hand_in_the_compiled_ticks_as_in_python(served, speed):
    """The web console's D key (the rate input's velocity for 0.3 s): the hand's target moves
    every tick, held within its lead of the handle (the fast key: the handle lags) and its
    workspace, in the compiled calls as in Python; the key's ticks are the kernel's."""

    def key(sim):
        hand = sim.components["MTMR/hand"]
        assert hand.command([min(speed, hand.max_speed), 0.0, 0.0])

    runs, answers = _both_ways(served, 600, before=key)
    _assert_same_run(*runs)
    assert sum(a[0] for a in answers) >= 590, answers
    sim = served[0]
    moved = sim.components["MTMR/hand"]._target - sim.components["MTMR/hand"]._origin
    assert np.linalg.norm(moved) > 0.5 * speed * 0.3  # (the hand did move)


@pytest.mark.parametrize("turn", [0.8, 3.0])
def test_a_turn_key_held_turns_the_wrist_in_the_compiled_ticks_as_in_python(served, turn):
    """The web console's turn keys (an angular velocity with a translation, 0.3 s): the
    first turn grasps the wrist (Python's tick), then the wrist's target turns every tick,
    held within its lead of the handle (the fast turn: the handle lags), in the compiled
    calls as in Python."""

    def key(sim):
        hand = sim.components["MTMR/hand"]
        assert hand.command([0.02, 0.0, 0.0], angular=[0.0, 0.0, min(turn, hand.max_turn)])

    runs, answers = _both_ways(served, 600, before=key)
    _assert_same_run(*runs)
    assert sum(a[0] for a in answers) >= 580, answers[:10]
    hand = served[0].components["MTMR/hand"]
    R_handle = served[0].components["MTMR/device"].input().T_hrsv_tip[:3, :3]
    assert hand._R_target is not None
    turned = np.degrees(np.arccos(np.clip((np.trace(hand._R_target.T @ R_handle) - 1) / 2, -1, 1)))
    assert turned < np.degrees(hand.max_turn_lead) + 1.0  # (held within its lead)


def test_the_camera_pedal_moves_the_endoscope_in_the_compiled_ticks_as_in_python(served):
    """The camera pedal held and the right hand moved (a key held 0.3 s): the camera
    teleoperation's following ticks — the ECM's goal from the hands, the spring and
    friction each hand feels, the handles' locks turned with the camera — are the kernel's,
    the same bits as Python's (the pedal's and the anchor's ticks are Python's)."""

    def camera(sim):
        sim.components["console"].press("camera")
        hand = sim.components["MTMR/hand"]
        assert hand.command([0.03, 0.02, 0.0])

    sim = served[0]
    q_before = sim.arms["ECM"].measured_js().position.copy()
    runs, answers = _both_ways(served, 600, before=camera)
    _assert_same_run(*runs)
    assert sum(a[0] for a in answers) >= 550, answers[:12]
    ecm = sim.components["console"].ecm_teleop
    assert ecm.snapshot().following
    moved = sim.arms["ECM"].measured_js().position - q_before
    assert np.abs(moved[:2]).max() > 0.002  # (the camera turned, rad)


def test_a_tracking_fault_in_a_call_is_the_python_fault(served):
    def shove(sim):  # a steady shove on the instrument: the tracking error grows, FAULT
        body = sim.model.body("PSM1/roll").id
        sim.data.xfrc_applied[body, :3] = (0.0, 600.0, 0.0)

    runs, answers = _both_ways(served, 400, before=shove)
    _assert_same_run(*runs)
    sim = served[0]
    assert sim.arms["PSM1"].operating_state().state == "FAULT"
    assert any("tracking error" in e[2] for e in runs[1][1])
    assert any(a[0] for a in answers)


def test_a_live_runners_passes_keep_their_plan_until_a_command(served):
    """Passes of 4 ticks that tell the chunk nothing else ran (a live runner's idle loop:
    the chunk keeps its plan) then a command between two passes (the scale: the next pass
    plans again with it), as the same ticks and command in Python."""
    sim, chunker, start = served
    runs = []
    for compiled in (False, True):
        sim.set_state(start)
        chunker._cooldown = 0
        sim.set_chunker(chunker if compiled else None)
        teleop = sim.components["console"].psm_teleops["MTMR_PSM1"]
        device = sim.components["MTMR/device"]
        T = device.input().T_hrsv_tip.copy()
        T[0, 3] += 0.01
        device.move_hand(T)  # (the handle moves: the new scale shows in the tool's motion)
        for p in range(100):
            if p == 40:
                assert teleop.set_scale(0.5)
            sim.advance(4, unchanged=compiled and p not in (0, 40))
        runs.append((sim.get_state(), [], sim.data.qpos.copy()))
    sim.set_chunker(chunker)
    _assert_same_run(*runs)


def test_a_live_runners_periods_write_back_at_their_ends_as_the_python_ticks(served):
    """The live runner (``LoopRunner``, passes of 4 ticks, snapshots every 10) leaves the
    chunk's write-back (the objects, the session's samples and events) to each period's end
    or to a call served through ``execute``: a repetition running, a key held and the
    scale set between two passes, as the same ticks in Python; at a period's end the
    components are written back (what the runners publish), in between the physics and
    the tick count are current."""
    from davinci_sim.sim.handle import execute
    from davinci_sim.sim.runtime.loop import CHUNK_TICKS, LoopRunner

    sim, chunker, start = served
    runs, seen, waiting = [], [], []
    for compiled in (False, True):
        sim.set_state(start)
        chunker._cooldown = 0
        sim.set_chunker(chunker if compiled else None)
        events, ends = _events(sim)
        t0 = sim.tick_count
        device = sim.components["MTMR/device"]
        T = device.input().T_hrsv_tip.copy()
        T[2, 3] += 0.03  # (the tool off point 1: a repetition starts, its metrics run)
        device.move_hand(T)

        def serve(sim=sim, t0=t0) -> bool:
            tick = sim.tick_count - (t0 + -t0 % 10)  # (from the first period's end)
            if tick == 404:  # (a pass's start both ways: a period's end + 4)
                assert execute(sim, "console", "set_scale", (0.5,), {})
            elif tick == 604:
                assert execute(sim, "MTML/hand", "command", ([0.0, 0.02, 0.0],), {})
            elif tick == 904:
                assert execute(sim, "MTML/hand", "command", ([0.0, 0.0, 0.0],), {})
            else:
                return sim.tick_count == t0
            return True

        def published(sim=sim, compiled=compiled) -> None:
            if not compiled:
                return
            if sim.tick_count % 10 == 0:  # (a period's end: what the runners publish)
                seen.append((chunker._pending, sim.components["task"].snapshot()))
            else:
                waiting.append(chunker._pending is not None)

        runner = LoopRunner(sim, real_time=False, chunk=CHUNK_TICKS if compiled else 1)
        runner.run(ticks=1500, before_tick=serve, after_tick=published, every=10)
        runs.append((sim.get_state(), list(events), sim.data.qpos.copy()))
        for end in ends:
            end()
    sim.set_chunker(chunker)
    _assert_same_run(*runs)
    assert sim.components["task"].monitor.phase in (Phase.RUNNING, Phase.FINISHED)
    # (the write-back waited within the periods; at their ends it was done, and the
    # snapshots follow the repetition's metrics as they go)
    assert len(waiting) > 200 and sum(waiting) > 0.9 * len(waiting)
    assert len(seen) >= 149 and all(pending is None for pending, _ in seen)
    assert len({snap.distance_to_path for _, snap in seen}) > 10


def test_the_compiled_passes_free_every_allocation_they_make(served):
    """Over a live runner's passes numba's allocations and frees balance: the reference
    counts pruned from the kernels (``kinematics/jit_refcounts.py``) leak nothing and free
    nothing twice."""
    from numba.core.runtime import _nrt_python, rtsys

    sim, chunker, start = served
    sim.set_state(start)
    chunker._cooldown = 0
    sim.set_chunker(chunker)
    was_on = _nrt_python.memsys_stats_enabled()
    _nrt_python.memsys_enable_stats()
    counts = []
    try:
        for p in range(120):
            if p in (20, 119):  # (after the plan's first passes, and at the end)
                gc.collect()
                stats = rtsys.get_allocation_stats()
                counts.append((stats.mi_alloc, stats.mi_free))
            sim.advance(4, unchanged=p > 0)
    finally:
        if not was_on:
            _nrt_python.memsys_disable_stats()
    (alloc0, free0), (alloc1, free1) = counts
    assert alloc1 > alloc0  # (the passes allocate: the balance below counts something)
    assert alloc1 - free1 == alloc0 - free0


def test_the_install_compiles_the_one_signature_the_ticks_use(served):
    """The console's install compiled (or loaded) the kernel with the signature its calls
    use: none is compiled inside the 1 kHz loop (a minute's stall on a clean checkout)."""
    from davinci_sim.console.chunk_kernel import console_chunk
    from davinci_sim.kinematics.bound import bind

    sim = served[0]
    binds = len(bind.signatures)
    sim.advance(50)
    assert len(SIGNATURES[0]) == 1
    assert list(console_chunk.signatures) == SIGNATURES[0]
    assert len(bind.signatures) == binds


def test_a_python_only_field_keeps_the_python_ticks(served):
    sim, chunker, start = served
    sim.set_state(start)
    haptics = sim.components["console"].haptics
    name = haptics.add_field(lambda state: np.zeros(6), mtm="MTML", name="user")
    try:
        assert chunker.plan() is None
    finally:
        haptics.remove_field(name)
    assert chunker.plan() is not None


# ---------------------------------------------------------------- the other exercises
_EXERCISES: dict = {}


@pytest.fixture(scope="module", params=["needle_drive", "camera_targeting"])
def exercise(request):
    """What ``serve --task <exercise> --home`` ticks, the person holding both handles after
    taking control: an exercise with objects (the needle, the suture pad's skin, no
    guidance: ``fixture: none``) and one without (the camera's targets)."""
    name = request.param
    if name not in _EXERCISES:
        _EXERCISES[name] = _serve(name)
    yield _EXERCISES[name]


def test_another_exercise_ticks_compiled_as_in_python_its_session_sampled_in_python(exercise):
    """An exercise's session samples each compiled tick afterwards through its kind's
    Python step (the needle's pose and the jaws on it as the kernel read them after each
    step): with the D key held, the same states, events and metrics as Python's ticks, and
    the kernel ran the ticks."""

    def key(sim):
        hand = sim.components["MTMR/hand"]
        assert hand.command([0.02, 0.0, 0.0])

    sim = exercise[0]
    runs, answers = _both_ways(exercise, 600, before=key)
    _assert_same_run(*runs)
    assert sum(a[0] for a in answers) >= 580, answers[:10]
    session = sim.components["task"]
    if session.task.objects_probe(sim.model, {}) is not None:
        # the needle read after each step: it rests in its park, the attempt is ready
        assert session.monitor.phase == Phase.READY
        assert np.isfinite(session.monitor.state.p_prev).all()


@pytest.fixture(scope="module")
def needle_drive():
    """The ``exercise`` fixture's needle driving."""
    if "needle_drive" not in _EXERCISES:
        _EXERCISES["needle_drive"] = _serve("needle_drive")
    return _EXERCISES["needle_drive"]


def test_the_tool_pressing_the_skin_ticks_compiled_as_in_python(needle_drive):
    """Needle driving with PSM1's tool brought down onto the suture pad's skin by the right
    hand: every tick touches the skin, and the compiled ticks measure what the session
    samples (the force on the skin, the instruments' contacts) as the Python ticks do,
    bit for bit, without leaving the ticks to Python."""
    sim, chunker, start = needle_drive
    session = sim.components["task"]
    sim.set_state(start)
    probe, pad = session.task.probe(sim.model), session.task.pad
    above = [pad.center[0], pad.center[1], pad.top + 0.012]  # world, m
    assert guide_tool(sim, "MTMR_PSM1", above, lambda: probe.read(sim.data).flex_force > 0.2)
    samples: list = []

    def record(sim):  # what the session samples each tick, in this run
        monitor, seen = session.monitor, []
        samples.append(seen)
        observe = type(monitor).observe

        def observing(sample, active=None):
            seen.append((int(sample.contacts[0]), float(sample.tool_force[0]),
                         float(sample.tissue_force[0])))  # fmt: skip
            return observe(monitor, sample, active)

        monitor.observe = observing

    try:
        runs, answers = _both_ways((sim, chunker, sim.get_state()), 300, before=record)
    finally:
        session.monitor.__dict__.pop("observe", None)
    _assert_same_run(*runs)
    assert sum(a[0] for a in answers) >= 290, answers[:10]
    python, compiled = samples
    assert len(python) == 300 and compiled == python
    assert min(f for _, _, f in python) > 0.05  # (the skin pressed every tick)
    assert sim.arms["PSM1"].operating_state().state == "ENABLED"


@pytest.mark.parametrize("task", ["seed_path", "needle_drive"])
def test_the_clutch_held_ticks_compiled_as_in_python(served, needle_drive, task):
    """The clutch pedal pressed with the D key held (the hand brings the master back while
    the tools stay), on the seed's path during a repetition: the same states, events and
    samples (the clutch among them: a press the path's metrics count) as Python's ticks,
    and the kernel ran the ticks after the pedal's."""
    system = served if task == "seed_path" else needle_drive
    sim = system[0]
    console, session = sim.components["console"], sim.components["task"]
    samples: list = []

    def clutch(sim):
        if task == "seed_path":  # the tool off point 1: a repetition runs
            device = sim.components["MTMR/device"]
            T = device.input().T_hrsv_tip.copy()
            T[2, 3] += 0.03
            device.move_hand(T)
            sim.advance(600)
            assert session.monitor.phase == Phase.RUNNING
        console.press("clutch")
        assert sim.components["MTMR/hand"].command([0.02, 0.0, 0.0])
        seen = []
        samples.append(seen)
        monitor = session.monitor
        observe = type(monitor).observe

        def observing(sample, active=None):  # (the kinds sampled through their Python step)
            seen.append(bool(sample.clutch[0]))
            return observe(monitor, sample, active)

        monitor.observe = observing

    try:
        runs, answers = _both_ways(system, 600, before=clutch)
        assert all(t.is_clutched() for t in console.psm_teleops.values() if t.selected)
    finally:
        session.monitor.__dict__.pop("observe", None)
        console.release("clutch")
    _assert_same_run(*runs)
    assert sum(a[0] for a in answers) >= 580, answers[:10]
    python, compiled = samples
    assert compiled == python
    if task == "needle_drive":
        assert len(python) == 600 and all(python[5:])


@pytest.fixture(scope="module")
def rota():
    """What ``serve --task rota_path --home`` ticks (Rota's viscous-elastic fixture on the
    path), the person holding both handles after taking control."""
    return _serve("rota_path")


def test_rotas_fixture_ticks_compiled_as_in_python(rota):
    """Rota's fixture (viscous + elastic, capped, scaled: its compiled law) renders in the
    compiled ticks: with the W key held the tool rises off the path (which runs across the
    view) and the fixture pulls; the same states, events and metrics as Python's ticks, and
    the kernel ran them."""
    from davinci_sim.haptics import fixture_row

    def key(sim):
        assert sim.components["MTMR/hand"].command([0.0, 0.02, 0.0])

    sim = rota[0]
    field = sim.components["console"].haptics.entries_for("MTMR")[0].field
    assert field.compiled_row()[6] == fixture_row.VISCOUS_ELASTIC
    runs, answers = _both_ways(rota, 600, before=key)
    _assert_same_run(*runs)
    assert sum(a[0] for a in answers) >= 580, answers[:10]
    requested = sim.components["console"].haptics.requested("MTMR")
    assert requested is not None and requested[1] < -0.01  # it pulls back down to the path


def _user_pull(v, phi, params, out):
    """k·φ − c·v, N: a user's own law (``haptics/compiled_law.py``)."""
    for i in range(3):
        out[i] = params[0] * phi[i] - params[1] * v[i]


@pytest.fixture(scope="module")
def user_law():
    """``make run``'s console with the task's fixture replaced by a user's compiled law on
    the same path, the person holding both handles."""
    from davinci_sim.haptics.compiled_law import UserLawGuidance, compiled_law
    from davinci_sim.haptics.fixture import FixtureField

    sim, chunker, _ = _serve("seed_path")
    haptics = sim.components["console"].haptics
    (name,) = [n for n in haptics.field_names() if haptics.field(n).__class__ is FixtureField]
    path = haptics.field(name).fixture.fixtures[0].path
    haptics.remove_field(name)
    haptics.add_field(FixtureField(UserLawGuidance(path, compiled_law(_user_pull), (200.0, 1.0))),
                      mtm="MTMR", name="user")  # fmt: skip
    sim.run_for(0.05)
    return sim, chunker, sim.get_state()


def test_a_users_compiled_law_ticks_compiled_as_in_python(user_law):
    """A user's law compiled with ``compiled_law`` renders in the console's compiled ticks
    (through its C callback) as in the Python ticks, bit for bit, the W key held."""

    def key(sim):
        assert sim.components["MTMR/hand"].command([0.0, 0.02, 0.0])

    sim = user_law[0]
    runs, answers = _both_ways(user_law, 600, before=key)
    _assert_same_run(*runs)
    assert sum(a[0] for a in answers) >= 580, answers[:10]
    requested = sim.components["console"].haptics.requested("MTMR")
    assert requested is not None and requested[1] < -0.01  # it pulls back down to the path
