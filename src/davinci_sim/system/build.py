"""Building a running system from a :class:`~davinci_sim.system.description.SystemDescription`.

The one assembly of the simulator, in the order every user needs it:

1. :func:`new_simulation` — the scene at its keyframe, with the task's path drawn;
2. :func:`install` — the console (devices, teleoperations, haptics), the scripted hands, the
   task session, the ``qpos`` publisher for renderers, the arms' homing commands
   (:func:`install_console_of` is the console part alone, for callers that prepare the arms
   first: the study's trial set-up);
3. :func:`build_simulation` — 1 and 2; top level and picklable with its description, so it
   is also the process runner's factory;
4. :func:`build_system` — 3 behind a runner (a thread, a process, or none), with the stereo
   render pipeline if asked: a :class:`System` that owns them and stops them.

:func:`scene_model` compiles the same model as 1 (the task's drawing included) without the
simulation: the render process builds its model with it, so the endoscope images show what
the simulation has.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from davinci_sim.system.description import (
    UDP_PORTS,
    ConsoleDescription,
    DeviceDescription,
    SystemDescription,
    task_condition,
)

if TYPE_CHECKING:
    import mujoco

    from davinci_sim.console.console import Console
    from davinci_sim.devices.device import MasterDevice
    from davinci_sim.sim.simulation import Simulation
    from davinci_sim.tasks.base import Task


def load_description_task(description: SystemDescription) -> Task | None:
    """The task of ``description`` (None: no task), its condition checked.

    Raises:
        TaskError, ValueError: an unknown task, or a condition it does not have.
    """
    if description.task is None:
        return None
    from davinci_sim.tasks import load_task

    task = load_task(description.task.task)
    task_condition(task, description.task.condition)  # a bad condition fails before building
    return task


def _edit_spec(description: SystemDescription, task: Task | None):
    if task is None or not description.task.draw:
        return None

    def draw(spec) -> None:
        # The labels face the endoscope of the start keyframe (and a camera-frame task is
        # placed there): drawn facing a fixed world direction, they read mirrored when the
        # endoscope looks the other way.
        from davinci_sim.model import resolve_scene

        baseline = resolve_scene(description.scene).endoscope.baseline_m
        T = keyframe_camera(spec, description.keyframe, baseline)
        task.draw(spec, T_world_camera=T)

    return draw


def keyframe_camera(spec, keyframe: str, baseline: float):
    """The endoscope's camera frame (the ECM tip, dvrk.md 1.6: x to the image's left, y up, z
    into the scene) in the world at ``keyframe``, 4x4, m, from a compile of ``spec`` and the
    stereo ``baseline`` (m); None if the scene has no endoscope or no such keyframe."""
    import mujoco
    import numpy as np

    from davinci_sim.geometry.se3 import rot_y, transform

    model = spec.compile()
    cam = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, "ECM/left")
    key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, keyframe)
    if cam < 0 or key < 0:
        return None
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, key)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)  # (camera poses are not part of mj_kinematics)
    T_world_left = transform(data.cam_xmat[cam].reshape(3, 3), data.cam_xpos[cam])
    # model/cameras.T_tip_camera: left = tip · translate(+b/2 along x) · rot_y(π).
    T_left_tip = transform(rot_y(np.pi)) @ transform(p=[-baseline / 2, 0.0, 0.0])
    return T_world_left @ T_left_tip


def new_simulation(description: SystemDescription, task: Task | None = None) -> Simulation:
    """The scene of ``description`` at its keyframe and seed, the task's path drawn (pass
    ``task`` if already loaded)."""
    from davinci_sim.sim.simulation import Simulation

    if task is None:
        task = load_description_task(description)
    return Simulation(
        description.scene,
        seed=description.seed,
        keyframe=description.keyframe,
        edit_spec=_edit_spec(description, task),
    )


def scene_model(description: SystemDescription) -> mujoco.MjModel:
    """The compiled model of ``description``'s scene with the task's drawing: what
    :func:`new_simulation` compiles (the render process builds its model with this)."""
    from davinci_sim.model import build_spec

    spec = build_spec(description.scene)
    edit = _edit_spec(description, load_description_task(description))
    if edit is not None:
        edit(spec)
    return spec.compile()


def make_device(sim: Simulation, mtm: str, device: DeviceDescription, console: ConsoleDescription):
    """The :class:`~davinci_sim.devices.MasterDevice` of ``mtm`` (component ``<mtm>/device``)."""
    name = f"{mtm}/device"
    if device.kind == "simulated":
        from davinci_sim.devices.simulated import SimulatedMTM

        return SimulatedMTM(sim, mtm, limits=console.limits)
    if device.kind == "network":
        from davinci_sim.devices.network import NetworkDevice

        return NetworkDevice(name, watchdog=device.watchdog, dt=sim.dt)
    from davinci_sim.devices.udp import UDPJSONDevice

    port = device.port if device.port is not None else UDP_PORTS[mtm]
    return UDPJSONDevice(name, host=device.host, port=port, watchdog=device.watchdog, dt=sim.dt)


def install_console_of(sim: Simulation, description: SystemDescription) -> Console | None:
    """Install ``description``'s console on ``sim`` (None if it has none): its devices,
    teleoperations and haptic loop, then the scripted hands if asked."""
    console_description = description.console_description
    if console_description is None:
        return None
    from davinci_sim.console.setup import MTM_NAMES, add_scripted_hands, install_console

    c = console_description
    unknown = sorted(set(c.devices) - set(MTM_NAMES))
    if unknown:
        raise ValueError(f"devices for unknown MTMs {unknown}; MTMs: {list(MTM_NAMES)}")
    devices: dict[str, MasterDevice] = {
        mtm: make_device(sim, mtm, d, c)
        for mtm, d in c.devices.items()
        if d.kind != "simulated" or mtm in sim.arms
    }
    console = install_console(
        sim,
        devices=devices,
        teleop_config=c.teleop_config,
        ecm_config=c.ecm,
        limits=c.limits,
        contact_feedback=c.contact_feedback,
        operator_present=c.operator_present,
        teleop_enabled=c.teleop_enabled,
    )
    if c.scripted_hands:
        add_scripted_hands(sim, console)
    for mtm in c.hand_inputs:
        from davinci_sim.devices.hand_input import HandInput
        from davinci_sim.devices.simulated import SimulatedMTM

        device = sim.components.get(f"{mtm}/device")
        if not isinstance(device, SimulatedMTM):
            raise ValueError(f"a hand input needs {mtm} as a simulated MTM, got {device!r}")
        sim.add_component(HandInput(device), before=device.name)
        # A rate input moves the handle, not its orientation: the teleoperations it drives
        # lock rotation (dvrk.md 4.2, lock_rotation: the PSM keeps its tool's orientation,
        # the MTM's motors hold the wrist), so a relaxed wrist cannot drift the tool into an
        # orientation the MTM can no longer align with.
        for teleop in console.psm_teleops.values():
            if teleop.mtm_name == mtm:
                teleop.lock_rotation(True)
    return console


def install(sim: Simulation, description: SystemDescription, task: Task | None = None):
    """Install on ``sim`` what ``description`` asks beyond the scene: console, task session,
    the ``qpos`` publisher, the arms' enable and home commands."""
    install_console_of(sim, description)
    if description.task is not None:
        from davinci_sim.tasks.session import install_task

        if task is None:
            task = load_description_task(description)
        t = description.task
        session = install_task(sim, task, condition=task_condition(task, t.condition), log=t.log,
                               frame_view=t.frame_view)  # fmt: skip
        mtm = task.teleop.mtm
        if mtm in description.console_description.hand_inputs:
            from davinci_sim.operators.live import SyntheticOperator

            device = sim.components[f"{mtm}/device"]
            operator = SyntheticOperator(session, device, seed=description.seed)
            sim.add_component(operator, before=device.name)
    if description.publish_qpos:
        from davinci_sim.sim.runtime.render import QposProbe

        sim.add_component(QposProbe(sim))
    if description.record_inputs:
        from davinci_sim.sim.inputs import InputLog

        sim.add_component(InputLog(sim))
    if description.home:
        for arm in sim.arms.values():
            arm.state_command("enable")
            arm.state_command("home")


