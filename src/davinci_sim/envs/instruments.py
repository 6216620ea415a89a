"""An environment whose actions move several instruments and turn them: the exercises
done with both hands (needle pick-up and hand-off, needle driving, the running suture,
peg transfer with its hand-off).

It is :class:`~davinci_sim.envs.base.DavinciEnv` (the same start, reset, task, rewards
and info) with these differences; ``gymnasium.make`` builds one when the keyword arguments
set ``arms`` or ``rotation`` (:class:`~davinci_sim.envs.setup.EnvConfig`).

**Action** (``Box(-1, 1)``, float32): one slice per arm of ``arms``, in that order —
``cartesian``: (dx, dy, dz, jaw), with ``rotation`` (dx, dy, dz, rx, ry, rz, jaw): the tip
goal's displacement in the camera frame in units of ``max_step`` (m), its turn, a rotation
vector about the camera's axes in units of ``max_rotation_step`` (rad), and the jaw from
closed (−1) to open (1); ``joint``: (dq₁…dq₆, jaw) per arm.

**Step.** Each tick of the period sends every arm its ramp's ``servo_cp`` (position and
orientation moving at constant velocity over the period, the twist as feed-forward) or
``servo_jp``, then the simulation ticks and the task samples, in Python: the compiled
period (:mod:`davinci_sim.sim.live_period`) drives one arm (so an action costs about the
K ticks' Python, ~1–2 ms a tick with the needle's scene, against the single-arm
environment's compiled period).

**Observation**: the per-arm fields of :class:`~davinci_sim.envs.base.DavinciEnv` with a
leading axis, one row per arm of ``arms`` — ``joint_position``, ``joint_velocity`` (A, dof),
``jaw`` (A,), ``tip_position`` (A, 3), ``tip_orientation`` (A, 6), ``setpoint`` (A, 3) or
(A, dof), and with ``rotation`` ``setpoint_orientation`` (A, 6); the task's features (of its
own PSM's tip, as in the single-arm environment); the objects
(:mod:`davinci_sim.envs.objects`, ``needle_held`` one entry per arm of ``arms``); images.

**Info** ``fault``: any of the arms went to FAULT (the episode terminates).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from davinci_sim.envs import control
from davinci_sim.envs.base import DavinciEnv, joint_steps
from davinci_sim.envs.control import orientation_features
from davinci_sim.envs.objects import object_spaces
from davinci_sim.envs.problems import TaskProblem
from davinci_sim.sim import operating_state as ops

_BIG = 10.0  # (bounds of positions, m)


class InstrumentsEnv(DavinciEnv):
    """Several instruments moved and turned by the actions (see the module docstring);
    ``**kwargs``: :class:`~davinci_sim.envs.setup.EnvConfig`."""

    _PER_INSTRUMENT = True

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        super().__init__(render_mode, **kwargs)
        start, config = self._start, self.config
        names = config.arms if config.arms is not None else (start.psm,)
        allowed = (start.psm, *getattr(start.task, "instruments", ()))
        unknown = [n for n in names if n not in allowed]
        if unknown or start.arm == "ECM":
            self.close()
            what = (
                "the ECM's task moves the camera"
                if start.arm == "ECM"
                else (f"the arms {unknown} are not among the task's instruments {list(allowed)}")
            )
            raise ValueError(f"InstrumentsEnv: {what}")
        self.names: tuple[str, ...] = tuple(names)
        """The arms the actions move, in order."""
        self.instruments = [self.sim.arms[n] for n in self.names]
        self._period = None  # (the compiled period drives one arm: Python ticks)
        # Each arm's goal at the start (camera frame): the task's PSM at the task's start
        # (build_start), the others where homing left them.
        goals = []
        for name, arm in zip(self.names, self.instruments, strict=True):
            T = arm.setpoint_cp().T.copy()
            if name == start.psm:
                T[:3, :3], T[:3, 3] = start.R_goal, start.p_start_camera
            goals.append(T)
        self._T_start = np.array(goals)
        self._T_goals = self._T_start.copy()
        self._q_start = np.array([arm.setpoint_jp() for arm in self.instruments])
        self._q_goals = self._q_start.copy()
        lo, hi = start.workspace
        p = self._T_start[:, :3, 3]
        self._lo = np.minimum(lo, p.min(axis=0) - config.workspace)
        self._hi = np.maximum(hi, p.max(axis=0) + config.workspace)
        self._joint_steps = [joint_steps(arm.chain, config.max_joint_step)
                             for arm in self.instruments]  # fmt: skip
        self.action_space = self._action_space()
        self.observation_space = self._observation_space()

    # ------------------------------------------------------------ spaces
    def _per_arm(self) -> int:
        """Numbers per arm in an action."""
        cfg = self.config
        if cfg.action_space == "joint":
            return self.arm.dof + 1
        return 3 + (3 if cfg.rotation else 0) + 1

    def _action_space(self) -> spaces.Box:
        n = len(self.names) * self._per_arm()
        return spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)

    def _observation_space(self) -> spaces.Dict:
        A, dof = len(self.names), self.arm.dof
        box = {"low": -_BIG, "high": _BIG, "dtype": np.float64}
        unit = {"low": -1.0, "high": 1.0, "dtype": np.float64}
        cartesian = self.config.action_space == "cartesian"
        out: dict[str, spaces.Space] = {
            "joint_position": spaces.Box(shape=(A, dof), **box),
            "joint_velocity": spaces.Box(
                low=-100.0, high=100.0, shape=(A, dof), dtype=np.float64
            ),  # fmt: skip
            "jaw": spaces.Box(low=-1.0, high=4.0, shape=(A,), dtype=np.float64),
            "tip_position": spaces.Box(shape=(A, 3), **box),
            "tip_orientation": spaces.Box(shape=(A, 6), **unit),
            "setpoint": spaces.Box(shape=(A, 3 if cartesian else dof), **box),
        }
        if self.config.rotation:
            out["setpoint_orientation"] = spaces.Box(shape=(A, 6), **unit)
        out.update(self.problem.spaces())
        out.update(object_spaces(self._start.task, self.names))
        if self.config.images:
            w, h = self.config.image_size
            for side in ("left", "right"):
                out[side] = spaces.Box(0, 255, shape=(h, w, 3), dtype=np.uint8)
        return spaces.Dict(out)

    # ------------------------------------------------------------ gymnasium
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        self._T_goals = self._T_start.copy()
        self._q_goals = self._q_start.copy()
        return super().reset(seed=seed, options=options)

    # ------------------------------------------------------------ internals
    def _faulted(self) -> bool:
        return any(arm.operating_state().state == ops.FAULT for arm in self.instruments)

    def _apply(self, a: np.ndarray) -> None:
        """One control period: every arm's ramp, tick by tick (the module docstring)."""
        K, cfg = self.K, self.config
        m = self._per_arm()
        cartesian = cfg.action_space == "cartesian"
        ramps = []
        for i, arm in enumerate(self.instruments):
            ai = a[i * m : (i + 1) * m]
            jaw = control.jaw_angle(ai[-1], arm.jaw.spec.qmin, arm.jaw.spec.qmax)
            arm.jaw.servo_jp([float(jaw)])
            if cartesian:
                T = self._T_goals[i]
                delta = control.cartesian_delta(ai[:3], T[:3, 3], cfg.max_step, self._lo,
                                                self._hi)  # fmt: skip
                omega = (control.rotation_step(ai[3:6], cfg.max_rotation_step)
                         if cfg.rotation else np.zeros(3))  # fmt: skip
                twist = np.concatenate([control.feedforward(delta, K),
                                        control.feedforward(omega, K)])  # fmt: skip
                ramps.append((T.copy(), delta, omega, twist))
            else:
                q = self._q_goals[i]
                delta = control.joint_delta(ai[:-1], q, self._joint_steps[i], arm.chain.qmin,
                                            arm.chain.qmax)  # fmt: skip
                ramps.append((q.copy(), delta, None, control.feedforward(delta, K)))
        task = self.problem if isinstance(self.problem, TaskProblem) else None
        T_goal = np.eye(4)
        for k in range(1, K + 1):
            for arm, (start, delta, omega, feedforward) in zip(self.instruments, ramps,
                                                               strict=True):  # fmt: skip
                if cartesian:
                    T_goal[:3, 3] = control.ramp(start[:3, 3], delta, k, K)
                    T_goal[:3, :3] = control.ramp_rotation(start[:3, :3], omega, k, K)
                    arm.servo_cp(T_goal, feedforward)
                else:
                    arm.servo_jp(control.ramp(start, delta, k, K), feedforward)
            self.sim.tick()
            if task is not None:
                self._sample_task(task)
        for i, (start, delta, omega, _) in enumerate(ramps):
            if cartesian:
                self._T_goals[i][:3, 3] = start[:3, 3] + delta
                self._T_goals[i][:3, :3] = control.ramp_rotation(start[:3, :3], omega, K, K)
            else:
                self._q_goals[i] = start + delta

    def _observation(self, T: np.ndarray, T_task_camera, feats) -> dict[str, np.ndarray]:
        """The observation (see the module docstring); ``T`` the task's PSM's tip."""
        arms = self.instruments
        T_tips = np.array([arm._measured_T() for arm in arms])
        cartesian = self.config.action_space == "cartesian"
        obs = {
            "joint_position": np.array([arm._q() for arm in arms]),
            "joint_velocity": np.array([arm._qd() for arm in arms]),
            "jaw": np.array([arm.jaw.measured_jp() for arm in arms], dtype=float),
            "tip_position": T_tips[:, :3, 3].copy(),
            "tip_orientation": orientation_features(T_tips[:, :3, :3]),
            "setpoint": (self._T_goals[:, :3, 3] if cartesian else self._q_goals).copy(),
        }
        if self.config.rotation:
            obs["setpoint_orientation"] = orientation_features(self._T_goals[:, :3, :3])
        obs.update({k: v[0] for k, v in feats.items()})
        if T_task_camera is not None:
            obs.update(self._object_observation(T_task_camera, self.names))
        if self.config.images:
            w, h = self.config.image_size
            obs["left"], obs["right"] = self.sim.render_stereo(w, h)
        return obs
