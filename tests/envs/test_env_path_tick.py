"""The path-following environment runs its control periods compiled with the ticks' samples
kept (``sim/live_period.py``'s records) and samples its task from them by the compiled tick of
one path trial (``tasks/live_path.py``): an episode gives the same observations, rewards,
infos, task state and metrics, bit for bit, as the Python path (each tick in Python, then
``TaskProblem.sample`` and ``advance``)."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from bits import assert_same_bits

gym = pytest.importorskip("gymnasium")

import davinci_sim.envs  # noqa: E402,F401 (registers the ids)
from davinci_sim.envs.base import DavinciEnv  # noqa: E402
from davinci_sim.tasks import Phase, live_path, path_row  # noqa: E402

pytestmark = pytest.mark.skipif(not path_row.COMPILED, reason="numba is off: no compiled tick")


def _episode(env, actions) -> list:
    """Each step's outcome and the task's state and metrics after it."""
    env.reset(seed=5)
    problem = env.problem
    out = []
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        out.append((obs, reward, terminated, truncated, info,
                    copy.deepcopy(problem.state), problem.metrics.get_state()))  # fmt: skip
        if terminated or truncated:
            break
    return out


def test_an_episode_is_the_python_paths_bit_for_bit(monkeypatch):
    rng = np.random.default_rng(2)
    actions = [rng.uniform(-1.0, 1.0, (4,)) for _ in range(150)]
    calls, recorded, in_turn = [], [], []  # (samples the compiled tick took; in turn)
    tick, ticks = live_path.LivePathTick.tick, live_path.LivePathTick.ticks
    monkeypatch.setattr(
        live_path.LivePathTick,
        "tick",
        lambda self, *a: (took := tick(self, *a)) and calls.append(1) or took,
    )
    monkeypatch.setattr(live_path.LivePathTick, "ticks",
                        lambda self, *a: (took := ticks(self, *a))
                        and (calls.extend([1] * len(a[3])) or in_turn.append(len(a[3])))
                        or took)  # fmt: skip
    sample_recorded = DavinciEnv._sample_recorded
    monkeypatch.setattr(DavinciEnv, "_sample_recorded",
                        lambda self, task, s, ticks: recorded.append(len(ticks))
                        or sample_recorded(self, task, s, ticks))  # fmt: skip
    episodes = []
    for compiled in (True, False):  # (a new environment each: the same start, the same clock)
        monkeypatch.setattr(live_path, "ENABLED", compiled)
        env = gym.make("DavinciSim/PathFollow-v0", max_episode_steps=150).unwrapped
        try:
            assert env.action_space.shape == (4,)
            assert env._period is not None and env._period.can_record(True)
            if not compiled:
                env._period = None  # (every tick in Python)
            episodes.append(_episode(env, actions))
            assert env.problem._tick is not None  # (one row of the path kind: it applies)
        finally:
            env.close()
        if compiled:
            assert len(calls) > 1000  # (every tick of the episode)
            assert sum(recorded) > 0.8 * len(calls)  # (most from the compiled periods' records)
            assert sum(in_turn) > 0.8 * len(calls)  # (most in one compiled call a period)
    compiled, python = episodes
    assert len(compiled) == len(python) > 20
    assert {int(step[5].phase[0]) for step in compiled} >= {Phase.READY, Phase.RUNNING}
    for k, (x, y) in enumerate(zip(compiled, python, strict=True)):
        assert_same_bits(x, y, f"step {k}")