def build_simulation(description: SystemDescription) -> Simulation:
    """The simulation of ``description`` with everything installed (a picklable factory:
    ``functools.partial(build_simulation, description)``)."""
    task = load_description_task(description)
    sim = new_simulation(description, task)
    install(sim, description, task)
    return sim


@dataclass
class System:
    """A running system: the simulation behind its runner (see :func:`build_system`).

    ``handle`` is the :class:`~davinci_sim.sim.handle.SimHandle` every outside user goes
    through; ``sim`` is the simulation itself when it lives in this process (thread runner:
    owned by the loop's thread once started; no runner: the caller ticks it), None with the
    process runner.
    """

    description: SystemDescription
    sim: Simulation | None
    handle: Any

    @property
    def model_source(self):
        """A picklable callable returning the compiled model (task drawing included), for
        renderers in other processes."""
        return functools.partial(scene_model, self.description)

    def stereo_frame(self):
        """The runner's latest stereo pair (``render_hz`` must be set), or None yet."""
        return self.handle.stereo_frame()

    def frames(self, rate_hz: float = 30.0, *, use_handle: bool | None = None):
        """Stereo frames for a viewer (a web console's view, the bridge's image topics):
        the runner's renderer if it has one, else one started on first use and fed from
        snapshots; the system's model, the task's drawing included
        (:class:`~davinci_sim.sim.runtime.render.StereoFrames`; stop it when done)."""
        from davinci_sim.sim.runtime.render import StereoFrames

        return StereoFrames(self.handle, self.description.scene, rate_hz,
                            model=self.model_source, use_handle=use_handle)  # fmt: skip

    def start(self) -> System:
        if self.handle is not None:
            self.handle.start()
        return self

    def stop(self):
        """Stop the runner (and its renderer) and release the simulation; returns the
        runner's final period statistics (None without a runner)."""
        stats = None
        if self.handle is not None:
            stopped = self.handle.stop()
            stats = stopped if stopped is not None else _statistics(self.handle)
        if self.sim is not None:
            self.sim.close()
        return stats

    def __enter__(self) -> System:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


