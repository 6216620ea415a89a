"""Peg transfer: the rings' grasping physics, the state machine on constructed samples, the
task files, and a scripted operator who transfers a ring with a hand-off."""

import dataclasses

import numpy as np
import pytest
from scripted_operator import Operator

from davinci_sim.tasks import TaskError, load_task, task_from_dict, task_kinds, task_to_dict
from davinci_sim.tasks.base import Sample
from davinci_sim.tasks.check import check_task
from davinci_sim.tasks.peg import PegTransferTask
from davinci_sim.tasks.peg_scene import ring_mass
from davinci_sim.tasks.state import Phase, TaskMonitor

PSM1_JAWS, PSM2_JAWS = 0b0011, 0b1100


# ================================================================ the state machine
def _on_peg(task, peg):
    x, y = task.pegs[peg]
    return [x, y, task.board_top + task.ring_tube_radius]


class Run:
    """Feeds constructed samples of one trial (rings' centres and jaw bits) to a monitor."""

    def __init__(self, task, dt=0.01):
        self.task, self.dt, self.t = task, dt, 0.0
        self.monitor = TaskMonitor(task)
        self.p = np.array([_on_peg(task, i) for i in task.start_pegs])
        self.grasp = np.zeros(task.n_rings, dtype=np.int64)
        self.totals = {"transferred": 0, "handoffs": 0, "dropped": 0}

    def tick(self, n=1):
        for _ in range(n):
            self.t += self.dt
            s = Sample.of(self.t, self.p[0] + [0, 0, 0.01], objects=self.p, grasp=self.grasp)
            self.monitor.observe(s)
            if self.monitor.phase in (Phase.RUNNING, Phase.FINISHED):
                for k in self.totals:
                    self.totals[k] += int(self.monitor.observations[k][0])

    def lift(self, ring, bits, dz=0.03):
        self.grasp[ring] = bits
        self.tick()
        self.p[ring, 2] += dz
        self.tick(3)

    def move_over(self, ring, peg, dz=0.03):
        x, y = self.task.pegs[peg]
        self.p[ring] = [x, y, self.task.board_top + self.task.ring_tube_radius + dz]
        self.tick(3)

    def release_onto(self, ring, point):
        self.grasp[ring] = 0
        self.tick()  # let go: still for an instant (not yet resting)
        self.p[ring] = point
        self.tick(3)  # fell: moving fast
        self.tick(int(round(self.task.rest_time / self.dt)) + 3)  # at rest


@pytest.fixture(scope="module")
def plain():
    return load_task("peg_transfer")


@pytest.fixture(scope="module")
def icra():
    return load_task("peg_transfer_icra")


def test_states_start_when_a_ring_is_first_held(plain):
    run = Run(plain)
    run.tick(int(plain.rest_time / run.dt))
    assert run.monitor.phase == Phase.IDLE  # not yet still for rest_time
    run.tick(15)
    assert run.monitor.phase == Phase.READY  # every ring rests on a start peg
    run.tick(5)
    assert run.monitor.phase == Phase.READY
    run.grasp[0] = PSM1_JAWS ^ 0b01  # one jaw only: not held
    run.tick()
    assert run.monitor.phase == Phase.READY
    run.grasp[0] = PSM2_JAWS
    run.tick()
    assert run.monitor.phase == Phase.RUNNING
    assert run.monitor.state.t_start[0] == pytest.approx(run.t)


def test_a_ring_carried_to_a_target_peg_is_transferred_without_a_wall(plain):
    run = Run(plain)
    run.tick(15)
    run.lift(0, PSM2_JAWS)
    run.move_over(0, plain.target_pegs[0])
    run.release_onto(0, _on_peg(plain, plain.target_pegs[0]))
    assert run.totals == {"transferred": 1, "handoffs": 0, "dropped": 0}
    assert run.monitor.state.done[0].tolist() == [True, False, False]
    run.tick(5)  # resting there counts once
    assert run.totals["transferred"] == 1


def test_the_panel_says_which_ring_is_next_and_asks_for_the_hand_off(icra):
    """The console's progress words: none before the start; ``ring k of K`` with k the
    next ring not yet transferred; over the wall, while the carried ring has not changed
    hands, the hand-off is asked for."""
    run = Run(icra)
    run.tick(15)
    assert icra.progress(run.monitor.state) == ""
    run.lift(0, PSM2_JAWS)
    assert (
        icra.progress(run.monitor.state)
        == "ring 1 of 3 to a target peg (hand it off over the wall)"
    )
    run.grasp[0] = PSM1_JAWS | PSM2_JAWS
    run.tick(15)
    run.grasp[0] = PSM1_JAWS
    run.tick(15)
    assert icra.progress(run.monitor.state) == "ring 1 of 3 to a target peg"
    run.move_over(0, icra.target_pegs[0])
    run.release_onto(0, _on_peg(icra, icra.target_pegs[0]))
    assert icra.progress(run.monitor.state) == "ring 2 of 3 to a target peg"


