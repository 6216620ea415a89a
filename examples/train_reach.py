"""Train a policy on ``DavinciSim/Reach-v0`` with Stable-Baselines3 (SAC) and plot its curve.

Needs the ``learn`` extra (``pip install -e '.[learn]'``: stable-baselines3 and torch).

    python examples/train_reach.py --timesteps 30000 --out reach_run

Every ``--eval-every`` steps the deterministic policy runs ``--eval-episodes`` episodes on
a separate environment (fixed seeds); the success rate (tip within 3 mm of the target
before the 2 s time limit) and the mean return go to ``<out>/curve.json`` and
``<out>/curve.png`` with the wall time of the run. ``--timesteps 300`` is the smoke run the
tests do.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import davinci_sim.envs  # noqa: F401 (registers the ids)

#: The observations the policy sees (the rest is for other tasks or for analysis).
KEYS = ("tip_position", "setpoint", "target", "target_offset", "joint_position")


def make_env(seed: int = 0):
    import gymnasium as gym
    from gymnasium.wrappers import FilterObservation

    env = gym.make("DavinciSim/Reach-v0")
    return FilterObservation(env, list(KEYS))


def evaluate(model, env, episodes: int, seed: int = 10_000) -> tuple[float, float]:
    """``(success rate, mean return)`` of the deterministic policy over ``episodes``."""
    successes, returns = 0, []
    for k in range(episodes):
        obs, _ = env.reset(seed=seed + k)
        total, done, info = 0.0, False, {}
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = env.step(action)
            total += reward
            done = terminated or truncated
        successes += bool(info.get("is_success"))
        returns.append(total)
    return successes / episodes, float(np.mean(returns))


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=30_000)
    parser.add_argument("--eval-every", type=int, default=2_500)
    parser.add_argument("--eval-episodes", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("reach_run"))
    parser.add_argument("--plot", type=Path, default=None, help="also write the curve here")
    args = parser.parse_args(argv)

    import torch
    from stable_baselines3 import SAC

    torch.set_num_threads(1)  # (2 cores, shared: threads only contend)
    from stable_baselines3.common.callbacks import BaseCallback

    args.out.mkdir(parents=True, exist_ok=True)
    env, eval_env = make_env(), make_env()
    model = SAC(
        "MultiInputPolicy", env, seed=args.seed, learning_starts=min(1000, args.timesteps // 2),
        batch_size=256, gamma=0.95, verbose=0, device="cpu",
    )  # fmt: skip
    curve: list[dict] = []
    wall0 = time.perf_counter()

    class Evaluate(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps % args.eval_every == 0:
                rate, ret = evaluate(self.model, eval_env, args.eval_episodes)
                curve.append({"timesteps": self.num_timesteps, "success_rate": rate,
                              "mean_return": ret, "wall_s": time.perf_counter() - wall0})
                print(f"{self.num_timesteps:7d} steps  success {rate:5.0%}  return {ret:8.2f}"
                      f"  {time.perf_counter() - wall0:6.0f} s", flush=True)  # fmt: skip
            return True

    model.learn(total_timesteps=args.timesteps, callback=Evaluate())
    wall = time.perf_counter() - wall0
    rate, ret = evaluate(model, eval_env, args.eval_episodes)
    result = {
        "env": "DavinciSim/Reach-v0", "algorithm": "SAC", "timesteps": args.timesteps,
        "final_success_rate": rate, "final_mean_return": ret, "wall_s": wall,
        "simulated_s": args.timesteps / 50.0, "curve": curve,
    }  # fmt: skip
    (args.out / "curve.json").write_text(json.dumps(result, indent=2))
    _plot(result, [args.out / "curve.png", *([args.plot] if args.plot else [])])
    model.save(args.out / "sac_reach")
    env.close()
    eval_env.close()
    print(f"final success rate {rate:.0%} after {args.timesteps} steps, {wall:.0f} s wall")
    return result


def _plot(result: dict, paths) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curve = result["curve"]
    if not curve:
        return
    x = [c["timesteps"] for c in curve]
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(x, [100 * c["success_rate"] for c in curve], "o-")
    ax.set_xlabel("environment steps (50 Hz actions)")
    ax.set_ylabel("success rate, %")
    ax.set_ylim(-5, 105)
    ax.set_title(f"SAC on DavinciSim/Reach-v0 ({result['wall_s'] / 60:.0f} min on 2 CPU cores)")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    for p in paths:
        fig.savefig(p, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
