"""Instruments of different arms touch each other (and the trainer counts it), peg
transfer's economy of motion sums every instrument's path, and a session's reset puts the
rings back on their pegs without a rebuild."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from davinci_sim.model import SceneConfig
from davinci_sim.sim.simulation import Simulation
from davinci_sim.tasks import load_task
from davinci_sim.tasks.base import Sample
from davinci_sim.tasks.state import Phase, TaskMonitor
from davinci_sim.tasks.trainer import InstrumentContacts

SCENE = SceneConfig(arms=("PSM1", "PSM2", "ECM"), include_console=False)


# ================================================================ instrument on instrument
def test_two_instruments_driven_into_each_other_collide_and_are_counted():
    """PSM2's tip streamed (servo_cp) through PSM1's tip: MuJoCo reports contacts between a
    PSM2 tool geom and a PSM1 one, and PSM1's InstrumentContacts counts them (before the
    change the contact bits kept instruments apart and the count stayed 0)."""
    sim = Simulation(SCENE, keyframe="surgical")
    try:
        m, d = sim.model, sim.data
        for n in ("PSM1", "PSM2"):
            assert sim.arms[n].state_command("enable")
            assert sim.arms[n].state_command("home")
        homed = lambda: all(sim.arms[n].is_homed() and not sim.arms[n].is_busy()  # noqa: E731
                            for n in ("PSM1", "PSM2"))  # fmt: skip
        assert sim.run_until(homed, 20)
        counter = InstrumentContacts(m, "PSM1")
        assert counter.measure(m, d)[0] == 0  # apart at the start
        T_camera_world = np.linalg.inv(sim.T_cart_camera())
        tip = {n: d.site_xpos[m.site(f"{n}/tip").id].copy() for n in ("PSM1", "PSM2")}
        R2 = d.site_xmat[m.site("PSM2/tip").id].reshape(3, 3).copy()
        goal = tip["PSM1"] + 0.5 * (tip["PSM1"] - tip["PSM2"])  # through PSM1's tip
        worst, pairs, t0 = 0, set(), sim.time
        while sim.time - t0 < 1.5:
            x = min(1.0, (sim.time - t0) / 1.0)
            G = np.eye(4)
            G[:3, :3], G[:3, 3] = R2, tip["PSM2"] + x * (goal - tip["PSM2"])
            sim.arms["PSM2"].servo_cp(T_camera_world @ G)
            sim.tick()
            count, _ = counter.measure(m, d)
            worst = max(worst, count)
            for c in d.contact[: d.ncon]:
                names = sorted(m.body(m.geom_bodyid[g]).name.split("/")[0] for g in c.geom)
                pairs.add(tuple(names))
        assert worst > 0
        assert ("PSM1", "PSM2") in pairs
    finally:
        sim.close()


def test_an_instrument_never_collides_with_itself_and_every_tool_pair_of_two_arms_does():
    from davinci_sim.model import build_model

    m = build_model("full")
    tools = [g for g in range(m.ngeom) if m.geom_contype[g] & 2]
    arm = {g: m.geom(g).name.split("/")[0] for g in tools}
    for a in tools:
        for b in tools:
            collide = bool(m.geom_contype[a] & m.geom_conaffinity[b]) or bool(
                m.geom_contype[b] & m.geom_conaffinity[a]
            )
            assert collide == (arm[a] != arm[b]), (m.geom(a).name, m.geom(b).name)


# ================================================================ economy of motion
def _peg_run(task, tools_path, dt=0.01):
    """Rings resting on their start pegs, ring 1 held by PSM1's jaws from the 16th sample
    (RUNNING), the instruments' tips following ``tools_path`` (list of (A, 3)) from then
    on, until the time limit finishes the attempt."""
    x = [(task.pegs[p][0], task.pegs[p][1], task.board_top + task.ring_tube_radius)
         for p in task.start_pegs]  # fmt: skip
    rings = np.array(x)
    monitor = TaskMonitor(task)
    grasp = np.zeros(task.n_rings, dtype=np.int64)
    path = [tools_path[0]] * 15 + list(tools_path)
    k = 0
    while monitor.phase not in (Phase.FINISHED, Phase.RESULTS) and k < 10_000:
        if k == 15:
            grasp[0] = 0b0011
        tools = path[min(k, len(path) - 1)]
        monitor.observe(Sample.of(k * dt, tools[0], objects=rings, grasp=grasp, tools=tools))
        k += 1
    return monitor.results.row(0)


def test_peg_economy_of_motion_sums_both_instruments_paths():
    """PSM1's tip goes 3 cm along x; PSM2's 2 cm along y and back (4 cm of path, none of
    displacement): 7 cm of economy of motion, not PSM1's 3 cm."""
    task = dataclasses.replace(load_task("peg_transfer"), time_limit=1.0)
    a = np.array([0.0, 0.0, 0.83])
    b = np.array([0.05, 0.0, 0.83])
    steps = []
    for i in range(61):
        p1 = a + [0.03 * min(i, 30) / 30, 0.0, 0.0]
        p2 = b + [0.0, 0.02 * (i / 30 if i <= 30 else (60 - i) / 30), 0.0]
        steps.append(np.array([p1, p2]))
    row = _peg_run(task, steps)
    assert row["path_length"] == pytest.approx(0.07, abs=1e-9)
    assert row["transferred"] == 0 and row["missed_targets"] == task.n_rings
    # Without the instruments' tips sampled the metric is unavailable, not PSM1's alone.
    monitor = TaskMonitor(task)
    monitor.observe(Sample.of(0.0, a, objects=np.zeros((3, 3)), grasp=np.zeros(3, int)))
    assert monitor.results is None or np.isnan(monitor.results.path_length[0])