def test_with_the_wall_only_a_handed_off_ring_counts(icra):
    run = Run(icra)
    run.tick(15)
    run.lift(0, PSM2_JAWS)
    run.move_over(0, icra.target_pegs[0])
    run.release_onto(0, _on_peg(icra, icra.target_pegs[0]))
    assert run.totals == {"transferred": 0, "handoffs": 0, "dropped": 0}  # on a peg: no drop
    # The next ring changes hands: PSM2 alone, both, PSM1 alone.
    run.lift(1, PSM2_JAWS)
    run.grasp[1] = PSM1_JAWS | PSM2_JAWS
    run.tick(15)
    run.grasp[1] = PSM1_JAWS
    run.tick(15)
    assert run.totals["handoffs"] == 1
    run.move_over(1, icra.target_pegs[1])
    run.release_onto(1, _on_peg(icra, icra.target_pegs[1]))
    assert run.totals == {"transferred": 1, "handoffs": 1, "dropped": 0}
    assert run.monitor.state.done[0].tolist() == [False, True, False]


def test_drops_a_released_ring_off_the_pegs_and_a_knocked_off_one(plain):
    run = Run(plain)
    run.tick(15)
    run.lift(0, PSM1_JAWS)
    off_board_point = [plain.board_center[0], plain.board_center[1], run.p[0, 2] - 0.03]
    run.release_onto(0, off_board_point)
    assert run.totals["dropped"] == 1
    run.tick(10)  # lying there is one drop
    assert run.totals["dropped"] == 1
    # Ring 2 pushed off its peg without being held (a jaw's side, no grasp bits).
    run.p[1, 0] += 0.02
    run.tick(15)
    assert run.totals["dropped"] == 2
    # Picked up again and dropped again: a second drop of ring 1.
    run.lift(0, PSM1_JAWS)
    run.release_onto(0, off_board_point)
    assert run.totals == {"transferred": 0, "handoffs": 0, "dropped": 3}


def test_finishes_with_every_ring_transferred_and_reports_the_metrics(plain):
    run = Run(plain)
    run.tick(15)
    for ring, peg in enumerate(plain.target_pegs):
        run.lift(ring, PSM1_JAWS)
        run.move_over(ring, peg)
        run.release_onto(ring, _on_peg(plain, peg))
    assert run.monitor.phase >= Phase.FINISHED
    r = run.monitor.results.row(0)
    assert (r["transferred"], r["handoffs"], r["drops"], r["missed_targets"]) == (3, 0, 0, 0)
    assert r["completion_time"] == pytest.approx(run.monitor.state.t_finish[0] - 
                                                 run.monitor.state.t_start[0])  # fmt: skip
    assert np.isnan(r["instrument_collisions"])  # not sampled here: unavailable, not 0
    assert plain.score(r)["score"] is not None


def test_the_time_limit_finishes_an_attempt_and_misses_the_rest(icra):
    task = dataclasses.replace(icra, time_limit=1.0)
    run = Run(task, dt=0.1)
    run.tick(15)
    run.lift(0, PSM2_JAWS)
    run.tick(10)
    assert run.monitor.phase >= Phase.FINISHED
    r = run.monitor.results.row(0)
    assert r["completion_time"] == pytest.approx(1.0, abs=0.11)  # (the first sample past it)
    assert (r["transferred"], r["missed_targets"]) == (0, 3)


# ================================================================ files and scene
def test_task_files_load_round_trip_and_pass_the_check(plain, icra):
    assert task_kinds()["peg_transfer"] is PegTransferTask
    assert (plain.wall, icra.wall, plain.time_limit, icra.time_limit) == (False, True, 300, 180)
    again = task_from_dict(task_to_dict(icra))
    assert again.to_dict() == icra.to_dict()
    for task in (plain, icra):
        bad = [c for c in check_task(task) if not c.ok]
        assert not bad, bad
    # A ring is ~0.5 g of silicone (2π R · π r² · 1200 kg/m³).
    assert ring_mass(0.009, 0.0015) == pytest.approx(2 * np.pi * 0.009 * np.pi * 0.0015**2 * 1200)
    assert 0.0004 < ring_mass(0.009, 0.0015) < 0.0006


