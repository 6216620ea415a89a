"""The environment whose actions move and turn several instruments: the needle exercises
done through it by a scripted agent, its one-arm case the single-arm environment's bits,
and its rotation actions as documented."""

from __future__ import annotations

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import davinci_sim.envs  # noqa: E402,F401 (registers the ids)
from davinci_sim.envs import DavinciEnv, InstrumentsEnv  # noqa: E402
from davinci_sim.geometry.so3 import rotation_from_vector, rotation_vector  # noqa: E402
from davinci_sim.tasks.needle_scene import grasp_pose  # noqa: E402
from davinci_sim.tasks.state import Phase  # noqa: E402


@pytest.fixture(scope="module")
def pickup():
    env = gym.make("DavinciSim/NeedlePickup-v0").unwrapped
    yield env
    env.close()


def frame(features6: np.ndarray) -> np.ndarray:
    """The rotation whose first two columns are ``features6`` (orientation_features)."""
    x, y = features6[:3], features6[3:]
    return np.column_stack([x, y, np.cross(x, y)])


class Agent:
    """Steers the setpoints of an :class:`InstrumentsEnv` (rotation on) at goals, as a
    proportional controller on what it observes."""

    def __init__(self, env: InstrumentsEnv, obs: dict) -> None:
        self.env, self.obs, self.m = env, obs, env.action_space.shape[0] // len(env.names)
        self.info: dict = {}
        self.ended = False

    def action(self, goals: dict, jaws: dict) -> np.ndarray:
        cfg, obs, m = self.env.config, self.obs, self.m
        a = np.zeros(self.env.action_space.shape, dtype=np.float32)
        for i, (p, R) in goals.items():
            R_set = frame(obs["setpoint_orientation"][i])
            a[i * m : i * m + 3] = np.clip((p - obs["setpoint"][i]) / cfg.max_step, -1, 1)
            turn = rotation_vector(R @ R_set.T) / cfg.max_rotation_step
            a[i * m + 3 : i * m + 6] = np.clip(turn, -1, 1)
        for i, jaw in jaws.items():
            a[i * m + 6] = jaw
        return a

    def step(self, goals: dict, jaws: dict) -> None:
        self.obs, _, terminated, truncated, self.info = self.env.step(self.action(goals, jaws))
        self.ended = terminated or truncated

    def _there(self, i: int, p: np.ndarray, R: np.ndarray) -> bool:
        R_set = frame(self.obs["setpoint_orientation"][i])
        return bool(np.linalg.norm(self.obs["setpoint"][i] - p) < 1e-9
                    and np.linalg.norm(rotation_vector(R @ R_set.T)) < 1e-9)  # fmt: skip

    def go(self, goals: dict, jaws: dict, settle: int = 15) -> None:
        """Until every goal's setpoint is there, then ``settle`` actions more (or the end)."""
        for _ in range(300):
            self.step(goals, jaws)
            there = all(self._there(i, p, R) for i, (p, R) in goals.items())
            if there or self.ended:
                break
        for _ in range(settle):
            if self.ended:
                return
            self.step(goals, jaws)