# ================================================================ reset
@pytest.fixture(scope="module")
def peg_sim():
    task = load_task("peg_transfer")
    sim = Simulation(SCENE, keyframe="surgical", edit_spec=task.draw)
    yield task, sim
    sim.close()


def _ring(sim, k):
    m, d = sim.model, sim.data
    b = m.body(f"task/ring{k + 1}").id
    j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"task/ring{k + 1}")
    v = m.jnt_dofadr[j]
    return d.xpos[b].copy(), d.xquat[b].copy(), d.qvel[v : v + 6].copy()


def test_reset_scene_puts_a_dropped_ring_back_on_its_peg_at_rest(peg_sim):
    task, sim = peg_sim
    sim.run_for(0.1)
    start = [_ring(sim, k) for k in range(task.n_rings)]
    # Throw ring 2 up and sideways; it falls and lands off its peg.
    m, d = sim.model, sim.data
    j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "task/ring2")
    q, v = m.jnt_qposadr[j], m.jnt_dofadr[j]
    d.qpos[q + 2] += 0.03
    d.qvel[v : v + 6] = [0.2, 0.1, 0.0, 3.0, 1.0, 0.0]
    sim.run_for(0.05)
    assert np.linalg.norm(_ring(sim, 1)[0] - start[1][0]) > 0.005  # in flight, away
    task.reset_scene(m, d)
    for k in range(task.n_rings):
        p, quat, vel = _ring(sim, k)
        np.testing.assert_allclose(p, start[k][0], atol=2e-4)  # (start: after settling)
        np.testing.assert_allclose(np.abs(quat @ start[k][1]), 1.0, atol=1e-6)
        assert np.all(vel == 0.0)
    sim.run_for(0.2)
    p = _ring(sim, 1)[0]
    assert np.linalg.norm(p - start[1][0]) < 5e-4  # rests there
    assert task.peg_of(p[None, None])[0, 0] == task.start_pegs[1]


def test_the_session_reset_command_restores_the_rings_without_a_rebuild():
    """The console's task session (what the web console's Reset and ``/task/reset`` call):
    a ring dropped off the pegs is back on it after ``reset``, the model the same object,
    and the session READY again once the rings rest."""
    from davinci_sim.system import ConsoleDescription, SystemDescription, build_simulation
    from davinci_sim.system.description import TaskDescription

    scene = SceneConfig(arms=("PSM1", "PSM2", "ECM", "MTMR"), include_patient=False)
    console = ConsoleDescription(operator_present=True, teleop_enabled=True)
    system = SystemDescription(scene, console=console, task=TaskDescription("peg_transfer"),
                               runner="none")  # fmt: skip
    sim = build_simulation(system)
    try:
        session, model = sim.components["task"], sim.model
        task = session.task
        sim.run_for(0.3)
        assert session.snapshot().phase == "READY"
        m, d = sim.model, sim.data
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "task/ring1")
        q = m.jnt_qposadr[j]
        cx, cy = task.board_center
        d.qpos[q : q + 3] = [cx, cy + 0.025, task.board_top + 0.01]  # dropped off the pegs
        sim.run_for(0.3)
        assert task.peg_of(_ring(sim, 0)[0][None, None])[0, 0] == -1
        assert session.reset()
        assert sim.model is model and session.snapshot().phase == "IDLE"
        p = _ring(sim, 0)[0]
        x, y = task.pegs[task.start_pegs[0]]
        np.testing.assert_allclose(p, [x, y, task.board_top + task.ring_tube_radius], atol=1e-9)
        sim.run_for(0.3)
        assert session.snapshot().phase == "READY"
    finally:
        sim.close()
