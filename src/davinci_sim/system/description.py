"""What a running system is made of, as one frozen value: :class:`SystemDescription`.

A description is plain data (picklable, comparable): the scene and its initial state, the
surgeon console and the device behind each MTM, the teleoperation settings, the training
task and its condition, how the loop runs (a thread of this process or its own process, real
time or as fast as possible) and what it publishes for the viewers (snapshots, the joint
positions renderers need, stereo frames rendered by the runner). :func:`~davinci_sim.system.
build.build_system` turns it into a running system; ``serve``, the demo, the study's trial
set-up and the web console all describe what they want this way.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

from davinci_sim.console.teleop_config import SIMULATED_SYSTEM, TeleopECMConfig, TeleopPSMConfig
from davinci_sim.devices.device import DVRK_WATCHDOG
from davinci_sim.devices.safety import WrenchLimits
from davinci_sim.model.config import SceneConfig

if TYPE_CHECKING:
    from davinci_sim.tasks.base import Task

#: The dVRK socket streamer's default UDP ports of the MTMs (dvrk.md 5).
UDP_PORTS = {"MTML": 48054, "MTMR": 48055}


@dataclass(frozen=True)
class DeviceDescription:
    """The input device behind one MTM of the console.

    ``simulated``: the console model's MTM moved by a simulated hand
    (:class:`~davinci_sim.devices.SimulatedMTM`); ``network``: input pushed by a client (a
    ROS console in client mode, a web console; :class:`~davinci_sim.devices.NetworkDevice`);
    ``udp``: the dVRK socket-streamer JSON format (:class:`~davinci_sim.devices.UDPJSONDevice`).
    """

    kind: Literal["simulated", "network", "udp"] = "simulated"
    host: str = "127.0.0.1"
    """``udp``: the interface to listen on."""
    port: int | None = None
    """``udp``: the port to listen on (None: the dVRK default of the MTM, 48054/48055)."""
    watchdog: float | None = DVRK_WATCHDOG
    """``network``/``udp``: input older than this (s) is stale (None: never)."""

    def __post_init__(self) -> None:
        if self.kind not in ("simulated", "network", "udp"):
            raise ValueError(f"device kind must be simulated, network or udp, not {self.kind!r}")


@dataclass(frozen=True)
class ConsoleDescription:
    """The surgeon console: devices, teleoperations and haptics
    (:func:`~davinci_sim.console.install_console`)."""

    devices: Mapping[str, DeviceDescription] = field(default_factory=dict)
    """MTM name (``MTML``, ``MTMR``) -> its device; an MTM not listed is simulated."""
    teleop: TeleopPSMConfig = SIMULATED_SYSTEM
    """Settings of every PSM teleoperation."""
    scale: float | None = None
    """Motion scale MTM -> PSM replacing ``teleop.scale`` (None: keep it)."""
    ecm: TeleopECMConfig | None = None
    limits: WrenchLimits | None = None
    """Safety limits of the simulated MTMs (None: the default)."""
    contact_feedback: bool = False
    operator_present: bool = False
    teleop_enabled: bool = False
    scripted_hands: bool = False
    """The simulated hands draw circles once their teleoperation follows (demos, benchmarks)."""
    hand_inputs: tuple[str, ...] = ()
    """MTMs whose simulated hand a rate input steers (keyboard, gamepad: the web console),
    through a :class:`~davinci_sim.devices.hand_input.HandInput` component ``<MTM>/hand``;
    their teleoperations lock rotation (the input moves the tool, not its orientation)."""

    @property
    def teleop_config(self) -> TeleopPSMConfig:
        """``teleop`` with ``scale`` applied."""
        return self.teleop if self.scale is None else self.teleop.replace(scale=self.scale)


@dataclass(frozen=True)
class TaskDescription:
    """A training task done at the console (:func:`~davinci_sim.tasks.install_task`)."""

    task: str
    """Task name (``seed_path``) or task file."""
    condition: str | dict | None = None
    """A condition name of the task, ``B:G_max`` (viscous guidance) or a fixture entry;
    None: the task's own fixture."""
    log: str | None = None
    """CSV file each finished repetition is appended to."""
    draw: bool = True
    """Draw the path in the scene (the endoscope shows it, in every renderer)."""
    frame_view: float | None = None
    """Bring the endoscope to the task from this distance, m, once the ECM is homed
    (:meth:`~davinci_sim.tasks.session.TaskSession.frame_view`; the web console does);
    None: the camera stays at the keyframe's pose."""


