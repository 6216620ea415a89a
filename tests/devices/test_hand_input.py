"""The rate input on a simulated MTM's hand (keyboard, gamepad): the tool moves the way the
input says, by the teleoperation's scale; the input stops by itself; bad input changes
nothing."""

import math

import numpy as np
import pytest

from davinci_sim.system import ConsoleDescription, SystemDescription
from davinci_sim.system.build import build_simulation


@pytest.fixture(scope="module")
def following():
    """PSM1 teleoperated by MTMR with a hand input, following; and its saved state."""
    description = SystemDescription(
        scene="psm1_ecm_mtmr",
        home=True,
        runner="none",
        console=ConsoleDescription(
            hand_inputs=("MTMR",), operator_present=True, teleop_enabled=True
        ),
    )
    sim = build_simulation(description)
    teleop = sim.components["console"].psm_teleops["MTMR_PSM1"]
    assert sim.run_until(teleop.is_following, 30.0)
    return sim, teleop, sim.get_state()


@pytest.fixture
def system(following):
    sim, teleop, state = following
    sim.set_state(state)
    return sim, teleop, sim.components["MTMR/hand"]


def tip(sim):
    return sim.arms["PSM1"].measured_cp().position.copy()


def test_the_hand_input_is_ticked_before_the_device_it_steers(system):
    sim, _, _ = system
    order = list(sim.components)
    assert order.index("MTMR/hand") < order.index("MTMR/device")


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_a_velocity_moves_the_tool_along_the_same_camera_axis_by_the_scale(system, axis):
    sim, teleop, hand = system
    handle0, p0 = teleop.device.input().position.copy(), tip(sim)
    v = np.zeros(3)
    v[axis] = 0.04  # m/s in HRSV
    for _ in range(5):  # commands every 0.1 s, as a page sends them
        assert hand.command(v)
        sim.run_for(0.1)
    sim.run_for(0.5)  # the input times out; the handle settles
    moved_handle = teleop.device.input().position - handle0
    moved_tool = tip(sim) - p0
    # The hand moved for 0.4 s plus the last command's timeout; HRSV and camera axes are
    # aligned (dvrk.md 4.2).
    assert moved_handle[axis] == pytest.approx(0.04 * (0.4 + hand.timeout), abs=0.003)
    assert moved_tool[axis] == pytest.approx(teleop.scale() * moved_handle[axis], abs=0.0015)
    others = [i for i in range(3) if i != axis]
    assert np.abs(moved_tool[others]).max() < 0.2 * abs(moved_tool[axis])


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_the_handle_moves_with_the_hand_soon_after_a_key(system, axis):
    """The hand moves with its target (the device's damping acts about the key's
    velocity), so the handle is under way within 18 ms of simulated time of a key at
    5 cm/s, and lags the hand by less than the hand's damping alone would hold it back
    (``D·v/K``, 1.25 mm at the default impedance) plus the MTM's own resistance. A hand
    damping the handle's motion in space took 23-34 ms."""
    sim, teleop, hand = system
    device = teleop.device
    h0, t0 = device.input().position.copy(), sim.time
    v = np.zeros(3)
    v[axis] = 0.05  # m/s in HRSV
    assert hand.command(v)
    started = None
    while sim.time - t0 < 0.25:
        sim.tick()
        if started is None and abs(device.input().position[axis] - h0[axis]) > 1e-4:
            started = sim.time - t0
    assert started is not None and started <= 0.018
    lag = hand.snapshot()["target"][axis] - device.input().position[axis]
    assert 0.0 < lag < 0.0035  # m (the same hand damping in space: 2.5-4.3 mm)


