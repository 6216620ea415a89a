"""Recording environments' rollouts to MCAP: :class:`RecordEpisodes` wraps a single
environment, :class:`RecordVectorEpisodes` a vector environment (one file per row).

Every episode goes through an :class:`~davinci_sim.records.episodes.EpisodeRecorder`: one
``davinci_sim.Step`` message on ``/episode/step`` per reset and per step (observation,
action, reward, termination, truncation, info), so ``davinci-sim replay FILE --to-dataset``
(:func:`~davinci_sim.records.dataset.to_dataset`) turns the files into the HDF5 layout, one
demo per episode. Times: a step's log time is its episode's simulated time (steps over
``control_hz``), episodes following each other on the file's time line.

For Foxglove's 3-D panel (``snapshots=True``, the default): the single environment adds its
simulation's snapshot at every reset and step (the arms' joint states, poses and ``/tf``,
the model's ``/sim/qpos``: what a session's recording writes per tick); a vector row adds
its tool tip's pose (``/<PSM>/measured_cp``, ``foxglove.PoseInFrame``, and ``/tf``: the
tip's frame in the camera's, from the observation) and the row's ``/sim/qpos`` (the whole
model's joint positions, m and rad; not for a ``SAME_STEP`` episode's last step, whose state
the reset replaced).

Vector rows' episode boundaries follow the environment's autoreset mode: ``NEXT_STEP`` — the
step after a row ended returns the next episode's first observation (recorded as that
episode's reset; the step's action was ignored, so it is not recorded); ``SAME_STEP`` — the
ending step's last observation is ``info["final_obs"]`` (recorded as the step) and the
returned one is the next episode's first (recorded as its reset).

A killed process leaves each file readable up to its last chunk (the recorder's property).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorWrapper

from davinci_sim.records.episodes import EpisodeRecorder
from davinci_sim.records.mcap_schemas import numbers, pose_fields, stamp

#: The file name of a single environment's rollouts when given a directory.
SINGLE_FILE = "episodes.mcap"


def row_file(i: int) -> str:
    """The file name of vector row ``i`` when given a directory."""
    return f"env_{i:03d}.mcap"


def _metadata(env) -> tuple[str, dict[str, Any], float]:
    """(id, keyword arguments, seconds per step) of ``env`` for the file's metadata."""
    spec = getattr(env, "spec", None)
    env_id = spec.id if spec is not None else type(env.unwrapped).__name__
    config = getattr(env.unwrapped, "config", None)
    kwargs = dataclasses.asdict(config) if dataclasses.is_dataclass(config) else {}
    hz = getattr(config, "control_hz", None) or env.metadata.get("render_fps") or 100.0
    return env_id, kwargs, 1.0 / float(hz)


def _open(path: Path, env, **extra) -> EpisodeRecorder:
    env_id, kwargs, dt = _metadata(env)
    path.parent.mkdir(parents=True, exist_ok=True)
    return EpisodeRecorder(path, env_id=env_id, dt=dt, extra={"env_kwargs": kwargs, **extra})


class RecordEpisodes(gym.Wrapper):
    """Records every episode of ``env`` to one MCAP file (see the module docstring).

    Args:
        env: the environment (a :class:`~davinci_sim.envs.DavinciEnv` for the snapshots;
            any Gymnasium environment for the steps).
        path: the file (``*.mcap``) or a directory (the file :data:`SINGLE_FILE` in it).
        snapshots: add the simulation's snapshot at each reset and step (Foxglove's panels).
    """

    def __init__(self, env: gym.Env, path: str | Path, *, snapshots: bool = True) -> None:
        super().__init__(env)
        path = Path(path)
        self.path = path if path.suffix == ".mcap" else path / SINGLE_FILE
        self.recorder = _open(self.path, env)
        self._sim = getattr(env.unwrapped, "sim", None) if snapshots else None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self.recorder.reset(obs, info)
        self._snapshot()
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.recorder.step(obs, action, reward, terminated, truncated, info)
        self._snapshot()
        return obs, reward, terminated, truncated, info

    def _snapshot(self) -> None:
        if self._sim is None:
            return
        from davinci_sim.sim.handle import take_snapshot

        rec = self.recorder
        # (the episode's time, as the step's: the simulation's own clock runs on over resets)
        snap = take_snapshot(self._sim)
        extras = {**snap.extras, "qpos": self._sim.data.qpos.copy()}  # (/sim/qpos)
        snap = dataclasses.replace(snap, time=rec.steps * rec.dt, extras=extras)
        rec.snapshot(snap)

    def close(self) -> None:
        try:
            self.recorder.close()
        finally:
            super().close()