def test_an_agent_picks_the_needle_up_and_hands_it_over(pickup):
    """From the observations alone (the needle's pose, the tips', camera frame): PSM2 grasps
    the needle across its plane a third of the way along, lifts it out of the foam, PSM1
    grasps it near its point, PSM2 lets go and moves away. The task's own state machine
    sees the pick-up (RUNNING), one hand-off and no drop, and the delivery ends the
    episode as a success."""
    env = pickup
    obs, _ = env.reset(seed=0)
    agent = Agent(env, obs)
    giver, taker = env.names.index("PSM2"), env.names.index("PSM1")
    needle = env._start.task.needle
    up = np.linalg.inv(env._start.T_world_camera)[:3, :3] @ [0.0, 0.0, 1.0]

    def needle_frame():
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = frame(agent.obs["needle_orientation"]), agent.obs["needle_position"]
        return T

    open_, closed = 1.0, -1.0
    R2, pivot2 = grasp_pose(needle_frame(), needle, frame(obs["tip_orientation"][giver]), 0.35,
                            0.008)  # fmt: skip
    agent.go({giver: (pivot2 - 0.012 * R2[:, 2], R2)}, {giver: open_, taker: closed})
    agent.go({giver: (pivot2, R2)}, {giver: open_, taker: closed})
    assert agent.obs["phase"][0] == Phase.READY and not agent.obs["needle_held"].any()
    agent.go({giver: (pivot2, R2)}, {giver: closed, taker: closed})
    np.testing.assert_array_equal(agent.obs["needle_held"][[giver, taker]], [1.0, 0.0])
    assert agent.obs["phase"][0] == Phase.RUNNING
    height = up @ agent.obs["needle_position"]
    lifted = pivot2 + 0.02 * up
    agent.go({giver: (lifted, R2)}, {giver: closed, taker: closed}, settle=30)
    assert up @ agent.obs["needle_position"] - height > 0.01  # m: out of the foam
    assert agent.obs["needle_held"][giver] == 1.0

    hold = {giver: (lifted, R2)}
    R1, pivot1 = grasp_pose(needle_frame(), needle, frame(agent.obs["tip_orientation"][taker]),
                            0.85, 0.006)  # fmt: skip
    agent.go({taker: (pivot1 - 0.012 * R1[:, 2], R1), **hold}, {taker: open_, giver: closed})
    agent.go({taker: (pivot1, R1), **hold}, {taker: open_, giver: closed})
    agent.go({taker: (pivot1, R1), **hold}, {taker: closed, giver: closed})
    np.testing.assert_array_equal(agent.obs["needle_held"], [1.0, 1.0])
    away = lifted - 0.012 * R2[:, 2] + 0.01 * up
    agent.go({taker: (pivot1, R1), giver: (away, R2)}, {taker: closed, giver: open_}, settle=150)
    assert agent.ended, "the delivery should end the episode"
    info = agent.info
    assert info["is_success"] and info["reward_finish"] == 10.0 and not info["fault"]
    assert info["metric_handoffs"] == 1.0 and info["metric_drops"] == 0.0
    assert info["metric_missed_targets"] == 0.0
    np.testing.assert_array_equal(agent.obs["needle_held"][[giver, taker]], [0.0, 1.0])


def test_a_rotation_action_turns_the_setpoint_by_its_rotation_vector(pickup):
    """An action's (rx, ry, rz) turn the arm's orientation goal about the camera's axes by
    that rotation vector × ``max_rotation_step``, its position goal and the other arm's
    goals unchanged; the tool's orientation follows."""
    env = pickup
    obs0, _ = env.reset(seed=0)
    i, other = env.names.index("PSM1"), env.names.index("PSM2")
    m = env.action_space.shape[0] // 2
    a = np.zeros(env.action_space.shape, dtype=np.float32)
    a[i * m + 3 : i * m + 6] = [1.0, -0.5, 0.25]
    a[[m - 1, 2 * m - 1]] = -1.0  # (jaws closed, as at the start)
    obs, *_ = env.step(a)
    w = env.config.max_rotation_step * np.array([1.0, -0.5, 0.25])
    R_expected = rotation_from_vector(w) @ frame(obs0["setpoint_orientation"][i])
    np.testing.assert_allclose(frame(obs["setpoint_orientation"][i]), R_expected, atol=1e-12)
    np.testing.assert_array_equal(obs["setpoint"], obs0["setpoint"])
    np.testing.assert_array_equal(obs["setpoint_orientation"][other],
                                  obs0["setpoint_orientation"][other])  # fmt: skip
    for _ in range(10):
        obs, *_ = env.step(np.where(np.arange(len(a)) % m == m - 1, -1.0, 0.0).astype(np.float32))
    turned = rotation_vector(frame(obs["tip_orientation"][i]) @ R_expected.T)
    assert np.linalg.norm(turned) < 0.01  # rad: the tool followed
    assert np.linalg.norm(obs["tip_position"][i] - obs["setpoint"][i]) < 5e-4