@dataclass(frozen=True)
class SystemDescription:
    """Everything a running system is built from (see the module docstring)."""

    scene: str | SceneConfig = "full"
    """A scene name of :data:`davinci_sim.model.SCENES` or a ``SceneConfig``."""
    keyframe: str = "surgical"
    seed: int = 0
    console: ConsoleDescription | None = None
    """The surgeon console (None: none, unless ``task`` asks for one)."""
    task: TaskDescription | None = None
    """A training task at the console (implies a console: the default one if None)."""
    home: bool = False
    """Enable and home every arm at start."""
    runner: Literal["thread", "process", "none"] = "thread"
    """The loop in a thread of this process, in its own process, or none (the caller ticks
    the simulation itself, e.g. the demo)."""
    real_time: bool = True
    stepped: bool = False
    """Process runner, not real time: the loop ticks only the simulated time its handle's
    ``advance(seconds)`` asks for (a script that looks at each state before it acts then
    sees every state it asked for, at the machine's speed, however busy the machine is)."""
    start_paused: bool = False
    """The runner waits for ``handle.resume()`` before its first tick (inputs scheduled with
    ``handle.call_at`` first make a reproducible run)."""
    snapshot_period: float = 0.01
    """Sim time between the snapshots the runner publishes, s."""
    publish_qpos: bool = False
    """Put a copy of ``qpos`` in each snapshot (``extras["qpos"]``) for renderers fed from
    snapshots (the bridge's image topics)."""
    record_inputs: bool = False
    """Log every call the handle runs with its tick (:class:`~davinci_sim.sim.inputs.InputLog`,
    component ``inputs``): what a recording needs to replay the session through the physics."""
    render_hz: float | None = None
    """The runner renders the stereo endoscope at this rate in a render process
    (``handle.stereo_frame()``); None: it does not."""
    realtime_priority: int | None = None
    """Process runner: SCHED_FIFO priority of the loop process (1-99), as the dVRK runs its
    control loops; needs the privilege (root or CAP_SYS_NICE), else the loop runs at normal
    priority and the handle's ``info`` says why. None: normal priority."""
    loop_cpu: int | None = None
    """Process runner: pin the loop process to this CPU (None: the OS chooses)."""

    def __post_init__(self) -> None:
        if self.runner not in ("thread", "process", "none"):
            raise ValueError(f"runner must be thread, process or none, not {self.runner!r}")
        if not (math.isfinite(self.snapshot_period) and self.snapshot_period > 0):
            raise ValueError(f"snapshot_period must be > 0 s, got {self.snapshot_period!r}")
        if self.render_hz is not None and not (
            math.isfinite(self.render_hz) and self.render_hz > 0
        ):
            raise ValueError(f"render_hz must be > 0 or None, got {self.render_hz!r}")
        if self.render_hz is not None and self.runner == "none":
            raise ValueError("render_hz needs a runner (thread or process)")
        if self.stepped and (self.runner != "process" or self.real_time):
            raise ValueError("stepped needs the process runner and real_time=False")
        if self.realtime_priority is not None and not (1 <= self.realtime_priority <= 99):
            raise ValueError(f"realtime_priority must be in 1..99, got {self.realtime_priority}")

    @property
    def console_description(self) -> ConsoleDescription | None:
        """The console to install: ``console``, or the default one for a task."""
        if self.console is None and self.task is not None:
            return ConsoleDescription()
        return self.console

    def replace(self, **changes) -> SystemDescription:
        import dataclasses

        return dataclasses.replace(self, **changes)


def task_condition(task: Task, condition: str | dict | None) -> dict | str | None:
    """A task's condition from its description: a condition name of ``task`` (kept),
    ``B:G_max`` (viscous guidance, N·s/m : N) as a fixture entry, or a fixture entry written
    as a YAML mapping (``'{type: adaptive, mode: fading, B0: 40}'``, any kind).

    Raises:
        ValueError: if ``condition`` is neither.
    """
    if condition is None or isinstance(condition, dict):
        return condition
    if condition in {c.get("name") for c in task.conditions}:
        return condition
    if condition.lstrip().startswith("{"):
        import yaml

        try:
            entry = yaml.safe_load(condition)
        except yaml.YAMLError as e:
            raise ValueError(f"condition {condition!r} is not a YAML mapping: {e}") from None
        if not isinstance(entry, dict):
            raise ValueError(f"condition {condition!r} is not a YAML mapping")
        return entry
    try:
        B, G = (float(x) for x in condition.split(":"))
    except ValueError:
        names = [c.get("name") for c in task.conditions]
        raise ValueError(
            f"condition {condition!r} is neither one of {task.name!r}'s ({names}) nor B:G_max"
        ) from None
    return {"type": "viscous", "B": B, "G_max": G}
