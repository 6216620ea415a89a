"""Environments spread over Ray workers: one vector environment of many rows whose rows live
in Ray actors, each a :class:`~davinci_sim.envs.vector.DavinciVectorEnv` of its own rows,
on this machine's cores or a Ray cluster's machines.

    import ray
    from davinci_sim.envs.ray_envs import RayVectorEnv

    ray.init()                       # or ray.init(address="auto") on a cluster
    env = RayVectorEnv("DavinciSim/Reach-v0", workers=4, envs_per_worker=64)
    obs, info = env.reset(seed=0)    # row i is the environment seeded 0 + i
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

It is a ``gymnasium.vector.VectorEnv`` of ``workers × envs_per_worker`` rows: a step sends
each actor its rows' actions and gathers the results (all actors step at once); row i of
the whole is row ``i mod envs_per_worker`` of actor ``i // envs_per_worker``, seeded so that
it is the same environment as row i of one ``DavinciVectorEnv`` (``tests/envs`` checks it).
Autoreset as the actors' (``NEXT_STEP`` by default). Needs Ray (``pip install
'davinci-sim[ray]'``).
"""

from __future__ import annotations

import numpy as np
from gymnasium.vector import VectorEnv
from gymnasium.vector.utils import batch_space

from davinci_sim.envs import ENVIRONMENTS, VECTOR_IDS


class _Worker:
    """A Ray actor's environment (built in the actor's process)."""

    def __init__(self, env_id: str, n: int, kwargs: dict) -> None:
        from davinci_sim.envs.vector import DavinciVectorEnv

        self.env = DavinciVectorEnv(n, **{**ENVIRONMENTS[env_id], **kwargs})

    def spaces(self):
        return self.env.single_observation_space, self.env.single_action_space, self.env.metadata

    def reset(self, seed):
        return self.env.reset(seed=seed)

    def step(self, actions):
        return self.env.step(actions)

    def close(self) -> None:
        self.env.close()


class RayVectorEnv(VectorEnv):
    """``workers`` Ray actors of ``envs_per_worker`` rows each (see the module docstring);
    ``**kwargs``: the environments' settings (:class:`~davinci_sim.envs.setup.EnvConfig`)."""

    def __init__(self, env_id: str, workers: int = 2, envs_per_worker: int = 1, **kwargs) -> None:
        try:
            import ray
        except ImportError as e:
            raise ImportError("RayVectorEnv needs Ray: pip install 'davinci-sim[ray]'") from e
        if env_id not in VECTOR_IDS:
            raise ValueError(f"RayVectorEnv runs {VECTOR_IDS}, not {env_id!r}")
        if not (isinstance(workers, int) and workers >= 1):
            raise ValueError(f"workers must be an int >= 1, got {workers!r}")
        if not (isinstance(envs_per_worker, int) and envs_per_worker >= 1):
            raise ValueError(f"envs_per_worker must be an int >= 1, got {envs_per_worker!r}")
        self._ray = ray
        actor = ray.remote(num_cpus=1)(_Worker)
        self.k = envs_per_worker
        self.workers = [actor.remote(env_id, envs_per_worker, kwargs) for _ in range(workers)]
        self.num_envs = workers * envs_per_worker
        obs_space, act_space, metadata = ray.get(self.workers[0].spaces.remote())
        self.single_observation_space, self.single_action_space = obs_space, act_space
        self.observation_space = batch_space(obs_space, self.num_envs)
        self.action_space = batch_space(act_space, self.num_envs)
        self.metadata = dict(metadata)
        self.render_mode = None

    def reset(self, *, seed=None, options=None):
        seeds = [None if seed is None else seed + w * self.k for w in range(len(self.workers))]
        parts = self._ray.get([w.reset.remote(s) for w, s in zip(self.workers, seeds, strict=True)])
        return _join([p[0] for p in parts]), _join([p[1] for p in parts])

    def step(self, actions):
        a = np.asarray(actions).reshape(self.action_space.shape)
        k = self.k
        refs = [w.step.remote(a[i * k : (i + 1) * k]) for i, w in enumerate(self.workers)]
        parts = self._ray.get(refs)
        obs, reward, terminated, truncated, info = zip(*parts, strict=True)
        return (
            _join(obs), np.concatenate(reward), np.concatenate(terminated),
            np.concatenate(truncated), _join(info),
        )  # fmt: skip

    def close_extras(self, **kwargs) -> None:
        self._ray.get([w.close.remote() for w in self.workers])
        for w in self.workers:
            self._ray.kill(w)


def _join(parts: list[dict]) -> dict:
    """The actors' dicts of row arrays as one (a key some actors lack: masked out there)."""
    keys = list(dict.fromkeys(k for p in parts for k in p))
    out = {}
    for key in keys:
        if key.startswith("_"):
            continue
        have = [p for p in parts if key in p]
        if len(have) == len(parts):
            out[key] = np.concatenate([p[key] for p in parts])
            if f"_{key}" in keys:
                out[f"_{key}"] = np.concatenate([p[f"_{key}"] for p in parts])
        else:
            template = have[0][key]
            rows = [
                p[key] if key in p else np.zeros_like(template, shape=(len(_any(p)),))
                for p in parts
            ]
            out[key] = np.concatenate(rows)
            out[f"_{key}"] = np.concatenate(
                [p.get(f"_{key}", np.zeros(len(_any(p)), dtype=bool)) for p in parts]
            )
    return out


def _any(part: dict) -> np.ndarray:
    """A row array of ``part`` (to know its number of rows)."""
    for key, value in part.items():
        if key.startswith("_"):
            return value
    return next(iter(part.values()))
