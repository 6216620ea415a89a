"""What an environment is built from and its start: one frozen :class:`EnvConfig`, and
:func:`build_start`, which builds the simulation once and brings it to the state every
episode starts from (``reset`` restores it with
:meth:`~davinci_sim.sim.simulation.Simulation.set_state`: microseconds, no rebuild).

The scene is reduced to what the exercise needs: the task's PSM (or PSM1) and the ECM (the
camera frame), no surgeon console (actions replace the master) and, unless asked, no patient
(nothing to touch in free space, which also spares the contact search).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from davinci_sim.model.config import SceneConfig
from davinci_sim.sim.simulation import Simulation
from davinci_sim.sim.state import SimState

#: Where the Reach task's tool starts, world (cart) frame, m: the middle of the seed's path
#: (seen by the ``surgical`` keyframe's endoscope, within PSM1's reach).
REACH_START_WORLD = (0.080, 1.185, 0.805)

ACTION_SPACES = ("cartesian", "joint")
#: The tool comes down to the start from this far above it (world z), m.
APPROACH_HEIGHT = 0.03


@dataclass(frozen=True)
class EnvConfig:
    """One environment's settings (the keyword arguments of ``gymnasium.make``)."""

    task: str | None = None
    """A task name or file (:func:`~davinci_sim.tasks.load_task`); None: the Reach task."""
    action_space: str = "cartesian"
    """``cartesian``: tip displacement in the camera frame + jaw; ``joint``: joint
    displacements of the arm + jaw (:mod:`davinci_sim.envs.control`)."""
    control_hz: float = 50.0
    """Actions per simulated second (the physics and servo tick at 1 kHz underneath)."""
    max_step: float = 0.002
    """Cartesian: largest tip displacement per action and axis, m (0.1 m/s at 50 Hz)."""
    max_joint_step: float = 0.02
    """Joint: largest displacement per action, rad (prismatic joints: this / 10, m)."""
    max_episode_steps: int = 100
    """Actions before an episode is truncated (Reach: 2 s at 50 Hz)."""
    workspace: float = 0.04
    """Margin of the box the tip's goal is kept in around the start and the task's points,
    m (camera axes)."""
    images: bool = False
    """Add the stereo endoscope images (``left``, ``right``) to the observations."""
    image_size: tuple[int, int] = (160, 120)
    """Width and height of the images, pixels."""
    include_patient: bool = False
    """The operating table and phantom in the scene (contacts with the tissue)."""
    seed: int = 0
    """The simulation's own seed (its generator; episodes draw from ``reset(seed=)``)."""
    reach_radius: float = 0.025
    """Reach: the target is drawn uniformly within ± this of the start, per axis, m."""
    reach_tolerance: float = 0.003
    """Reach: within this distance of the target the episode is a success, m."""
    arms: tuple[str, ...] | None = None
    """The PSMs the actions move, in order (each its own slice of the action and row of the
    per-arm observations): the task's PSM and its other instruments (peg transfer, the
    needle exercises: ``("PSM1", "PSM2")``); None: the task's PSM alone (or the ECM for
    camera targeting). Given, or with ``rotation``, the environment is an
    :class:`~davinci_sim.envs.instruments.InstrumentsEnv` (``gymnasium.make`` picks it)."""
    rotation: bool = False
    """Cartesian actions also turn each moved tool: three more numbers per arm, a rotation
    vector about the camera's axes in units of ``max_rotation_step`` (otherwise the
    orientation the tool has at the start is held)."""
    max_rotation_step: float = 0.05
    """Rotation: largest turn per action and axis, rad (2.5 rad/s at 50 Hz)."""
    joint_errors: Any = ()
    """The robot's kinematic inaccuracy, per PSM (a mapping or pairs of PSM name and its
    first three joints' errors, rad, rad, m: :attr:`SceneConfig.joint_errors
    <davinci_sim.model.config.SceneConfig.joint_errors>`, e.g. from
    :func:`~davinci_sim.model.config.random_joint_errors`). The observed tips are what the
    arms report (their nominal kinematics), the objects where they are: an agent must see
    where its tools are, as on the AccelNet challenge's perturbed robots."""

    def __post_init__(self) -> None:
        if self.action_space not in ACTION_SPACES:
            raise ValueError(
                f"action_space must be one of {ACTION_SPACES}, got {self.action_space!r}"
            )
        names = ("max_step", "max_joint_step", "workspace", "reach_radius", "reach_tolerance",
                 "max_rotation_step")  # fmt: skip
        for name in names:
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        if not (isinstance(self.max_episode_steps, int) and self.max_episode_steps >= 1):
            raise ValueError(
                f"max_episode_steps must be an int >= 1, got {self.max_episode_steps!r}"
            )
        if self.arms is not None:
            arms = tuple(self.arms) if isinstance(self.arms, list | tuple) else ()
            if not arms or not all(isinstance(a, str) and a.startswith("PSM") for a in arms) \
                    or len(set(arms)) != len(arms):  # fmt: skip
                raise ValueError(f"arms must be distinct PSM names, e.g. ('PSM1', 'PSM2'), "
                                 f"got {self.arms!r}")  # fmt: skip
            object.__setattr__(self, "arms", arms)
        errors = self.joint_errors
        pairs = errors.items() if isinstance(errors, dict) else errors
        try:
            object.__setattr__(self, "joint_errors",
                               tuple((str(n), tuple(e)) for n, e in pairs))  # fmt: skip
        except (TypeError, ValueError):
            raise ValueError("joint_errors must map PSM names to three errors (rad, rad, m), "
                             f"got {errors!r}") from None  # fmt: skip
        if self.rotation and self.action_space != "cartesian":
            raise ValueError("rotation=True turns the tool with Cartesian actions; joint "
                             "actions turn the wrist's joints already")  # fmt: skip
        w, h = self.image_size
        if not (isinstance(w, int) and isinstance(h, int) and 8 <= w <= 1920 and 8 <= h <= 1080):
            raise ValueError(
                f"image_size must be (width, height) in pixels, got {self.image_size!r}"
            )

    @property
    def per_instrument(self) -> bool:
        """Whether the actions name the instruments they move or turn them
        (:class:`~davinci_sim.envs.instruments.InstrumentsEnv`'s)."""
        return self.rotation or self.arms is not None


