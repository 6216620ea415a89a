"""Learning environments: the exercises as Gymnasium (>= 1.0) environments, single and
vectorised on the study's batch laws.

Importing this package registers the ids (``gymnasium.make("DavinciSim/Reach-v0")``, or
``gymnasium.make("davinci_sim.envs:DavinciSim/Reach-v0")`` without importing it first):

* ``DavinciSim/Reach-v0`` — bring PSM1's tool tip to a random target (hello world);
* ``DavinciSim/PathFollow-v0`` — the seed's path-following task (``seed_path``);
* ``DavinciSim/PegTransfer-v0`` — peg transfer (``peg_transfer``; the actions move PSM1,
  PSM2 holds still);
* ``DavinciSim/CameraTargeting-v0`` — centre targets with the endoscope (the ECM, joint
  actions);
* ``DavinciSim/RingWalk-v0``, ``DavinciSim/NeedleTargeting-v0`` — the ring walk and needle
  targeting exercises;
* ``DavinciSim/NeedlePickup-v0``, ``DavinciSim/NeedleDrive-v0``,
  ``DavinciSim/RunningSuture-v0`` — needle pick-up and hand-off, needle driving through one
  pair of marks, the running suture through four: both PSMs moved and turned
  (:class:`InstrumentsEnv`).

* :class:`DavinciEnv` (base.py) — one environment on a live
  :class:`~davinci_sim.sim.simulation.Simulation`: actions, observations, reset and
  rewards documented there; settings :class:`EnvConfig` (setup.py).
* :class:`InstrumentsEnv` (instruments.py) — the same with several instruments moved and
  turned by the actions (``arms``, ``rotation``; any id with those keyword arguments).
* :class:`DavinciVectorEnv` (vector.py) — N environments stepped as arrays with the
  study's batch laws (Reach and path following), ``gymnasium.make_vec`` or
  :func:`make_vector`.
* :mod:`davinci_sim.envs.ray_envs` — environments spread over Ray workers.
* :class:`RecordEpisodes`, :class:`RecordVectorEpisodes` (recording.py) — wrappers writing
  every episode to MCAP (``replay --to-dataset`` turns the files into a dataset).
"""

from __future__ import annotations

import gymnasium as gym

from davinci_sim.envs.base import DavinciEnv
from davinci_sim.envs.instruments import InstrumentsEnv
from davinci_sim.envs.recording import RecordEpisodes, RecordVectorEpisodes
from davinci_sim.envs.setup import EnvConfig

#: id → the task file (None: Reach) and its defaults.
ENVIRONMENTS: dict[str, dict] = {
    "DavinciSim/Reach-v0": {"task": None, "max_episode_steps": 100},
    "DavinciSim/PathFollow-v0": {"task": "seed_path", "max_episode_steps": 500},
    "DavinciSim/PegTransfer-v0": {"task": "peg_transfer", "max_episode_steps": 1500},
    "DavinciSim/CameraTargeting-v0": {
        "task": "camera_targeting",
        "max_episode_steps": 1000,
        "action_space": "joint",
    },
    "DavinciSim/RingWalk-v0": {"task": "ring_walk", "max_episode_steps": 1500},
    "DavinciSim/NeedleTargeting-v0": {"task": "needle_targeting", "max_episode_steps": 1000},
    # (both hands, turning the wrists: the tasks' time limits at 50 actions/s)
    "DavinciSim/NeedlePickup-v0": {
        "task": "needle_pickup", "max_episode_steps": 6000, "arms": ("PSM1", "PSM2"),
        "rotation": True,
    },
    "DavinciSim/NeedleDrive-v0": {
        "task": "needle_drive", "max_episode_steps": 9000, "arms": ("PSM1", "PSM2"),
        "rotation": True,
    },
    "DavinciSim/RunningSuture-v0": {
        "task": "running_suture", "max_episode_steps": 30000, "arms": ("PSM1", "PSM2"),
        "rotation": True,
    },
}  # fmt: skip
#: The ids the vector environment runs (PSM tasks whose samples need no scene objects).
VECTOR_IDS = ("DavinciSim/Reach-v0", "DavinciSim/PathFollow-v0")


def _register() -> None:
    for env_id, kwargs in ENVIRONMENTS.items():
        if env_id in gym.registry:
            continue
        vector = None
        if env_id in VECTOR_IDS:
            vector = "davinci_sim.envs.vector:DavinciVectorEnv"
        gym.register(
            env_id,
            entry_point="davinci_sim.envs:make_env",
            vector_entry_point=vector,
            kwargs=dict(kwargs),
            # (no TimeLimit wrapper: the environment truncates at its max_episode_steps, the
            # same way as the vector environment)
            disable_env_checker=True,
        )


_register()


def make_env(render_mode: str | None = None, **kwargs) -> DavinciEnv:
    """One environment of ``kwargs`` (:class:`EnvConfig`): an :class:`InstrumentsEnv` when
    they set ``arms`` or ``rotation``, else a :class:`DavinciEnv` (the registered ids'
    entry point)."""
    if kwargs.get("arms") is not None or kwargs.get("rotation"):
        return InstrumentsEnv(render_mode, **kwargs)
    return DavinciEnv(render_mode, **kwargs)


def make_vector(env_id: str, num_envs: int, **kwargs):
    """N environments of ``env_id`` on the batch engine (:class:`DavinciVectorEnv`)."""
    from davinci_sim.envs.vector import DavinciVectorEnv

    if env_id not in VECTOR_IDS:
        raise ValueError(f"the vector environment runs {VECTOR_IDS}, not {env_id!r}")
    return DavinciVectorEnv(num_envs=num_envs, **{**ENVIRONMENTS[env_id], **kwargs})


__all__ = [
    "DavinciEnv",
    "ENVIRONMENTS",
    "EnvConfig",
    "InstrumentsEnv",
    "RecordEpisodes",
    "RecordVectorEpisodes",
    "VECTOR_IDS",
    "make_env",
    "make_vector",
]
