"""What an environment observes of the objects a task handles, from the task's own reading
of the scene (:meth:`~davinci_sim.tasks.Task.scene_fields`, the fields its samples get):
one implementation for :class:`~davinci_sim.envs.base.DavinciEnv` and
:class:`~davinci_sim.envs.instruments.InstrumentsEnv`.

* peg transfer: ``objects`` (k, 3), the rings' centres, and ``grasp`` (k,), 1 where a jaw
  touches the ring;
* the needle exercises: ``needle_position`` (3,), the centre of the needle's circle,
  ``needle_orientation`` (6,), the first two columns of its frame (z: its plane's normal;
  :func:`~davinci_sim.envs.control.orientation_features`), and ``needle_held`` (A,), 1 where
  both jaws of the observed arm ``a`` touch it (the task's *held*);
* needle driving also: ``tissue_force`` (1,), the instruments' normal force on the skin, N.

Positions and orientations are in the camera frame, m.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from davinci_sim.envs.control import orientation_features

_BIG = 10.0  # (bounds of positions, m: the scene is much smaller)


def _is_needle(task) -> bool:
    return getattr(task, "kind", None) in ("needle_pickup", "needle_drive")


def object_spaces(task, arms: tuple[str, ...]) -> dict[str, spaces.Space]:
    """The observation spaces of ``task``'s objects seen with the arms ``arms`` (none for a
    task without objects)."""
    box = {"low": -_BIG, "high": _BIG, "dtype": np.float64}
    unit = {"low": 0.0, "high": 1.0, "dtype": np.float64}
    out: dict[str, spaces.Space] = {}
    k = getattr(task, "n_rings", 0)
    if k:
        out["objects"] = spaces.Box(shape=(k, 3), **box)
        out["grasp"] = spaces.Box(shape=(k,), **unit)
    if _is_needle(task):
        out["needle_position"] = spaces.Box(shape=(3,), **box)
        out["needle_orientation"] = spaces.Box(low=-1.0, high=1.0, shape=(6,), dtype=np.float64)
        out["needle_held"] = spaces.Box(shape=(len(arms),), **unit)
    if getattr(task, "kind", None) == "needle_drive":
        out["tissue_force"] = spaces.Box(low=0.0, high=1e4, shape=(1,), dtype=np.float64)
    return out


def object_features(
    task, fields: dict, T_camera_task: np.ndarray, arms: tuple[str, ...]
) -> dict[str, np.ndarray]:
    """The observations of :func:`object_spaces` from ``fields``, the task's scene fields
    now (task frame), with the task's frame in the camera's ``T_camera_task`` (4, 4)."""
    out: dict[str, np.ndarray] = {}
    R, t = T_camera_task[:3, :3], T_camera_task[:3, 3]
    if getattr(task, "n_rings", 0):
        p = np.asarray(fields["objects"], dtype=float).reshape(-1, 3)
        out["objects"] = p @ R.T + t
        out["grasp"] = (np.asarray(fields["grasp"]).reshape(-1) > 0).astype(float)
    if _is_needle(task):
        T = T_camera_task @ np.asarray(fields["T_task_object"], dtype=float)
        out["needle_position"] = T[:3, 3].copy()
        out["needle_orientation"] = orientation_features(T[:3, :3])
        bits = int(np.asarray(fields["grasp"]).reshape(-1)[0])
        instruments = tuple(task.instruments)
        out["needle_held"] = np.array(
            [float(a in instruments and (bits >> (2 * instruments.index(a))) & 3 == 3)
             for a in arms]
        )  # fmt: skip
    if getattr(task, "kind", None) == "needle_drive":
        out["tissue_force"] = np.array([float(fields.get("tissue_force", 0.0))])
    return out
