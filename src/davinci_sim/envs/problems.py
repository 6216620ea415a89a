"""What an environment asks of the agent: its task features, rewards and termination, for
n rows at once (one implementation for the single and the vector environments).

* :class:`ReachProblem` — the hello world: bring the tool tip to a random target.
* :class:`TaskProblem` — an exercise of :mod:`davinci_sim.tasks` (any kind): every tick a
  :class:`~davinci_sim.tasks.Sample` goes through the task's own state machine and metrics
  (:func:`~davinci_sim.tasks.advance`, as the live session and the study do); the episode
  terminates when the task's phase reaches FINISHED; the reward's terms are the exercise's
  per-sample quantities (its ``distance`` observation, the path's progress or needle
  driving's pairs passed) and its finish. Features: ``phase``, ``distance``; path following
  ``progress`` and ``next_point``; camera targeting ``target``; needle driving
  ``entry_mark`` and ``exit_mark``, the next pair's marks (the last pair's once all are
  passed).

Rewards are returned as a sum with each term in ``info`` (``reward_<term>``), as
Gymnasium's MuJoCo environments do. Positions in features are in the camera frame, m.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from davinci_sim.geometry.se3 import invert_transform
from davinci_sim.haptics.path_query import closest_point
from davinci_sim.model.cameras import in_left_image
from davinci_sim.tasks import PathTask, Phase, Sample, advance
from davinci_sim.tasks.live_path import LivePathTick

_ONE = np.ones(1, dtype=bool)

#: Distances in rewards are in cm: 1 cm off costs 1 per action.
REWARD_LENGTH = 0.01
#: Reward of a success (Reach) or of the exercise's finish.
SUCCESS_REWARD = 10.0
#: Path following: the whole path's progress is worth this much.
PROGRESS_REWARD = 20.0
#: Path following: the next-point feature looks this far ahead along the path, m.
LOOKAHEAD = 0.005
_BIG = 10.0  # bounds of positions (m) in the observation spaces: the scene is much smaller


def _box(*shape: int, low: float = -_BIG, high: float = _BIG) -> spaces.Box:
    return spaces.Box(low, high, shape=shape, dtype=np.float64)


def _transform(T: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Points (n, 3) through T (4, 4) or (n, 4, 4), elementwise per row."""
    if T.ndim == 2:
        return np.einsum("ij,nj->ni", T[:3, :3], p) + T[:3, 3]
    return np.einsum("nij,nj->ni", T[:, :3, :3], p) + T[:, :3, 3]


class ReachProblem:
    """Bring the tool tip within ``tolerance`` of a target drawn uniformly in a box of
    half-width ``radius`` around the start (camera frame). Reward per action:
    ``reward_distance`` = −(distance to the target in cm) and ``reward_success`` =
    :data:`SUCCESS_REWARD` when within the tolerance (the episode then terminates)."""

    samples_ticks = False
    """Whether :meth:`after_tick` does anything (else a stepper need not record the ticks)."""

    def __init__(self, n: int, p_start: np.ndarray, radius: float, tolerance: float) -> None:
        self.n = n
        self.p_start = np.asarray(p_start, dtype=float)
        self.radius, self.tolerance = float(radius), float(tolerance)
        self.target = np.tile(self.p_start, (n, 1))

    def spaces(self) -> dict[str, spaces.Space]:
        return {"target": _box(3), "target_offset": _box(3)}

    def reset(self, rows, rngs) -> None:
        """New targets for ``rows``, each drawn from its generator ``rngs[row]``."""
        for i in rows:
            self.target[i] = self.p_start + rngs[i].uniform(-self.radius, self.radius, 3)

    def after_tick(self, t: float, T_camera_tip: np.ndarray, active: np.ndarray) -> None:
        """Reach samples nothing per tick."""

    def features(self, T_camera_tip: np.ndarray, T_task_camera=None) -> dict[str, np.ndarray]:
        tip = T_camera_tip[:, :3, 3]
        return {"target": self.target.copy(), "target_offset": self.target - tip}

    def outcome(self, T_camera_tip: np.ndarray, T_task_camera=None, features=None):
        """``(reward (n,), terminated (n,), terms: name → (n,))`` at the current state
        (``features``: :meth:`features` of the same state, if the caller has them)."""
        tip = T_camera_tip[:, :3, 3]
        offset = self.target - tip if features is None else features["target_offset"]
        d = np.linalg.norm(offset, axis=1)
        success = d <= self.tolerance
        terms = {
            "reward_distance": -d / REWARD_LENGTH,
            "reward_success": np.where(success, SUCCESS_REWARD, 0.0),
        }
        return terms["reward_distance"] + terms["reward_success"], success, terms

    def info(self) -> dict[str, np.ndarray]:
        return {}