def test_one_arm_without_turning_is_the_single_arm_environment_bit_for_bit():
    """``arms=("PSM1",)`` runs each period's ticks in Python, per arm: the same ticks as
    the single-arm environment's (compiled) period, bit for bit."""
    actions = np.random.default_rng(3).uniform(-1, 1, (12, 4)).astype(np.float32)
    single, several = DavinciEnv(), InstrumentsEnv(arms=("PSM1",))
    try:
        assert several.action_space.shape == (4,)
        o1, _ = single.reset(seed=5)
        o2, _ = several.reset(seed=5)
        np.testing.assert_array_equal(o1["target"], o2["target"])
        for a in actions:
            o1, r1, t1, u1, _ = single.step(a)
            o2, r2, t2, u2, _ = several.step(a)
            assert (r1, t1, u1) == (r2, t2, u2)
            for k in ("tip_position", "tip_orientation", "joint_position", "setpoint", "jaw"):
                np.testing.assert_array_equal(o1[k], np.reshape(o2[k], np.shape(o1[k])), k)
    finally:
        single.close()
        several.close()


def test_settings_it_cannot_run_are_refused():
    with pytest.raises(ValueError, match="instruments"):
        InstrumentsEnv(task="needle_pickup", arms=("PSM1", "PSM3"))
    with pytest.raises(ValueError, match="joint"):
        InstrumentsEnv(task="needle_pickup", action_space="joint", rotation=True)
    with pytest.raises(ValueError, match="InstrumentsEnv"):
        DavinciEnv(arms=("PSM1",))
    with pytest.raises(ValueError, match="distinct PSM"):
        InstrumentsEnv(arms=("PSM1", "PSM1"))
    with pytest.raises(ValueError, match="ECM"):
        gym.make("DavinciSim/CameraTargeting-v0", action_space="joint", arms=("PSM1",))
    env = gym.make("DavinciSim/NeedleDrive-v0", arms=None, rotation=False).unwrapped
    try:  # (the single-arm environment, with the needle's observations)
        assert type(env) is DavinciEnv
        assert {"needle_position", "needle_held", "tissue_force", "entry_mark"} <= set(
            env.observation_space.spaces
        )
    finally:
        env.close()


def test_with_joint_errors_the_observed_tip_is_what_the_arm_reports_not_where_it_is():
    """The robot-inaccuracy option: the observation's tip is the arm's own (nominal)
    kinematics, the episode's start its goal, while the instrument stands millimetres away
    (its MuJoCo tip site)."""
    import mujoco

    errors = {"PSM1": (0.044, -0.008, 0.004)}
    env = DavinciEnv(joint_errors=errors)
    try:
        obs, _ = env.reset(seed=0)
        np.testing.assert_allclose(obs["tip_position"], obs["setpoint"], atol=2e-4)
        site = mujoco.mj_name2id(env.sim.model, mujoco.mjtObj.mjOBJ_SITE, "PSM1/tip")
        T = np.linalg.inv(env.sim.T_cart_camera())
        p_true = T[:3, :3] @ env.sim.data.site_xpos[site] + T[:3, 3]
        assert np.linalg.norm(p_true - obs["tip_position"]) > 0.005  # m
        assert env.sim.config.errors_of("PSM1") == errors["PSM1"]
    finally:
        env.close()
    with pytest.raises(ValueError, match="joint_errors"):
        DavinciEnv(joint_errors={"PSM2": (0.0, 0.0, 0.001)})  # (no PSM2 in Reach's scene)


def test_needle_drivings_progress_reward_is_the_share_of_pairs_newly_passed():
    """The running suture's four pairs: each pair passed gives a quarter of
    PROGRESS_REWARD once, at the action it is passed; the marks observed are the next
    pair's (the last pair's once all are passed)."""
    from davinci_sim.envs.problems import PROGRESS_REWARD, TaskProblem
    from davinci_sim.tasks import load_task

    task = load_task("running_suture")
    problem = TaskProblem(task, 1, np.eye(4), camera=None)
    T_tip = np.eye(4)[None]
    marks = task.pad.marks_world()
    rewards = []
    for passed in (0, 0, 1, 3, 4, 4):
        problem.state = problem.state._replace(next_pair=np.array([passed]))
        _, _, terms = problem.outcome(T_tip, np.eye(4))
        rewards.append(terms["reward_progress"][0])
        feats = problem.features(T_tip, np.eye(4))
        np.testing.assert_allclose(feats["entry_mark"][0], marks[min(passed, 3), 0])
    np.testing.assert_allclose(rewards, np.array([0, 0, 1, 2, 1, 0]) * PROGRESS_REWARD / 4)
