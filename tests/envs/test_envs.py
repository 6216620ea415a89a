"""The Gymnasium environments of the exercises: checked by Gymnasium, deterministic, reset by
state, and the task's phases ending the episodes."""

from __future__ import annotations

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

from gymnasium.utils.env_checker import check_env  # noqa: E402

import davinci_sim.envs  # noqa: E402,F401 (registers the ids)
from davinci_sim.envs import ENVIRONMENTS, control  # noqa: E402
from davinci_sim.envs.base import DavinciEnv  # noqa: E402
from davinci_sim.envs.setup import EnvConfig  # noqa: E402


@pytest.mark.parametrize("env_id", list(ENVIRONMENTS))
def test_every_environment_passes_gymnasiums_checker(env_id):
    env = gym.make(env_id).unwrapped
    try:
        check_env(env, skip_render_check=True)
        obs, _ = env.reset(seed=3)
        assert env.observation_space.contains(obs)
    finally:
        env.close()


def test_joint_space_variant_passes_the_checker():
    env = gym.make("DavinciSim/Reach-v0", action_space="joint").unwrapped
    try:
        check_env(env, skip_render_check=True)
        assert env.action_space.shape == (7,)  # six joints and the jaw
        assert env.observation_space["setpoint"].shape == (6,)
    finally:
        env.close()


@pytest.fixture(scope="module")
def reach():
    env = DavinciEnv()
    yield env
    env.close()


def _run(env, seed, actions):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, reward, terminated, truncated, _ = env.step(a)
        out.append({**obs, "reward": np.array([reward])})
        if terminated or truncated:
            break
    return out


def test_the_same_seed_gives_the_same_episode_bit_for_bit(reach):
    actions = np.random.default_rng(1).uniform(-1, 1, (12, 4)).astype(np.float32)
    first, second = _run(reach, 7, actions), _run(reach, 7, actions)
    other = _run(reach, 8, actions)
    assert len(first) == len(second)
    for a, b in zip(first, second, strict=True):
        for k in a:
            np.testing.assert_array_equal(a[k], b[k])
    assert not np.array_equal(first[0]["target"], other[0]["target"])


def test_an_action_runs_compiled_with_the_python_ticks_results(reach, monkeypatch):
    """The control period's ticks in one compiled call (sim/live_period.py) give the
    episode the Python ticks give, bit for bit; they ran compiled."""
    actions = np.random.default_rng(2).uniform(-1, 1, (30, 4)).astype(np.float32)
    if reach._period is None:
        pytest.skip("numba does not compile here")
    calls = []
    run = reach._period.run
    monkeypatch.setattr(reach._period, "run", lambda *a, **k: calls.append(1) or run(*a, **k))
    compiled = _run(reach, 5, actions)
    assert len(calls) >= len(compiled) - 1
    monkeypatch.setattr(reach, "_period", None)
    python = _run(reach, 5, actions)
    assert len(compiled) == len(python)
    for a, b in zip(compiled, python, strict=True):
        for k in a:
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def test_reset_restores_the_start_state_without_rebuilding(reach):
    sim, model = reach.sim, reach.sim.model
    obs0, _ = reach.reset(seed=2)
    for _ in range(5):
        reach.step(np.array([1.0, -1.0, 1.0, 1.0], dtype=np.float32))
    obs1, _ = reach.reset(seed=2)
    assert reach.sim is sim and reach.sim.model is model
    for k in obs0:
        np.testing.assert_array_equal(obs0[k], obs1[k])
    # The start: the tool at its goal, still, with the target within the drawn box.
    np.testing.assert_allclose(obs0["tip_position"], obs0["setpoint"], atol=1e-4)
    assert np.abs(obs0["joint_velocity"]).max() < 1e-3
    assert np.all(np.abs(obs0["target"] - obs0["setpoint"]) <= reach.config.reach_radius)


def test_a_proportional_controller_reaches_the_target(reach):
    """The actions move the tip in the camera frame: steering the setpoint at the target
    brings the tip within the tolerance, which terminates the episode as a success."""
    obs, _ = reach.reset(seed=4)
    d0 = np.linalg.norm(obs["target_offset"])
    for _ in range(100):
        a = np.zeros(4, dtype=np.float32)
        a[:3] = np.clip((obs["target"] - obs["setpoint"]) / reach.config.max_step, -1, 1)
        obs, reward, terminated, truncated, info = reach.step(a)
        if terminated or truncated:
            break
    assert terminated and info["is_success"] and not info["fault"]
    assert info["reward_success"] == 10.0
    assert np.linalg.norm(obs["target_offset"]) <= reach.config.reach_tolerance < d0
    assert reward == pytest.approx(info["reward_distance"] + info["reward_success"])


def test_the_episode_truncates_at_its_step_limit():
    env = DavinciEnv(max_episode_steps=3)
    try:
        env.reset(seed=0)
        ends = [env.step(np.zeros(4, dtype=np.float32))[3] for _ in range(3)]
        assert ends == [False, False, True]
        with pytest.raises(RuntimeError, match="reset"):
            env.step(np.zeros(4, dtype=np.float32))
    finally:
        env.close()