class TaskProblem:
    """An exercise (``task``, any kind) for n rows; ``T_task_camera`` (4, 4) the camera in
    the task's frame (see the module docstring). The single environment passes the camera's
    current pose to :meth:`after_tick`; the vector one holds the start's."""

    samples_ticks = True
    """Every tick's sample goes through the task (:meth:`after_tick`)."""

    def __init__(self, task, n: int, T_task_camera: np.ndarray, camera) -> None:
        self.task, self.n = task, n
        self.T_task_camera = np.asarray(T_task_camera, dtype=float)
        self.camera = camera
        self.state = task.initial_state(n)
        self.metrics = task.metrics_accumulator(n)
        self._tick = LivePathTick.build(task, self, camera)
        """One row of the path kind: its sample and tick in one compiled call (None: the
        Python path, :meth:`sample` then ``advance``)."""
        self.path = getattr(task, "path", None) if task.kind == "path" else None
        # The path kind's distance is its closest point's: found once for both features.
        self._distance_of_closest = self.path is not None and (
            type(task).distance is PathTask.distance and task.path is self.path
        )
        self._progress = np.zeros(n)
        self._phase = np.zeros(n, dtype=int)
        self.time_now = 0.0
        """Time of the last sample, s."""

    # ------------------------------------------------------------ spaces
    def spaces(self) -> dict[str, spaces.Space]:
        out = {"phase": _box(1, low=0.0, high=float(Phase.RESULTS)), "distance": _box(1)}
        if self.path is not None:
            out["progress"] = _box(1, low=0.0, high=1.0)
            out["next_point"] = _box(3)
        if self.task.kind == "camera_targeting":
            out["target"] = _box(3)
        if self.task.kind == "needle_drive":
            out["entry_mark"], out["exit_mark"] = _box(3), _box(3)
        return out

    # ------------------------------------------------------------ episodes
    def reset(self, rows, rngs) -> None:
        mask = np.zeros(self.n, dtype=bool)
        mask[list(rows)] = True
        self.state = self.task.reset_state(self.state, mask)
        self.metrics.reset(mask)
        self._progress[mask] = 0.0
        self._phase[mask] = Phase.IDLE

    def sample(self, t, T_camera_tip: np.ndarray, T_task_camera=None, **extra) -> Sample:
        """The task's :class:`~davinci_sim.tasks.Sample` of n tips (n, 4, 4), camera frame."""
        T = self.T_task_camera if T_task_camera is None else T_task_camera
        T_task_tip = T @ T_camera_tip
        p_camera = T_camera_tip[:, :3, 3]
        return Sample.of(
            t, T_task_tip[:, :3, 3], visible=in_left_image(p_camera, self.camera),
            T_task_camera=T, R_task_tip=T_task_tip[:, :3, :3],
            contacts=extra.pop("contacts", 0), tool_force=extra.pop("tool_force", 0.0), **extra,
        )  # fmt: skip

    def after_tick(self, t, T_camera_tip, active, T_task_camera=None, **extra) -> None:
        """One tick's sample of the rows ``active`` (n,) through the task and its metrics."""
        self.time_now = t
        if self._tick is not None and active[0] and extra.keys() <= {"contacts", "tool_force"}:
            T = self.T_task_camera if T_task_camera is None else T_task_camera
            T_task_tip = (T @ T_camera_tip)[0]  # (sample's product)
            count, force = extra.get("contacts", 0), extra.get("tool_force", 0.0)
            inputs = (T_camera_tip[0], None, False, None, (int(count), float(force)))
            if self._tick.tick(T, inputs, t, T_task_tip):
                return
        sample = self.sample(t, T_camera_tip, T_task_camera, **extra)
        self.state, _ = advance(self.task, self.state, self.metrics, sample, active)

    def after_ticks(self, t, T_camera_tip, T_task_camera) -> None:
        """:meth:`after_tick` of m ticks in turn, the one row active, with no contacts: their
        times (m,) s, tips (m, 4, 4) in the camera frame and cameras in the task's frame
        (m, 4, 4) (an environment's samples of a compiled period's ticks)."""
        T_task_tip = T_task_camera @ T_camera_tip  # (each row: sample's product)
        zeros = np.zeros(len(t))
        if self._tick is not None and self._tick.ticks(
            T_task_camera, T_task_tip, T_camera_tip, t, zeros.astype(np.int64), zeros
        ):
            self.time_now = float(t[-1])
            return
        for j in range(len(t)):
            self.after_tick(float(t[j]), T_camera_tip[j : j + 1], _ONE, T_task_camera[j],
                            contacts=0, tool_force=0.0)  # fmt: skip

    # ------------------------------------------------------------ per action
    def features(self, T_camera_tip, T_task_camera=None) -> dict[str, np.ndarray]:
        T = self.T_task_camera if T_task_camera is None else T_task_camera
        tip = _transform(T, T_camera_tip[:, :3, 3])
        cp = None if self.path is None else closest_point(self.path, tip)  # (compiled, same bits)
        distance = cp.distance if self._distance_of_closest else self.task.distance(tip)
        if self.task.kind == "camera_targeting":  # (about the camera, not the tip)
            _, seen = self.task.step(self.state, self.sample(self.time_now, T_camera_tip, T))
            distance = seen["distance"]
        out = {
            "phase": self.state.phase.astype(float)[:, None],
            "distance": np.reshape(distance, (-1, 1)),
        }
        T_camera_task = invert_transform(T)
        if cp is not None:
            length = self.path.length
            ahead = self.path.point_at(np.minimum(cp.arc_length + LOOKAHEAD, length))
            out["progress"] = (self.state.progress / length)[:, None]
            out["next_point"] = _transform(T_camera_task, np.reshape(ahead, (-1, 3)))
        if self.task.kind == "camera_targeting":
            k = np.minimum(self.state.target, len(self.task.targets) - 1)
            out["target"] = _transform(T_camera_task, self.task.targets[k])
        if self.task.kind == "needle_drive":  # (the marks: task frame, the world's)
            marks = self.task.pad.marks_world()
            k = np.minimum(self.state.next_pair, len(marks) - 1)
            out["entry_mark"] = _transform(T_camera_task, marks[k, 0])
            out["exit_mark"] = _transform(T_camera_task, marks[k, 1])
        return out

    def outcome(self, T_camera_tip, T_task_camera=None, features=None):
        """``(reward (n,), terminated (n,), terms)``: ``reward_distance`` −(the task's
        ``distance`` in cm), ``reward_progress`` (path: the share of the path newly
        covered × :data:`PROGRESS_REWARD`; needle driving: the share of the pairs newly
        passed × the same), ``reward_finish`` (:data:`SUCCESS_REWARD` at
        the action the task finishes); terminated once the phase is FINISHED.
        ``features``: :meth:`features` of the same state, if the caller has them."""
        feats = self.features(T_camera_tip, T_task_camera) if features is None else features
        phase = self.state.phase.astype(int)
        done = phase >= Phase.FINISHED
        finish = done & (self._phase < Phase.FINISHED)
        terms = {"reward_distance": -feats["distance"][:, 0] / REWARD_LENGTH}
        if self.path is not None:
            progress = feats["progress"][:, 0]
            terms["reward_progress"] = PROGRESS_REWARD * (progress - self._progress)
            self._progress = progress.copy()
        elif self.task.kind == "needle_drive":
            progress = self.state.next_pair / len(self.task.pairs)
            terms["reward_progress"] = PROGRESS_REWARD * (progress - self._progress)
            self._progress = progress.astype(float)
        terms["reward_finish"] = np.where(finish, SUCCESS_REWARD, 0.0)
        self._phase = phase
        return sum(terms.values()), done, terms

    def info(self) -> dict[str, np.ndarray]:
        """The task's declared metrics of the repetition so far (``metric_<name>``, (n,))."""
        result = self.metrics.result()
        return {f"metric_{m.name}": np.asarray(getattr(result, m.name), dtype=float)
                for m in self.task.METRICS}  # fmt: skip