def test_a_hand_held_back_damps_the_handle_in_space(system):
    """Moving freely, the hand gives its device the key's velocity (its damping acts about
    it); held back by its lead on the handle, it gives none: a hand pushing on a held
    handle damps it as at rest."""
    sim, teleop, hand = system
    device = teleop.device
    v = np.array([0.0, 0.03, 0.0])
    assert hand.command(v)
    hand.pre_step(sim.time)
    np.testing.assert_array_equal(device.get_state()["_hand_velocity"], np.r_[v, 0, 0, 0])
    sim.tick()  # (the device's read uses it up)
    assert not device.get_state()["_hand_velocity"].any()
    lead, hand.max_lead = hand.max_lead, 1e-5  # m: the handle now holds the hand back
    try:
        assert hand.command(v)
        hand.pre_step(sim.time)
        assert not device.get_state()["_hand_velocity"].any()
    finally:
        hand.max_lead = lead


def test_the_input_stops_by_itself_after_its_timeout(system):
    sim, teleop, hand = system
    assert hand.command([0.05, 0.0, 0.0])
    sim.run_for(hand.timeout + 0.5)
    target = np.array(hand.snapshot()["target"])
    sim.run_for(1.0)  # no more commands: nothing moves the target any more
    assert np.array_equal(np.array(hand.snapshot()["target"]), target)
    assert hand.snapshot()["velocity"] == (0.0, 0.0, 0.0)
    # It had moved 0.05 m/s for the timeout (not for the whole 0.8 s).
    start = hand.get_state()["_origin"]
    assert np.linalg.norm(target - start) == pytest.approx(0.05 * hand.timeout, rel=0.05)


def test_the_target_never_leads_the_handle_by_more_than_max_lead(system):
    sim, teleop, hand = system
    hand.grasp()
    handle0 = teleop.device.input().position.copy()
    # Faster than the handle follows (0.25 m/s, 10 ms steps): the target waits for it.
    for _ in range(20):
        assert hand.command([0.0, 0.0, 0.25])
        sim.run_for(0.01)
        lead = np.array(hand.snapshot()["target"]) - teleop.device.input().position
        assert np.linalg.norm(lead) <= hand.max_lead + 1e-9
    assert teleop.device.input().position[2] > handle0[2]


def test_the_target_stays_in_the_workspace(system):
    sim, _, hand = system
    hand.grasp()
    origin = hand.get_state()["_origin"]
    for _ in range(40):
        hand.command([0.25, 0.0, 0.0])
        sim.run_for(0.1)
    reach = np.linalg.norm(np.array(hand.snapshot()["target"]) - origin)
    assert reach <= hand.workspace + 1e-9


@pytest.mark.parametrize(
    "velocity, gripper, words",
    [
        ([math.nan, 0, 0], None, "finite"),
        ([0, 0], None, "3 finite"),
        (["a", 0, 0], None, "3 numbers"),
        ([1.0, 0, 0], None, "over"),
        ([0, 0, 0], 2.0, "gripper"),
        ([0, 0, 0], math.nan, "gripper"),
        ([0, 0, 0], True, "gripper"),
    ],
)
def test_bad_input_is_refused_and_changes_nothing(system, velocity, gripper, words):
    sim, _, hand = system
    before = hand.get_state()
    result = hand.command(velocity, gripper)
    assert not result and words in result.message
    after = hand.get_state()
    for k, v in before.items():
        assert np.array_equal(np.asarray(after[k]), np.asarray(v)), k


def test_release_lets_go_and_a_new_input_takes_the_handle_again(system):
    sim, teleop, hand = system
    assert hand.command([0.0, 0.02, 0.0])
    sim.run_for(0.2)
    assert hand.release() and not hand.holding
    assert teleop.device.hand_target() is None
    assert hand.command([0.0, 0.02, 0.0]) and hand.holding
    assert teleop.device.hand_target() is not None


def test_the_gripper_input_sets_the_mtm_gripper(system):
    sim, _, hand = system
    assert hand.command([0, 0, 0], gripper=0.5)
    sim.run_for(0.5)
    gripper = sim.arms["MTMR"].gripper.measured_jp()
    assert gripper == pytest.approx(0.5, abs=0.05)


