"""Recording episodes (an environment's rollouts, a study's trials) to MCAP.

:class:`EpisodeRecorder` is what a Gymnasium wrapper calls (``davinci_sim.envs`` wraps an
environment with it): :meth:`~EpisodeRecorder.reset` with the first observation of an
episode, :meth:`~EpisodeRecorder.step` with each step's observation, action, reward,
termination, truncation and info. Each is one ``davinci_sim.Step`` message on
``/episode/step`` (observation and action as JSON: a ``Dict`` observation as an object of
lists, arrays as nested lists); :meth:`~EpisodeRecorder.snapshot` adds a simulator
snapshot's topics (joint states, poses, ``/tf``, ``/sim/qpos``: what Foxglove's panels draw)
at the same time. A step's log time is the episode's simulated time when given (``t``), else
the step count times ``dt``; episodes follow each other on one time line (each starts where
the previous ended), so Foxglove plays a file of many episodes in order.

The file starts with the metadata ``davinci_sim`` (kind ``episodes``, the environment's id
and its keyword arguments, versions, ``extra``) and may attach a system description and a
task file as a session's recording does (:func:`~davinci_sim.records.recording.write_header`).
The dataset converter (:mod:`~davinci_sim.records.dataset`) reads the steps back into arrays.

Wrapping an environment (a sketch of what ``davinci_sim.envs`` provides)::

    rec = EpisodeRecorder("rollouts.mcap", env_id="DavinciSim/Reach-v0", dt=env.dt)
    obs, info = env.reset(seed=0); rec.reset(obs, info)
    obs, r, term, trunc, info = env.step(a); rec.step(obs, a, r, term, trunc, info)
    rec.close()
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from davinci_sim.records.jsonvalue import plain
from davinci_sim.records.mcap_file import CHUNK_SIZE, McapWriter
from davinci_sim.records.mcap_schemas import stamp, time_ns
from davinci_sim.records.messages import write_snapshot
from davinci_sim.records.recording import write_header


class EpisodeRecorder:
    """Episodes to one MCAP file; see the module docstring.

    Args:
        path: the file.
        env_id: the environment's id (metadata).
        dt: seconds per step when :meth:`step` is given no time.
        description: a :class:`~davinci_sim.system.SystemDescription` to attach (optional).
        extra: more metadata (JSON-able values).
        chunk_size: bytes per chunk (a killed process loses at most the chunk in progress,
            or the last second).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        env_id: str = "",
        dt: float = 0.01,
        description=None,
        extra: Mapping[str, Any] | None = None,
        chunk_size: int = CHUNK_SIZE,
    ) -> None:
        self.path = Path(path)
        self.dt = float(dt)
        self.writer = McapWriter(self.path, chunk_size=chunk_size)
        """The file's writer (attachments, more topics)."""
        write_header(
            self.writer,
            "episodes",
            description=description,
            extra={"env_id": env_id, "dt": self.dt, **dict(extra or {})},
        )
        self.episode = -1
        """The current episode's index (-1 before the first reset)."""
        self.steps = 0
        """Steps of the current episode."""
        self.last_observation: Any = None
        self.last_action: Any = None
        self._t0 = 0.0  # this episode's start on the file's time line, s
        self._t = 0.0  # the last message's time, s

    def _time(self, t: float | None) -> float:
        if t is None:
            t = self.steps * self.dt
        self._t = max(self._t, self._t0 + float(t))
        return self._t

    def reset(
        self, observation: Any, info: Mapping | None = None, *, t: float | None = None
    ) -> int:
        """Start an episode with its first observation; returns its index."""
        self.episode += 1
        self._t0 = self._t + (self.dt if self.episode else 0.0)
        self.steps = 0
        tt = self._time(0.0 if t is None else t)
        self._write(tt, observation, None, None, False, False, info)
        return self.episode

    def step(
        self,
        observation: Any,
        action: Any,
        reward: float | None,
        terminated: bool,
        truncated: bool,
        info: Mapping | None = None,
        *,
        t: float | None = None,
    ) -> None:
        """One step: the observation after ``action``, its reward, whether it ended.

        Raises:
            RuntimeError: before :meth:`reset`.
        """
        if self.episode < 0:
            raise RuntimeError("EpisodeRecorder.step before reset")
        self.steps += 1
        self._write(self._time(t), observation, action, reward, terminated, truncated, info)

    def snapshot(self, snap) -> None:
        """A simulator :class:`~davinci_sim.sim.handle.Snapshot`'s topics at its time in the
        current episode (see :func:`~davinci_sim.records.recording.write_snapshot`)."""
        shifted = type(snap)(self._t0 + snap.time, snap.tick, snap.arms, snap.extras)
        write_snapshot(self.writer, shifted)

    @property
    def now(self) -> float:
        """The last message's time on the file's time line, s."""
        return self._t

    def message(self, topic: str, schema: str, body: Mapping[str, Any]) -> None:
        """Another message at :attr:`now` (its ``timestamp`` added), e.g. a pose for
        Foxglove's 3-D panel."""
        self.writer.write(topic, schema, time_ns(self._t), {"timestamp": stamp(self._t), **body})

    def _write(self, t, observation, action, reward, terminated, truncated, info) -> None:
        self.last_observation, self.last_action = observation, action
        r = None if reward is None else float(reward)
        self.writer.write(
            "/episode/step",
            "davinci_sim.Step",
            time_ns(t),
            {
                "timestamp": stamp(t),
                "episode": self.episode,
                "step": self.steps,
                "observation": plain(observation),
                "action": plain(action),
                "reward": r if r is None or r == r else None,
                "terminated": bool(terminated),
                "truncated": bool(truncated),
                "info": plain(dict(info or {})),
            },
        )

    def close(self) -> None:
        """Finish the file (summary and footer)."""
        self.writer.close()

    def __enter__(self) -> EpisodeRecorder:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
