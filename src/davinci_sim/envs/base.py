"""The single environment: one live :class:`~davinci_sim.sim.simulation.Simulation` behind
Gymnasium's ``reset``/``step``.

**Step.** An action lasts one control period (``control_hz``, 50 Hz by default: 20 ticks
of the 1 kHz physics and servo). Each tick sends the arm's ``servo_cp`` (the tool tip's
goal in the camera frame, orientation held, with the twist feed-forward) or ``servo_jp``
(joint goal with its velocity), moving along the period's ramp as the teleoperation does
with the master's motion (:mod:`davinci_sim.envs.control`); the jaw's ``servo_jp`` once.
Then the simulation ticks (:meth:`Simulation.tick`: the arm's laws, the servo, ``mj_step``).
The period's ticks run in one compiled call (:func:`~davinci_sim.sim.live_period.run_period`:
the same laws, the same bits), each tick it has no compiled form of in Python. A task samples
every tick: the path kind (path following) from what the compiled call kept of each tick's
state, through its one compiled tick (:mod:`davinci_sim.tasks.live_path`); other kinds tick
by tick in Python.

**Action** (``Box(-1, 1)``, float32): ``cartesian``, (dx, dy, dz, jaw): the goal's
displacement in the camera frame in units of ``max_step`` (m), the jaw opening from closed
(−1) to open (1); ``joint``, (dq₁…dq₆, jaw) for a PSM (the ECM: dq₁…dq₄, no jaw) in units of
``max_joint_step`` (rad; prismatic joints a tenth of it, m).

**Observation** (``Dict``, float64; units):

* ``joint_position`` (dof,) rad and m (insertion), ``joint_velocity`` (dof,) rad/s, m/s —
  the arm the actions move (``measured_js``);
* ``jaw`` (1,) rad — the PSM's jaw opening (0 for the ECM);
* ``tip_position`` (3,) m, ``tip_orientation`` (6,) (the first two columns of the rotation)
  — the PSM's tool tip in the camera frame (``measured_cp``);
* ``setpoint`` — the goal the actions have moved so far (the tip lags it by the servo's
  tracking): the tip's goal in the camera frame (3,), m, or the joint goal (dof,);
* the task's features (:mod:`davinci_sim.envs.problems`): Reach ``target``,
  ``target_offset`` (m, camera frame); exercises ``phase`` (the task's
  :class:`~davinci_sim.tasks.Phase`), ``distance`` (m), path following ``progress``
  (0–1) and ``next_point`` (m, camera frame), camera targeting ``target`` (m, camera frame),
  peg transfer ``objects`` (rings, (k, 3), m, camera frame) and ``grasp`` (k,: 1 where a
  jaw touches the ring);
* with ``images=True``: ``left`` and ``right`` (height, width, 3) uint8, the endoscope.

**Reset** restores the start state (:func:`~davinci_sim.envs.setup.build_start`) with
:meth:`Simulation.set_state`, then draws the episode's randomness from ``np_random``.

**Info**: the reward's terms (``reward_*``), ``is_success``, ``fault`` (the arm went to
FAULT: the episode terminates), and at an episode's end the task's metrics
(``metric_<name>``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from davinci_sim.envs import control
from davinci_sim.envs.control import orientation_features
from davinci_sim.envs.objects import object_features, object_spaces
from davinci_sim.envs.problems import ReachProblem, TaskProblem
from davinci_sim.envs.setup import EnvConfig, EnvStart, build_start
from davinci_sim.kinematics import fk
from davinci_sim.sim import live_period
from davinci_sim.sim import operating_state as ops
from davinci_sim.sim.live_period import ArmPeriod, run_period


def joint_steps(chain, max_joint_step: float) -> np.ndarray:
    """Largest joint displacement per action (dof,): ``max_joint_step`` rad, a tenth of it
    in m for prismatic joints."""
    prismatic = np.array([j.joint_type == "prismatic" for j in chain.joints])
    return np.where(prismatic, 0.1 * max_joint_step, max_joint_step)


def observation_space(start: EnvStart, config: EnvConfig, problem) -> spaces.Dict:
    """The observation space of an environment of ``config`` (see the module docstring)."""
    dof = start.sim.arms[start.arm].dof
    big = 10.0
    box = {"low": -big, "high": big, "dtype": np.float64}
    out = {
        "joint_position": spaces.Box(shape=(dof,), **box),
        "joint_velocity": spaces.Box(low=-100.0, high=100.0, shape=(dof,), dtype=np.float64),
        "jaw": spaces.Box(low=-1.0, high=4.0, shape=(1,), dtype=np.float64),
        "tip_position": spaces.Box(shape=(3,), **box),
        "tip_orientation": spaces.Box(low=-1.0, high=1.0, shape=(6,), dtype=np.float64),
        "setpoint": spaces.Box(shape=(3 if config.action_space == "cartesian" else dof,), **box),
        **problem.spaces(),
    }
    out.update(object_spaces(start.task, (start.psm,)))
    if config.images:
        w, h = config.image_size
        for side in ("left", "right"):
            out[side] = spaces.Box(0, 255, shape=(h, w, 3), dtype=np.uint8)
    return spaces.Dict(out)


def action_space(start: EnvStart, config: EnvConfig) -> spaces.Box:
    arm = start.sim.arms[start.arm]
    n = 3 if config.action_space == "cartesian" else arm.dof
    n += 1 if start.arm.startswith("PSM") else 0
    return spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)


def make_problem(start: EnvStart, config: EnvConfig, n: int):
    if start.task is None:
        return ReachProblem(n, start.p_start_camera, config.reach_radius, config.reach_tolerance)
    return TaskProblem(start.task, n, start.T_task_camera, start.sim.endoscope)


_ONE = np.ones(1, dtype=bool)  # (the one row is active: after_tick only reads it)


class DavinciEnv(gym.Env):
    """One environment (see the module docstring); ``**kwargs``: :class:`EnvConfig`."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 50}
    _PER_INSTRUMENT = False  # (the config's arms and rotation: InstrumentsEnv's)

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        self.config = config = EnvConfig(**kwargs)
        if config.per_instrument and not self._PER_INSTRUMENT:
            raise ValueError("arms and rotation are InstrumentsEnv's (davinci_sim.envs."
                             "InstrumentsEnv; gymnasium.make picks it)")  # fmt: skip
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": config.control_hz}
        self.K = control.ticks_per_action(config.control_hz)
        self._start = start = build_start(config)
        if start.arm == "ECM" and config.action_space == "cartesian":
            start.sim.close()
            raise ValueError(
                "camera targeting moves the ECM: use action_space='joint' (the ECM's four "
                "joints); Cartesian actions move a PSM's tool tip"
            )
        self.sim = start.sim
        self.arm = self.sim.arms[start.arm]
        self.psm = self.sim.arms[start.psm]
        self.problem = make_problem(start, config, 1)
        self.observation_space = observation_space(start, config, self.problem)
        self.action_space = action_space(start, config)
        chain = self.arm.chain
        self._joint_step = joint_steps(chain, config.max_joint_step)
        self._qmin, self._qmax = chain.qmin, chain.qmax
        self._lo, self._hi = start.workspace
        self._steps = 0
        self._goal = start.p_start_camera.copy()
        self._q_goal = self._q_set()
        self._scene_cache: dict = {}
        self._episode_over = True
        self._period = ArmPeriod(self.sim, self.arm) if live_period.COMPILED else None

    # ------------------------------------------------------------ gymnasium
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.sim.set_state(self._start.state)
        self._goal = self._start.p_start_camera.copy()
        self._q_goal = self._q_set()
        self._steps = 0
        self.problem.reset([0], [self.np_random])
        self._episode_over = False
        T, T_task_camera = self._T_tip(), self._T_task_camera()
        feats = self.problem.features(T[None], T_task_camera)
        obs = self._observation(T, T_task_camera, feats)
        self.problem.outcome(T[None], T_task_camera, feats)  # (the reward's baselines)
        return obs, {}

    def step(self, action):
        if self._episode_over:
            raise RuntimeError("the episode is over: call reset() first")
        a = np.asarray(action, dtype=float).reshape(self.action_space.shape)
        if not np.all(np.isfinite(a)):
            raise ValueError(f"the action must be finite, got {action!r}")
        self._apply(a)
        T, T_task_camera = self._T_tip(), self._T_task_camera()  # (the outcome's and the obs')
        feats = self.problem.features(T[None], T_task_camera)  # (the same for both)
        reward, done, terms = self.problem.outcome(T[None], T_task_camera, feats)
        self._steps += 1
        fault = self._faulted()
        terminated = bool(done[0]) or fault
        truncated = not terminated and self._steps >= self.config.max_episode_steps
        info = {k: float(v[0]) for k, v in terms.items()}
        info["is_success"] = bool(done[0])
        info["fault"] = fault
        if terminated or truncated:
            # (the metrics defined so far: nan ones, e.g. a time before the task ran, left out)
            metrics = {k: float(v[0]) for k, v in self.problem.info().items()}
            info.update({k: v for k, v in metrics.items() if np.isfinite(v)})
            self._episode_over = True
        obs = self._observation(T, T_task_camera, feats)
        return obs, float(reward[0]), terminated, truncated, info

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        w, h = self.config.image_size
        return self.sim.render("ECM/left", w, h, fast=True)

    def close(self) -> None:
        self.sim.close()

    # ------------------------------------------------------------ internals
    def _q_set(self) -> np.ndarray:
        return self.sim.servo.q_ref[self.arm.actuator_indices].copy()

    def _T_task_camera(self) -> np.ndarray | None:
        """The camera in the task's frame now (it moves with the ECM); None for Reach."""
        if self._start.task is None:
            return None
        return self._start.task.T_task_camera(self.sim.T_cart_camera())

    def _T_tip(self) -> np.ndarray:
        """The tip in the camera frame (4, 4), read-only: ``measured_cp().T``, the same bits
        without the message (``Arm._measured_T``)."""
        return self.psm._measured_T()

    def _apply(self, a: np.ndarray) -> None:
        """One control period (see the module docstring)."""
        K, cfg = self.K, self.config
        if cfg.action_space == "cartesian":
            delta = control.cartesian_delta(a[:3], self._goal, cfg.max_step, self._lo, self._hi)
            start = self._goal
        else:
            dof = self.arm.dof
            delta = control.joint_delta(
                a[:dof], self._q_goal, self._joint_step, self._qmin, self._qmax
            )
            start = self._q_goal
        velocity = control.feedforward(delta, K)
        if self.arm is self.psm:
            spec = self.psm.jaw.spec
            jaw = float(control.jaw_angle(a[-1], spec.qmin, spec.qmax))
            if self.psm._not_ready():  # (refused, with its message)
                self.psm.jaw.servo_jp(jaw)
            else:  # finite (the action is), clipped to the limits as servo_jp clips it
                self.psm.jaw._servo_jp_checked(min(max(jaw, spec.qmin), spec.qmax))
        twist = np.concatenate([velocity, np.zeros(3)]) if cfg.action_space == "cartesian" else None
        task = self.problem if isinstance(self.problem, TaskProblem) else None
        # The ticks run compiled while they can (sim/live_period.py); the others, and a tick
        # the kernel stops before, in Python. A task samples every tick: from the period's
        # records where the kernel keeps them (the path kind's one compiled tick), else
        # tick by tick in Python.
        recorded = None
        if task is not None and task._tick is not None and self.arm is self.psm:
            recorded = lambda samples, ticks: self._sample_recorded(task, samples, ticks)  # noqa: E731
        run_period(
            self.sim, self.arm, K, cartesian=cfg.action_space == "cartesian", start=start,
            delta=delta, velocity=velocity, R_ref_goal=self._start.R_goal, twist_ref=twist,
            period=self._period, recorded=recorded,
            after_tick=None if task is None else lambda: self._sample_task(task),
        )  # fmt: skip
        if cfg.action_space == "cartesian":
            self._goal = start + delta
        else:
            self._q_goal = start + delta

    def _sample_task(self, task: TaskProblem) -> None:
        """The task's sample of this tick (the tip's pose as ``measured_cp``, without the
        message: ``Arm._measured_T``, the same bits)."""
        sim, t = self.sim, self.sim.time
        T_task_camera = self._T_task_camera()
        extra = task.task.scene_fields(sim.model, sim.data, self._scene_cache)
        contacts = self._contacts.measure(sim.model, sim.data) if sim.data.ncon else (0, 0.0)
        task.after_tick(
            t, self.psm._measured_T()[None], _ONE, T_task_camera,
            contacts=contacts[0], tool_force=contacts[1], **extra,
        )  # fmt: skip

    def _sample_recorded(self, task: TaskProblem, samples, ticks: range) -> None:
        """:meth:`_sample_task` of ticks a compiled period ran, from what it kept of the
        state after each (:class:`~davinci_sim.sim.live_period.PeriodSamples`; no contacts:
        the kernel stops at a step that leaves some): the tip's pose by the arm's own laws
        (forward kinematics, then its base frame's product), the camera's from the frames."""
        rows = slice(ticks.start, ticks.stop)
        T_base_tip, _ = fk.forward_kinematics_and_jacobian(self.psm.chain, samples.q[rows])
        T_camera_tip = samples.frames[rows, 1] @ T_base_tip  # (Arm._measured_T's, row by row)
        T_task_camera = self._start.task.T_task_cameras(samples.frames[rows, 0])
        task.after_ticks(samples.t[rows], T_camera_tip, T_task_camera)

    @property
    def _contacts(self):
        c = getattr(self, "_contacts_probe", None)
        if c is None:
            from davinci_sim.tasks import InstrumentContacts

            c = self._contacts_probe = InstrumentContacts.of_task(self.sim.model,
                                                                  self._start.task)  # fmt: skip
        return c

    def _observation(self, T: np.ndarray, T_task_camera, feats) -> dict[str, np.ndarray]:
        """The observation at the tip pose ``T`` (camera frame) and the camera's pose in the
        task's frame ``T_task_camera`` (None for Reach), both as they are now, with the
        problem's ``feats`` there (``problem.features``)."""
        arm = self.arm
        obs = {  # (measured_js' position and velocity, without the messages)
            "joint_position": arm._q(),
            "joint_velocity": arm._qd(),
            "jaw": np.array([self.psm.jaw.measured_jp()], dtype=float),
            "tip_position": T[:3, 3].copy(),
            "tip_orientation": orientation_features(T[:3, :3]),
            "setpoint": (
                self._goal if self.config.action_space == "cartesian" else self._q_goal
            ).copy(),
        }
        obs.update(self._object_observation(T_task_camera, (self._start.psm,)))
        obs.update({k: v[0] for k, v in feats.items()})
        if self.config.images:
            w, h = self.config.image_size
            obs["left"], obs["right"] = self.sim.render_stereo(w, h)
        return obs

    def _object_observation(self, T_task_camera, arms: tuple[str, ...]) -> dict:
        """The task's objects as the arms ``arms`` see them (:mod:`davinci_sim.envs.objects`;
        none for a task without objects)."""
        task = self._start.task
        if task is None or task.objects_probe(self.sim.model, self._scene_cache) is None:
            return {}
        fields = task.scene_fields(self.sim.model, self.sim.data, self._scene_cache)
        return object_features(task, fields, np.linalg.inv(T_task_camera), arms)

    def _faulted(self) -> bool:
        """Whether an arm the actions move is in FAULT (the episode then terminates)."""
        return self.arm.operating_state().state == ops.FAULT