@dataclass
class EnvStart:
    """A simulation at the start of an episode and what the environments read from it."""

    sim: Simulation
    state: SimState
    """The start: every reset restores it."""
    task: object | None
    """The :class:`~davinci_sim.tasks.Task` (None: Reach)."""
    psm: str
    """The instrument arm whose tip is observed (the task's PSM, or PSM1)."""
    arm: str
    """The arm the actions move (the PSM; the ECM for camera targeting)."""
    T_world_camera: np.ndarray
    """The camera in the world at the start, 4x4, m."""
    T_task_camera: np.ndarray
    """The camera in the task's frame at the start, 4x4, m (identity for Reach)."""
    p_start_camera: np.ndarray
    """(3,) the tip's goal at the start (where the actions' goal starts), camera frame, m."""
    R_goal: np.ndarray
    """(3, 3) the tip's orientation goal in the camera frame (held: actions move the tip)."""
    workspace: tuple[np.ndarray, np.ndarray]
    """(lo, hi) (3,) each: the box the tip's goal is kept in, camera frame, m — the start
    (Reach) or the task's points (its ``check_points``) and the start, ± ``workspace``."""


def scene_of(config: EnvConfig, psm: str, task=None) -> SceneConfig:
    """The reduced scene: ``psm``, the task's other instruments (they hold still: the
    actions move one arm) and the ECM; no console; the patient if asked."""
    arms = (psm, *getattr(task, "instruments", ()), "ECM")
    return SceneConfig(
        arms=tuple(dict.fromkeys(arms)), include_console=False,
        include_patient=config.include_patient, joint_errors=config.joint_errors,
    )  # fmt: skip