@pytest.mark.parametrize(
    ("change", "words"),
    [
        ({"start_pegs": [3, 9]}, "start_pegs"),
        ({"target_pegs": [3, 1, 2]}, "both a start and a target"),
        ({"ring_radius": 0.003}, "clear the peg"),
        ({"wall": "yes"}, "true or false"),
        ({"pegs": [[0.0, 1.2]]}, "at least 2"),
    ],
)
def test_bad_task_files_are_refused_with_the_field_named(icra, change, words):
    data = {**task_to_dict(icra), **change}
    with pytest.raises(TaskError, match=words):
        task_from_dict(data)


# ================================================================ physics and a scripted operator
class PegOperator(Operator):
    """The :class:`Operator` with the rings: where they are, which jaws touch them, and
    where a tip goes to grasp one."""

    def ring(self, i):
        d = self.sim.data
        b = self.probe.bodies[i]
        return d.xpos[b].copy(), d.xmat[b].reshape(3, 3).copy()

    def bits(self, i):
        return int(self.probe.measure(self.sim.data)[1][i])

    def grasp_pivot(self, n, i, depth=0.008, far_from=None):
        """Where ``n``'s tip (the jaws' pivot) goes to grasp ring ``i``'s wall: on the ring's
        circle where the jaws close radially, the tube ``depth`` along the jaws."""
        c, Rr = self.ring(i)
        a, y, normal = self.R[n][:, 2], self.R[n][:, 1], Rr[:, 2]
        radial = y - normal * np.dot(y, normal)
        radial /= np.linalg.norm(radial)
        points = [c + s * self.task.ring_radius * radial - depth * a for s in (1.0, -1.0)]
        if far_from is None:
            return points[0]
        return max(points, key=lambda p: np.linalg.norm(p - far_from))

    def pick(self, n, i, far_from=None, approach=0.02):
        p = self.grasp_pivot(n, i, far_from=far_from)
        self.jaw(n, 0.8)  # open: 46° (dVRK jaw range −40°…80°)
        self.move(n, p - approach * self.R[n][:, 2])
        self.move(n, p)
        self.jaw(n, -0.35)  # the dVRK's close (−20°): the jaw effort saturates on the ring
        return p


@pytest.fixture(scope="module")
def plain_operator(plain):
    op = PegOperator(plain)
    yield op
    op.sim.close()


def test_a_grasped_ring_stays_in_the_jaws_while_the_psm_moves_and_drops_when_they_open(
    plain_operator,
):
    op, task = plain_operator, plain_operator.task
    sim = op.sim
    assert sim.model.neq == 0  # nothing welds or attaches a ring: contact and friction only
    ring = 1
    p = op.pick("PSM2", ring)
    assert op.bits(ring) == PSM2_JAWS
    jaw_effort = sim.data.actuator_force[[sim.model.actuator(f"PSM2/jaw_{i}").id for i in (1, 2)]]
    assert np.allclose(jaw_effort, -0.16)  # the dVRK jaw's ftmax (dvrk.md 1.2)

    def in_tip(n):
        T = op.tip(n)
        return T[:3, :3].T @ (op.ring(ring)[0] - T[:3, 3])

    held_at = in_tip("PSM2")
    # Lift 3 cm, then 5 cm across and 3 cm sideways (move_cp: the dVRK's trajectory speeds).
    for goal in (p + [0, 0, 0.03], p + [-0.05, 0, 0.03], p + [-0.05, 0.03, 0.03]):
        op.move("PSM2", goal)
        assert op.bits(ring) == PSM2_JAWS
        assert np.linalg.norm(in_tip("PSM2") - held_at) < 0.003  # moved with the jaws
        assert op.ring(ring)[0][2] > task.board_top + 0.025
    op.jaw("PSM2", 0.8)
    sim.run_for(0.4)
    centre = op.ring(ring)[0]
    assert op.bits(ring) == 0
    assert centre[2] == pytest.approx(task.board_top + task.ring_tube_radius, abs=0.001)
    assert task.peg_of(centre[None, None])[0, 0] == -1  # on the board, off the pegs
    assert op.totals["dropped"] == 1