def _statistics(handle):
    stats = getattr(handle, "period_statistics", None)
    try:
        return stats() if callable(stats) else None
    except RuntimeError:  # a runner that never started has none
        return None


def build_system(description: SystemDescription, *, start: bool = False) -> System:
    """The system of ``description``: the simulation built here (thread runner, no runner)
    or in the loop process (process runner), behind its runner; started if ``start``."""
    if description.runner == "process":
        from davinci_sim.sim.runtime.process import ProcessSimulation

        handle = ProcessSimulation(
            functools.partial(build_simulation, description),
            real_time=description.real_time,
            snapshot_period=description.snapshot_period,
            render_hz=description.render_hz,
            render_model=functools.partial(scene_model, description),
            mirror_edit=_edit_spec(description, load_description_task(description)),
            start_paused=description.start_paused,
            realtime_priority=description.realtime_priority,
            loop_cpu=description.loop_cpu,
            stepped=description.stepped,
        )
        system = System(description, None, handle)
    else:
        sim = build_simulation(description)
        handle = None
        if description.runner == "thread":
            from davinci_sim.sim.handle import ThreadedSimulation

            handle = ThreadedSimulation(
                sim,
                real_time=description.real_time,
                snapshot_period=description.snapshot_period,
                render_hz=description.render_hz,
                render_model=functools.partial(scene_model, description),
                start_paused=description.start_paused,
            )
        system = System(description, sim, handle)
    return system.start() if start else system