def build_start(config: EnvConfig) -> EnvStart:
    """Build the scene of ``config`` and bring it to the start of an episode: the arms
    enabled and homed, the tool tip at the task's start (Reach: :data:`REACH_START_WORLD`)
    with the orientation it has after homing, every setpoint where its joint is.

    Raises:
        RuntimeError: if an arm cannot home or the tool cannot reach the start.
    """
    from davinci_sim.system import SystemDescription, TaskDescription, new_simulation
    from davinci_sim.tasks import load_task

    task = None if config.task is None else load_task(config.task)
    psm = "PSM1" if task is None else task.teleop.psm
    keyframe = "surgical" if task is None else task.teleop.keyframe
    scene = scene_of(config, psm, task)
    if task is None:
        sim = Simulation(scene, seed=config.seed, keyframe=keyframe)
    else:
        description = SystemDescription(
            scene=scene, keyframe=keyframe, seed=config.seed, runner="none",
            task=TaskDescription(config.task),
        )  # fmt: skip
        sim = new_simulation(description, task)
    arm = "ECM" if task is not None and task.kind == "camera_targeting" else psm
    ecm = sim.arms["ECM"]
    q_ecm = ecm.measured_jp().copy()
    for name in dict.fromkeys((psm, arm, *getattr(task, "instruments", ()))):
        a = sim.arms[name]
        a.state_command("enable")
        a.state_command("home")
        if not sim.run_until(lambda a=a: a.is_homed() and not a.is_busy(), 30.0):
            raise RuntimeError(f"{name} did not home")
    if arm == "ECM":  # homing moved the endoscope: back to the keyframe's view
        ecm.move_jp(q_ecm)
        if not sim.run_until(lambda: not ecm.is_busy(), 30.0):
            raise RuntimeError("the ECM cannot return to the keyframe's pose")
    T_world_camera = sim.T_cart_camera().copy()
    if task is None:
        T_task_camera = np.eye(4)
        p_world = np.append(REACH_START_WORLD, 1.0)
        p_start = (np.linalg.inv(T_world_camera) @ p_world)[:3]
    else:
        T_task_camera = task.T_task_camera(T_world_camera)
        p_start = (np.linalg.inv(T_task_camera) @ np.append(task.start, 1.0))[:3]
    tool = sim.arms[psm]
    goal = tool.setpoint_cp().T.copy()
    # Through a point above the start (world up), so that the joint-space move does not
    # sweep the tool through the task's objects (the peg board).
    up = np.linalg.inv(T_world_camera)[:3, :3] @ np.array([0.0, 0.0, APPROACH_HEIGHT])
    for p in (p_start + up, p_start):
        goal[:3, 3] = p
        result = tool.move_cp(goal)
        if not result or not sim.run_until(lambda: not tool.is_busy(), 30.0):
            raise RuntimeError(f"{psm} cannot reach the start {p_start}: {result.message}")
    sim.run_for(0.2)  # settle
    faulted = [n for n, a in sim.arms.items() if a.operating_state().state == "FAULT"]
    if faulted:
        raise RuntimeError(f"the arms {faulted} faulted while going to the start")
    if task is None:
        points = p_start[None]
    else:
        T_camera_task = np.linalg.inv(T_task_camera)
        pts = np.vstack([np.asarray(task.check_points, dtype=float).reshape(-1, 3), task.start])
        points = np.vstack([pts @ T_camera_task[:3, :3].T + T_camera_task[:3, 3], p_start])
    box = (points.min(axis=0) - config.workspace, points.max(axis=0) + config.workspace)
    return EnvStart(
        sim=sim, state=sim.get_state(), task=task, psm=psm, arm=arm,
        T_world_camera=T_world_camera, T_task_camera=np.asarray(T_task_camera, dtype=float),
        p_start_camera=np.asarray(p_start, dtype=float).copy(), R_goal=goal[:3, :3].copy(),
        workspace=box,
    )  # fmt: skip