def test_a_scripted_operator_transfers_a_ring_over_the_wall_with_a_hand_off(icra):
    """PSM2 lifts a ring off a start peg, brings it over the wall, PSM1 grasps it too, PSM2
    lets go, PSM1 drops it on a target peg (servo_cp streamed by the script; jaws by
    servo_jp): the state records one hand-off and one transfer, and the attempt (the ICRA
    board with one ring, to keep it short) is finished and scored."""
    icra = dataclasses.replace(icra, name="peg_transfer_icra_one_ring", start_pegs=(3,))
    op = PegOperator(icra)
    try:
        t0 = op.sim.time
        hand_off = np.array([icra.board_center[0] + 0.007, icra.board_center[1], 0.835])
        op.jaw("PSM1", 0.8, wait=False, servo=True)
        op.jaw("PSM2", 0.8, servo=True)  # open: 46° (dVRK jaw range −40°…80°)
        p2 = op.grasp_pivot("PSM2", 0)
        # PSM2 above the ring while PSM1 goes to wait above the hand-off place.
        op.glide({"PSM2": p2 - 0.01 * op.R["PSM2"][:, 2], "PSM1": hand_off + [-0.01, 0, 0.02]})
        op.glide({"PSM2": p2})
        op.jaw("PSM2", -0.35, servo=True)  # the dVRK close (−20°): full jaw effort on the ring
        assert op.bits(0) == PSM2_JAWS and op.monitor.phase == Phase.RUNNING
        op.glide({"PSM2": p2 + [0, 0, 0.02]})  # off the peg (15 mm)
        op.glide({"PSM2": op.tip("PSM2")[:3, 3] + hand_off - op.ring(0)[0]})  # over the wall
        assert op.bits(0) == PSM2_JAWS
        op.glide({"PSM1": op.grasp_pivot("PSM1", 0, far_from=op.tip("PSM2")[:3, 3])})
        op.jaw("PSM1", -0.35, servo=True)
        assert op.bits(0) == PSM1_JAWS | PSM2_JAWS
        op.jaw("PSM2", 0.8, servo=True)
        op.glide({"PSM2": op.tip("PSM2")[:3, 3] + [0.01, 0, 0.01]})
        assert op.bits(0) == PSM1_JAWS
        assert op.totals["handoffs"] == 1
        # Over a target peg, the ring's hole around it; open.
        x, y = icra.pegs[icra.target_pegs[2]]
        above = np.array([x, y, icra.board_top + icra.peg_height + 0.006])
        op.glide({"PSM1": op.tip("PSM1")[:3, 3] + above - op.ring(0)[0]})
        op.jaw("PSM1", 0.8, servo=True)
        op.sim.run_for(0.4)
        assert icra.peg_of(op.ring(0)[0][None, None])[0, 0] == icra.target_pegs[2]
        assert op.totals == {"transferred": 1, "handoffs": 1, "dropped": 0}
        assert op.monitor.phase >= Phase.FINISHED
        row = op.monitor.results.row(0)
        assert (row["transferred"], row["handoffs"], row["drops"], row["missed_targets"]) == (
            1, 1, 0, 0)  # fmt: skip
        assert 0 < row["completion_time"] < op.sim.time - t0
        assert row["path_length"] > 0.05  # PSM1's tip: to the hand-off, over the peg
        assert row["instrument_collisions"] == 0  # touching the ring is no collision
        score = icra.score(row)
        assert score["score"] > 50 and score["passed"] is None  # no pass mark set
        print(f"simulated {op.sim.time - t0:.2f} s")
    finally:
        op.sim.close()


def test_a_console_session_reads_the_rings_from_the_scene():
    """``serve --task peg_transfer_icra``'s system: the board drawn in the full scene (every
    keyframe extended by the rings), the session sampling the rings each tick."""
    from davinci_sim.system import ConsoleDescription, SystemDescription, build_simulation
    from davinci_sim.system.description import TaskDescription

    console = ConsoleDescription(operator_present=True, teleop_enabled=True)
    task = TaskDescription("peg_transfer_icra", condition="route_spring")
    sim = build_simulation(SystemDescription("full", console=console, task=task))
    try:
        session = sim.components["task"]
        sim.run_for(0.3)
        obs = session.monitor.observations
        assert session.snapshot().phase == "READY"  # every ring at rest on a start peg
        assert obs["peg"][0].tolist() == list(session.task.start_pegs)
        assert obs["held"][0].tolist() == [0, 0, 0]
        sim.reset()  # back to the keyframe: the rings on their pegs again
        assert sim.model.nkey >= 2 and sim.model.key_qpos.shape[1] == sim.model.nq
    finally:
        sim.close()


def test_scenes_without_the_board_are_unchanged(plain):
    """The board, rings and noslip solver come with the task only (the seed's path scene
    and the study's keep their physics)."""
    from davinci_sim.model import build_model, build_spec

    bare = build_model("psm1")
    assert bare.opt.noslip_iterations == 0
    spec = build_spec("psm1")
    plain.draw(spec)
    drawn = spec.compile()
    assert drawn.opt.noslip_iterations > 0
    assert drawn.nq == bare.nq + 7 * plain.n_rings  # one free joint per ring, appended
    assert np.array_equal(drawn.key_qpos[:, : bare.nq], bare.key_qpos)


def test_the_study_refuses_a_peg_task_in_one_line(tmp_path, capsys):
    from davinci_sim.cli import main

    assert main(["study", "--task", "peg_transfer", "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "peg_transfer exercise" in err and "path" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()
