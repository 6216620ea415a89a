"""Spread Reach environments over Ray workers and roll out random actions.

    python examples/ray_rollouts.py --workers 2 --envs-per-worker 64 --steps 50

On one machine Ray starts a local instance with a worker process per core; on a cluster,
start Ray there (``ray start --head`` / ``ray start --address=...``) and pass
``--address auto``: the workers then run on the cluster's machines. Each worker holds a
:class:`~davinci_sim.envs.vector.DavinciVectorEnv` of its rows; row i of the whole is the
same environment as row i of one vector environment with the same seed
(``tests/envs/test_ray_envs.py``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--envs-per-worker", type=int, default=64)
    parser.add_argument("--steps", type=int, default=50)
    parser.add_argument("--address", default=None, help="a Ray cluster's address, or 'auto'")
    args = parser.parse_args(argv)

    import ray

    from davinci_sim.envs.ray_envs import RayVectorEnv

    ray.init(address=args.address, include_dashboard=False, log_to_driver=False)
    try:
        env = RayVectorEnv("DavinciSim/Reach-v0", args.workers, args.envs_per_worker)
        env.reset(seed=0)
        rng = np.random.default_rng(0)
        successes, t0 = 0, time.perf_counter()
        for _ in range(args.steps):
            actions = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
            _, _, terminated, _, info = env.step(actions)
            successes += int(np.sum(terminated & info["is_success"]))
        wall = time.perf_counter() - t0
        steps = args.steps * env.num_envs
        print(f"{env.num_envs} environments on {args.workers} workers: {steps / wall:.0f} "
              f"steps/s, {steps * 0.02 / wall:.1f} simulated s per s; random successes: "
              f"{successes}")  # fmt: skip
        env.close()
    finally:
        ray.shutdown()


if __name__ == "__main__":
    main()
