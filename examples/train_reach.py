"""Train a policy on ``DavinciSim/Reach-v0`` with Stable-Baselines3 (PPO) on the vector
environment, and plot its learning curve.

Needs the ``learn`` extra (``pip install -e '.[learn]'``: stable-baselines3, which brings
torch).

    python examples/train_reach.py --timesteps 300000 --envs 32 --out reach_run

PPO collects its rollouts from ``--envs`` environments stepped together on the batch
engine (:class:`~davinci_sim.envs.vector.DavinciVectorEnv`, reset in the same step as SB3
expects); observations and rewards are normalised (``VecNormalize``). Every ``--eval-every``
steps the deterministic policy runs ``--eval-episodes`` fresh episodes (fixed seeds, all at
once on another vector environment): the success rate (tool tip within 3 mm of the target
before the 2 s limit) and the mean return go to ``<out>/curve.json`` and ``<out>/curve.png``
with the wall time. ``--timesteps 256`` is the smoke run of the tests.

(Image observations and training in one process: torch loads triton, whose bundled LLVM
crashes a process where Mesa's llvmpipe, MuJoCo's EGL rendering without a GPU, is loaded;
render in the environments' processes, e.g. Ray workers, or import torch first.)
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from davinci_sim.envs import ENVIRONMENTS
from davinci_sim.envs.vector import DavinciVectorEnv

#: The observations the policy sees (the rest is for other tasks or for analysis).
KEYS = ("tip_position", "setpoint", "target", "target_offset", "joint_position")
ENV_ID = "DavinciSim/Reach-v0"


def make_vector(n: int) -> DavinciVectorEnv:
    return DavinciVectorEnv(n, autoreset_mode="SameStep", **ENVIRONMENTS[ENV_ID])


def sb3_vec_env(env: DavinciVectorEnv, seed: int = 0):
    """``env`` as a Stable-Baselines3 ``VecEnv`` (its API: lists of infos,
    ``terminal_observation``, ``TimeLimit.truncated``), observing :data:`KEYS`."""
    from gymnasium import spaces
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv

    obs_space = spaces.Dict({k: env.single_observation_space[k] for k in KEYS})

    class Adapter(VecEnv):
        def __init__(self) -> None:
            super().__init__(env.num_envs, obs_space, env.single_action_space)
            self._seed = seed
            self._actions = None

        def reset(self):
            obs, _ = env.reset(seed=self._seed)
            self._seed += env.num_envs  # (another reset: other episodes)
            return {k: obs[k] for k in KEYS}

        def step_async(self, actions) -> None:
            self._actions = actions

        def step_wait(self):
            obs, reward, terminated, truncated, info = env.step(self._actions)
            done = terminated | truncated
            infos = [{} for _ in range(self.num_envs)]
            for i in np.flatnonzero(done):
                final = info["final_obs"][i]
                infos[i]["terminal_observation"] = {k: final[k] for k in KEYS}
                infos[i]["TimeLimit.truncated"] = bool(truncated[i])
                infos[i]["is_success"] = bool(info["is_success"][i])
            return {k: obs[k] for k in KEYS}, reward.astype(np.float32), done, infos

        def close(self) -> None:
            env.close()

        def get_attr(self, name, indices=None):
            return [getattr(env, name)] * len(self._get_indices(indices))

        def set_attr(self, name, value, indices=None) -> None:
            setattr(env, name, value)

        def env_method(self, name, *args, indices=None, **kwargs):
            return [getattr(env, name)(*args, **kwargs)] * len(self._get_indices(indices))

        def env_is_wrapped(self, wrapper_class, indices=None):
            return [False] * len(self._get_indices(indices))

    return Adapter()


def evaluate(model, normalize, env: DavinciVectorEnv, seed: int = 10_000):
    """``(success rate, mean return)`` of the deterministic policy over one episode of
    each of ``env``'s rows (seeds ``seed + i``)."""
    obs, _ = env.reset(seed=seed)
    n = env.num_envs
    done = np.zeros(n, dtype=bool)
    success = np.zeros(n, dtype=bool)
    total = np.zeros(n)
    while not done.all():
        action, _ = model.predict(normalize({k: obs[k] for k in KEYS}), deterministic=True)
        obs, reward, terminated, truncated, info = env.step(action)
        total += np.where(done, 0.0, reward)
        success |= ~done & info["is_success"]
        done |= terminated | truncated
    return float(success.mean()), float(total.mean())


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=300_000)
    parser.add_argument("--envs", type=int, default=32)
    parser.add_argument("--eval-every", type=int, default=20_000)
    parser.add_argument("--eval-episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("reach_run"))
    parser.add_argument("--plot", type=Path, default=None, help="also write the curve here")
    args = parser.parse_args(argv)

    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)  # (small networks: threads only contend on a shared machine)
    args.out.mkdir(parents=True, exist_ok=True)
    train = VecNormalize(sb3_vec_env(make_vector(args.envs), args.seed), gamma=0.98)
    eval_env = make_vector(args.eval_episodes)
    n_steps = max(8, min(128, args.timesteps // args.envs))
    model = PPO(
        "MultiInputPolicy", train, n_steps=n_steps, batch_size=min(256, n_steps * args.envs),
        n_epochs=10, gamma=0.98, learning_rate=3e-4, seed=args.seed, verbose=0, device="cpu",
    )  # fmt: skip
    curve: list[dict] = []
    wall0 = time.perf_counter()
    next_eval = [args.eval_every]

    def record() -> None:
        rate, ret = evaluate(model, train.normalize_obs, eval_env)
        wall = time.perf_counter() - wall0
        curve.append({"timesteps": model.num_timesteps, "success_rate": rate,
                      "mean_return": ret, "wall_s": wall})  # fmt: skip
        print(f"{model.num_timesteps:8d} steps  success {rate:5.0%}  return {ret:8.2f}"
              f"  {wall:6.0f} s", flush=True)  # fmt: skip

    class Evaluate(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps >= next_eval[0]:
                next_eval[0] += args.eval_every
                train.training = False
                record()
                train.training = True
            return True

    record()  # the untrained policy
    model.learn(total_timesteps=args.timesteps, callback=Evaluate())
    train.training = False
    record()
    wall = time.perf_counter() - wall0
    result = {
        "env": ENV_ID, "algorithm": "PPO (Stable-Baselines3)", "envs": args.envs,
        "timesteps": model.num_timesteps, "final_success_rate": curve[-1]["success_rate"],
        "final_mean_return": curve[-1]["mean_return"], "wall_s": wall,
        "simulated_s": model.num_timesteps * 0.02, "curve": curve,
    }  # fmt: skip
    (args.out / "curve.json").write_text(json.dumps(result, indent=2))
    _plot(result, [args.out / "curve.png", *([args.plot] if args.plot else [])])
    model.save(args.out / "ppo_reach")
    train.save(str(args.out / "vecnormalize.pkl"))
    train.close()
    eval_env.close()
    print(f"success rate {result['final_success_rate']:.0%} after {model.num_timesteps} "
          f"steps, {wall:.0f} s wall")  # fmt: skip
    return result


def _plot(result: dict, paths) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curve = result["curve"]
    x = [c["timesteps"] for c in curve]
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(x, [100 * c["success_rate"] for c in curve], "o-")
    ax.set_xlabel("environment steps (50 Hz actions)")
    ax.set_ylabel("success rate, %")
    ax.set_ylim(-5, 105)
    minutes = result["wall_s"] / 60
    ax.set_title(f"PPO on {ENV_ID}, {result['envs']} envs: {minutes:.0f} min, 2 shared cores")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    for p in paths:
        fig.savefig(p, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