def _row_info(info: dict, i: int) -> dict:
    """Row ``i``'s part of a vector environment's ``info`` (the keys its masks mark)."""
    out = {}
    for k, v in info.items():
        if k.startswith("_") or k in ("final_obs", "final_info"):
            continue
        mask = info.get(f"_{k}")
        if mask is not None and not mask[i]:
            continue
        out[k] = v[i] if isinstance(v, np.ndarray) else v
    return out


def _row(obs: dict | np.ndarray, i: int):
    if isinstance(obs, dict):
        return {k: v[i] for k, v in obs.items()}
    return obs[i]


class RecordVectorEpisodes(VectorWrapper):
    """Records each row of a vector environment to its own MCAP file (see the module
    docstring).

    Args:
        env: the vector environment (``NEXT_STEP`` or ``SAME_STEP`` autoreset; a
            :class:`~davinci_sim.envs.vector.DavinciVectorEnv` for the tip poses).
        directory: the files :func:`row_file` ``(i)`` go there.
        snapshots: add each row's tip pose, ``/tf`` and ``/sim/qpos`` at each step.

    Raises:
        ValueError: for an autoreset mode other than those two (``DISABLED``).
    """

    def __init__(self, env, directory: str | Path, *, snapshots: bool = True) -> None:
        super().__init__(env)
        mode = AutoresetMode(env.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP))
        if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            raise ValueError(f"recording needs NEXT_STEP or SAME_STEP autoreset, not {mode}")
        self.mode = mode
        self.directory = Path(directory)
        self.paths = [self.directory / row_file(i) for i in range(env.num_envs)]
        self.recorders = []
        try:
            for i, p in enumerate(self.paths):
                self.recorders.append(_open(p, env, row=i, autoreset_mode=mode.value))
        except BaseException:
            for r in self.recorders:
                r.close()
            raise
        inner = env.unwrapped
        self._poses = snapshots and hasattr(inner, "Q") and hasattr(inner, "_start")
        self._poses = self._poses and "tip_orientation" in env.single_observation_space.spaces
        if self._poses:
            start = inner._start
            psm = start.sim.arms[start.psm]
            self._arm, self._frame = start.psm, psm.base_frame()[1]
        self._pending = np.zeros(env.num_envs, dtype=bool)

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        for i, rec in enumerate(self.recorders):
            rec.reset(_row(obs, i), _row_info(info, i))
            self._pose(i, _row(obs, i))
        self._pending[:] = False
        return obs, info

    def step(self, actions):
        obs, reward, terminated, truncated, info = self.env.step(actions)
        ended = np.asarray(terminated) | np.asarray(truncated)
        for i, rec in enumerate(self.recorders):
            now = _row(obs, i)
            if self.mode == AutoresetMode.NEXT_STEP and self._pending[i]:
                rec.reset(now)  # (the row reset; its action was ignored)
            elif self.mode == AutoresetMode.SAME_STEP and ended[i]:
                last = info["final_obs"][i]
                row_info = _row_info(info["final_info"], i)
                rec.step(last, actions[i], reward[i], terminated[i], truncated[i], row_info)
                self._pose(i, last, qpos=False)  # (the row's state is the new episode's)
                rec.reset(now)
            else:
                row_info = _row_info(info, i)
                rec.step(now, actions[i], reward[i], terminated[i], truncated[i], row_info)
            self._pose(i, now)
        self._pending = ended & (self.mode == AutoresetMode.NEXT_STEP)
        return obs, reward, terminated, truncated, info

    def _pose(self, i: int, obs: dict, qpos: bool = True) -> None:
        """Row ``i``'s tip pose (from its observation ``obs``), ``/tf`` and (``qpos``) the
        row's joint positions, at the recorder's time."""
        if not self._poses:
            return
        inner, rec = self.env.unwrapped, self.recorders[i]
        c = np.asarray(obs["tip_orientation"], dtype=float)
        T = np.eye(4)
        T[:3, 0], T[:3, 1], T[:3, 2] = c[:3], c[3:], np.cross(c[:3], c[3:])
        T[:3, 3] = obs["tip_position"]
        p, q = pose_fields(T)
        rec.message(
            f"/{self._arm}/measured_cp",
            "foxglove.PoseInFrame",
            {"frame_id": self._frame, "pose": {"position": p, "orientation": q}},
        )
        transform = {"timestamp": stamp(rec.now), "parent_frame_id": self._frame,
                     "child_frame_id": self._arm, "translation": p, "rotation": q}  # fmt: skip
        rec.message("/tf", "foxglove.FrameTransforms", {"transforms": [transform]})
        if qpos:
            tick = int(round(inner.time[i] / inner.dt))
            rec.message(
                "/sim/qpos", "davinci_sim.Qpos", {"tick": tick, "qpos": numbers(inner.Q[i])}
            )

    def close(self, **kwargs) -> None:
        try:
            for r in self.recorders:
                r.close()
        finally:
            self.env.close(**kwargs)
