"""Recordings to an imitation-learning dataset: ``davinci-sim replay FILES --to-dataset OUT``.

The format is robomimic's HDF5 layout (one file, ``h5py``), which robomimic, LIBERO,
RoboCasa, MimicGen and their loaders read as it is, and which any HDF5 reader opens
(numpy-shaped arrays, no schema to learn). LeRobot's parquet needs pyarrow (~40 MB) and
splits a dataset into many files with videos; HDF5 keeps one self-describing file and
h5py is a ~5 MB wheel. The layout::

    data/                      attrs: total (steps), env_args (JSON: the recordings' metadata),
                               davinci_sim_layout ("robomimic-v1")
      demo_0/                  attrs: num_samples, source (file), kind, finished (bool)
        obs/<key>              (T, ...) float64: the observation before each action
        next_obs/<key>         (T, ...) the observation after it
        actions                (T, A) float64
        rewards                (T,)   float64
        dones                  (T,)   uint8: 1 at the episode's last step
        states                 (T, nq) MuJoCo qpos (sessions: the whole model's)
      demo_1/ ...
    mask/                      (robomimic's filter keys) ``finished``: the demos that end
                               with a finished repetition; ``all``

Episodes come from two kinds of recording:

* a **session** (``serve --record``): one demo per repetition of the task, split where the
  session reports a finished repetition (``/task/results``); the snapshots after the last
  report form a demo with ``finished`` false (without a task: one demo). Observations per
  snapshot: every PSM's and the ECM's joint positions (``<arm>_joint_pos``) and the PSMs'
  jaw (``<arm>_jaw``, rad), the tool tips in the camera frame (``<arm>_tip_pos``, m;
  ``<arm>_tip_quat``, x y z w) and the task's distance to the path (``task_distance``, m,
  NaN without a task). The action at snapshot k is what was commanded until snapshot k+1,
  in the dVRK's terms: each PSM's setpoint tip displacement in the camera frame (m, 3) and
  its jaw setpoint (rad), concatenated in arm order (``actions``), and the PSMs' next joint
  setpoints (``actions_joint``, the joint-space variant). Reward: 1 at the step in which a
  repetition finished, else 0.
* **episodes** (:class:`~davinci_sim.records.episodes.EpisodeRecorder`: environments, study
  trials): as recorded; a ``Dict`` observation's keys are the ``obs`` keys (flattened
  arrays), the action and reward as given.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from davinci_sim.records.mcap_file import McapContents, read_mcap

LAYOUT = "robomimic-v1"


@dataclass(frozen=True)
class Demo:
    """One episode as arrays (see the module docstring)."""

    obs: dict[str, np.ndarray]
    next_obs: dict[str, np.ndarray]
    actions: np.ndarray
    rewards: np.ndarray
    dones: np.ndarray
    states: np.ndarray | None
    finished: bool
    extra: dict[str, np.ndarray]


@dataclass(frozen=True)
class DatasetSummary:
    path: Path
    demos: int
    steps: int
    files: int

    def line(self) -> str:
        return f"{self.path}: {self.demos} demos, {self.steps} steps from {self.files} recording(s)"


def _arr(values) -> np.ndarray:
    return np.array([[np.nan if v is None else v for v in row] for row in values], dtype=float)


def _by_tick(contents: McapContents, topic: str) -> dict[int, dict]:
    return {m["tick"]: m for _, m in contents.topic(topic) if "tick" in m}


def _by_time(contents: McapContents, topic: str) -> dict[int, dict]:
    return {t: m for t, m in contents.topic(topic)}


def _pose(m: dict) -> tuple[list, list]:
    p, q = m["pose"]["position"], m["pose"]["orientation"]
    return [p["x"], p["y"], p["z"]], [q["x"], q["y"], q["z"], q["w"]]


def session_demos(contents: McapContents) -> list[Demo]:
    """The demos of a session recording (module docstring)."""
    q_msgs = contents.topic("/sim/qpos")
    if len(q_msgs) < 2:
        return []
    times = np.array([t for t, _ in q_msgs], dtype=np.int64)
    states = _arr([m["qpos"] for _, m in q_msgs])
    n = len(times)
    arms = sorted(
        {
            topic.split("/")[1]
            for topic in contents.messages
            if topic.endswith("/measured_js") and topic.count("/") == 2
        }
    )
    psms = [a for a in arms if a.startswith("PSM")]
    obs: dict[str, np.ndarray] = {}
    act_parts, joint_parts = [], []
    for arm in [*psms, *(a for a in arms if a == "ECM")]:
        js = _by_time(contents, f"/{arm}/measured_js")
        cp = _by_time(contents, f"/{arm}/measured_cp")
        width = len(next(iter(js.values()))["position"]) if js else 0
        obs[f"{arm}_joint_pos"] = _arr(
            [js[t]["position"] if t in js else [None] * width for t in times]
        )
        pos = [(_pose(cp[t]) if t in cp else ([None] * 3, [None] * 4)) for t in times]
        obs[f"{arm}_tip_pos"] = _arr([p for p, _ in pos])
        obs[f"{arm}_tip_quat"] = _arr([q for _, q in pos])
        if arm in psms:
            jaw = _by_time(contents, f"/{arm}/jaw/measured_js")
            obs[f"{arm}_jaw"] = _arr(
                [jaw[t]["position"][:1] if t in jaw else [None] for t in times]
            )
            sp = _by_time(contents, f"/{arm}/setpoint_cp")
            sj = _by_time(contents, f"/{arm}/setpoint_js")
            jaw_sp = _by_time(contents, f"/{arm}/jaw/setpoint_js")
            p_sp = _arr([_pose(sp[t])[0] if t in sp else [None] * 3 for t in times])
            jaw_set = _arr([jaw_sp[t]["position"][:1] if t in jaw_sp else [None] for t in times])
            if not jaw_sp:  # (older files: the measured jaw)
                jaw_set = obs[f"{arm}_jaw"]
            act_parts.append(np.concatenate([p_sp[1:] - p_sp[:-1], jaw_set[1:]], axis=1))
            joint_parts.append(
                _arr([sj[t]["position"] if t in sj else [None] * width for t in times])[1:]
            )
    task = _by_time(contents, "/task/state")
    obs["task_distance"] = np.array(
        [
            [float((task.get(t) or {}).get("state", {}).get("distance_to_path") or np.nan)]
            for t in times
        ]
    )
    actions = np.concatenate(act_parts, axis=1) if act_parts else np.zeros((n - 1, 0))
    joints = np.concatenate(joint_parts, axis=1) if joint_parts else np.zeros((n - 1, 0))
    # A repetition that finished between snapshot k and k+1: reward 1 at step k.
    ends = sorted(t for t, _ in contents.topic("/task/results"))
    rewards = np.zeros(n - 1)
    cuts = []
    for t in ends:
        k = int(np.searchsorted(times, t, side="left")) - 1
        k = min(max(k, 0), n - 2)
        rewards[k] = 1.0
        cuts.append(k + 1)
    bounds = sorted({0, *cuts, n - 1})
    demos = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        if b <= a:
            continue
        s = slice(a, b)
        dones = np.zeros(b - a, dtype=np.uint8)
        dones[-1] = 1
        demos.append(
            Demo(
                obs={k: v[a:b] for k, v in obs.items()},
                next_obs={k: v[a + 1 : b + 1] for k, v in obs.items()},
                actions=actions[s],
                rewards=rewards[s],
                dones=dones,
                states=states[s],
                finished=b in cuts,
                extra={"actions_joint": joints[s]},
            )
        )
    return demos


def _flat(value) -> dict[str, np.ndarray]:
    if isinstance(value, dict):
        return {k: np.asarray(v, dtype=float).ravel() for k, v in value.items()}
    return {"obs": np.asarray(value, dtype=float).ravel()}


def episode_demos(contents: McapContents) -> list[Demo]:
    """The demos of an episodes recording (module docstring)."""
    episodes: dict[int, list[dict]] = {}
    for _, m in contents.topic("/episode/step"):
        episodes.setdefault(m["episode"], []).append(m)
    demos = []
    for _, steps in sorted(episodes.items()):
        steps.sort(key=lambda m: m["step"])
        if len(steps) < 2 or steps[0]["action"] is not None:
            continue
        obs_rows = [_flat(m["observation"]) for m in steps]
        keys = list(obs_rows[0])
        all_obs = {k: np.stack([np.asarray(r[k], dtype=float) for r in obs_rows]) for k in keys}
        acts = np.stack([np.asarray(m["action"], dtype=float).ravel() for m in steps[1:]])
        rewards = np.array([np.nan if m["reward"] is None else m["reward"] for m in steps[1:]])
        T = len(steps) - 1
        dones = np.zeros(T, dtype=np.uint8)
        last = steps[-1]
        dones[-1] = 1
        demos.append(
            Demo(
                obs={k: v[:-1] for k, v in all_obs.items()},
                next_obs={k: v[1:] for k, v in all_obs.items()},
                actions=acts,
                rewards=rewards,
                dones=dones,
                states=None,
                finished=bool(last["terminated"]),
                extra={},
            )
        )
    return demos


def recording_demos(contents: McapContents) -> tuple[str, list[Demo]]:
    """The kind of a recording (``session`` or ``episodes``) and its demos."""
    kind = contents.metadata.get("davinci_sim", {}).get("kind", "")
    if kind == "episodes" or contents.topic("/episode/step"):
        return "episodes", episode_demos(contents)
    return "session", session_demos(contents)


def to_dataset(files, out: str | Path) -> DatasetSummary:
    """Write the demos of ``files`` (recordings, finished or cut off) to ``out`` (HDF5,
    robomimic's layout; replaced if it exists).

    Raises:
        ValueError: no recording holds a demo.
        McapReadError, OSError: a file that is not a recording, or unreadable.
    """
    import h5py

    out = Path(out)
    files = list(files)
    all_demos: list[tuple[str, str, Demo]] = []
    env_args = []
    for f in files:
        contents = read_mcap(f)
        kind, demos = recording_demos(contents)
        env_args.append(
            {
                "file": Path(f).name,
                "kind": kind,
                "complete": contents.complete,
                **contents.metadata.get("davinci_sim", {}),
            }
        )
        all_demos.extend((str(Path(f).name), kind, d) for d in demos)
    if not all_demos:
        raise ValueError(f"no demo in {len(files)} recording(s): too short, or no states")
    tmp = out.with_name(out.name + ".part")
    total = 0
    with h5py.File(tmp, "w") as h5:
        data = h5.create_group("data")
        names = []
        for i, (source, kind, d) in enumerate(all_demos):
            g = data.create_group(f"demo_{i}")
            names.append((f"demo_{i}", d.finished))
            g.attrs.update(
                num_samples=len(d.actions), source=source, kind=kind, finished=d.finished
            )
            for group, arrays in (("obs", d.obs), ("next_obs", d.next_obs)):
                sub = g.create_group(group)
                for key, value in arrays.items():
                    sub.create_dataset(key, data=value, compression="gzip")
            for key, value in (
                ("actions", d.actions),
                ("rewards", d.rewards),
                ("dones", d.dones),
                *d.extra.items(),
            ):
                g.create_dataset(key, data=value, compression="gzip")
            if d.states is not None:
                g.create_dataset("states", data=d.states, compression="gzip")
            total += len(d.actions)
        data.attrs.update(total=total, env_args=json.dumps(env_args), davinci_sim_layout=LAYOUT)
        mask = h5.create_group("mask")
        mask.create_dataset("all", data=np.array([n for n, _ in names], dtype="S"))
        mask.create_dataset("finished", data=np.array([n for n, f in names if f], dtype="S"))
    tmp.replace(out)
    return DatasetSummary(out, len(all_demos), total, len(files))