def test_a_squeezed_gripper_closes_the_jaw_to_the_dvrk_close(system):
    """Squeezed past "just closed" (0) to −15°, the MTM gripper reads −15° and the
    teleoperation's jaw = 80°/60° · gripper (dvrk.md 4.2) goes to −20°, the dVRK's close
    (dvrk.md 3.2): with nothing between the jaws they stop at the jaw's model limit."""
    sim, _, hand = system
    assert hand.command([0, 0, 0], gripper=math.radians(-15))
    sim.run_for(0.5)
    assert math.degrees(sim.arms["MTMR"].gripper.measured_jp()) == pytest.approx(-15, abs=1)
    jaw_goal = float(sim.arms["PSM1"].jaw.setpoint_js().position[0])
    assert math.degrees(jaw_goal) == pytest.approx(-20, abs=0.5)
    assert math.degrees(sim.arms["PSM1"].jaw.measured_jp()) == pytest.approx(-20, abs=2)


def test_state_round_trip_resumes_identically(system):
    sim, teleop, hand = system
    hand.command([0.03, 0.0, 0.01])
    sim.run_for(0.05)
    state = sim.get_state()
    sim.run_for(0.2)
    first = tip(sim)
    sim.set_state(state)
    sim.run_for(0.2)
    assert np.array_equal(tip(sim), first)


def test_the_teleoperation_of_a_rate_input_keeps_the_tool_orientation(system):
    sim, teleop, hand = system
    assert teleop.rotation_locked()
    R0 = sim.arms["PSM1"].measured_cp().T[:3, :3].copy()
    for _ in range(10):
        hand.command([0.03, -0.02, 0.02])
        sim.run_for(0.1)
    R1 = sim.arms["PSM1"].measured_cp().T[:3, :3]
    angle = np.arccos(np.clip((np.trace(R0.T @ R1) - 1) / 2, -1, 1))
    assert angle < np.radians(2)


def test_an_angular_velocity_turns_the_tool_the_same_way_once_rotation_is_unlocked(system):
    """The wrist keys' path: rotation unlocked (the web console does it on the first turn;
    the teleoperation re-aligns with the wrist relaxed), then 0.4 rad/s about HRSV y for
    0.5 s: the MTM and the tool turn by 0.2 rad about the same axis (camera and HRSV axes
    are aligned, the alignment offset multiplies on the right)."""
    from davinci_sim.geometry import so3

    sim, teleop, hand = system
    psm = sim.arms["PSM1"]
    assert teleop.rotation_locked()  # a rate input's teleoperation starts locked
    teleop.lock_rotation(False)
    assert sim.run_until(teleop.is_following, 10.0)
    R0 = psm.measured_cp().T[:3, :3].copy()
    p0 = tip(sim)
    for _ in range(5):
        assert hand.command([0.0, 0.0, 0.0], None, [0.0, 0.4, 0.0])
        sim.run_for(0.1)
    assert hand.snapshot()["wrist_held"]
    sim.run_for(0.5)  # the input times out; the handle settles
    turned = so3.rotation_vector(psm.measured_cp().T[:3, :3] @ R0.T)
    # 0.4 rad/s for 0.4 s of commands plus the last one's timeout (0.3 s).
    assert turned == pytest.approx([0.0, 0.4 * (0.4 + hand.timeout), 0.0], abs=0.02)
    assert np.linalg.norm(tip(sim) - p0) < 0.002  # turned about the tip, not moved
    assert hand.relax_wrist() and not hand.snapshot()["wrist_held"]


@pytest.mark.parametrize(
    "angular, words",
    [([0.0, 0.0], "3 finite"), ([0.0, math.nan, 0.0], "3 finite"), ([3.0, 0.0, 0.0], "over")],
)
def test_a_bad_angular_velocity_is_refused_and_changes_nothing(system, angular, words):
    sim, _, hand = system
    before = hand.get_state()
    result = hand.command([0.01, 0.0, 0.0], None, angular)
    assert not result and words in result.message
    after = hand.get_state()
    assert all(np.array_equal(np.asarray(before[k]), np.asarray(after[k]))
               for k in ("_v", "_w", "_target"))  # fmt: skip