def test_path_following_ends_when_the_task_finishes():
    """Following the next-point feature along the seed's path: the task's own state machine
    goes READY → RUNNING → FINISHED, which terminates the episode with the finish reward and
    the task's metrics in info."""
    env = gym.make("DavinciSim/PathFollow-v0").unwrapped
    try:
        obs, _ = env.reset(seed=0)
        phases, total_progress = [], 0.0
        for _ in range(400):
            a = np.zeros(4, dtype=np.float32)
            a[:3] = np.clip((obs["next_point"] - obs["setpoint"]) / env.config.max_step, -1, 1)
            obs, reward, terminated, truncated, info = env.step(a)
            phases.append(int(obs["phase"][0]))
            total_progress += info["reward_progress"]
            if terminated or truncated:
                break
        assert terminated and info["is_success"] and info["reward_finish"] == 10.0
        assert 2 in phases  # RUNNING
        assert total_progress == pytest.approx(20.0 * obs["progress"][0])
        assert obs["progress"][0] > 0.5
        assert 0 < info["metric_completion_time"] < 8.0
        assert info["metric_deviation_error"] < 0.003  # m: within the task's tube
    finally:
        env.close()


def test_the_step_computes_the_features_once_with_the_results_of_computing_them_twice():
    """A step finds the path's closest point once for the reward and the observation
    (``problem.features`` handed to ``outcome``): the same reward terms and features as
    ``outcome`` computing its own, and the path kind's distance as the task states it."""
    import copy

    env = gym.make("DavinciSim/PathFollow-v0").unwrapped
    try:
        obs, _ = env.reset(seed=0)
        for _ in range(30):
            a = np.zeros(4, dtype=np.float32)
            a[:3] = np.clip((obs["next_point"] - obs["setpoint"]) / env.config.max_step, -1, 1)
            obs, _, _, _, _ = env.step(a)
            T, T_task_camera = env._T_tip()[None], env._T_task_camera()
            own, given = copy.deepcopy(env.problem), copy.deepcopy(env.problem)
            feats = given.features(T, T_task_camera)
            r1, d1, terms1 = own.outcome(T, T_task_camera)
            r2, d2, terms2 = given.outcome(T, T_task_camera, feats)
            assert r1 == r2 and d1 == d2 and terms1.keys() == terms2.keys()
            for k in terms1:
                np.testing.assert_array_equal(terms1[k], terms2[k])
            for k in ("distance", "progress", "next_point", "phase"):
                np.testing.assert_array_equal(obs[k], feats[k][0])
            tip = T_task_camera[:3, :3] @ T[0, :3, 3] + T_task_camera[:3, 3]
            assert feats["distance"][0, 0] == pytest.approx(env.problem.task.distance(tip)[0])
    finally:
        env.close()


def test_bad_actions_and_settings_are_refused(reach):
    reach.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        reach.step(np.array([np.nan, 0, 0, 0], dtype=np.float32))
    with pytest.raises(ValueError, match="action_space"):
        EnvConfig(action_space="torque")
    with pytest.raises(ValueError, match="max_step"):
        EnvConfig(max_step=-1.0)
    with pytest.raises(ValueError, match="control_hz"):
        control.ticks_per_action(33.0)
    with pytest.raises(ValueError, match="joint"):
        gym.make("DavinciSim/CameraTargeting-v0", action_space="cartesian")
    # The environment still runs after refusing.
    reach.step(np.zeros(4, dtype=np.float32))


def test_control_laws():
    assert control.ticks_per_action(50) == 20 and control.ticks_per_action(1000) == 1
    g0, delta = np.array([[0.0, 1.0, 2.0]]), np.array([[0.01, -0.02, 0.0]])
    np.testing.assert_allclose(control.ramp(g0, delta, 20, 20), g0 + delta)
    np.testing.assert_allclose(control.ramp(g0, delta, 5, 20), g0 + delta / 4)
    np.testing.assert_allclose(control.feedforward(delta, 20), delta / 0.02)
    lo, hi = np.array([-1.0, 0.0, 0.0]), np.array([1.0, 1.005, 3.0])
    d = control.cartesian_delta(np.array([[2.0, 1.0, -0.5]]), g0, 0.01, lo, hi)
    np.testing.assert_allclose(d, [[0.01, 0.005, -0.005]])  # clipped action, then the box
    np.testing.assert_allclose(control.jaw_angle(np.array([-1.0, 0.0, 1.0]), 0.0, 1.2),
                               [0.0, 0.6, 1.2])  # fmt: skip
    R = np.eye(3)[[1, 2, 0]]
    np.testing.assert_array_equal(control.orientation_features(R), [0, 0, 1, 1, 0, 0])


def test_image_observations_are_the_stereo_endoscope():
    env = gym.make("DavinciSim/Reach-v0", images=True, image_size=(64, 48),
                   render_mode="rgb_array").unwrapped  # fmt: skip
    try:
        check_env(env)  # (the render check included)
        obs, _ = env.reset(seed=0)
        assert obs["left"].shape == obs["right"].shape == (48, 64, 3)
        assert obs["left"].dtype == np.uint8 and obs["left"].std() > 5  # a scene, not blank
        assert not np.array_equal(obs["left"], obs["right"])  # two viewpoints
        np.testing.assert_array_equal(env.render(), obs["left"])
    finally:
        env.close()
