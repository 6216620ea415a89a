"""``davinci-sim serve``: a simulation with its ROS interfaces, assembled from options.

One function, :func:`serve`, builds the simulation (optionally with the surgeon console and
its teleoperations, issue 3), runs it in its loop (a thread of this process, or its own
process with the process runner when available), and starts what the options ask for: the
rosbridge server with the dVRK, console and endoscope nodes, the UDP streams, the client
mode. It runs until ``stop`` is set (Ctrl-C in the CLI) or ``duration`` passes, then stops
everything in reverse order.
"""

from __future__ import annotations

import functools
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

from davinci_sim.bridge.rosbridge.config import BridgeConfig

_log = logging.getLogger("davinci_sim.bridge")


@dataclass(frozen=True)
class ServeOptions:
    """Everything ``davinci-sim serve`` can be told."""

    scene: str = "full"
    keyframe: str = "surgical"
    seed: int = 0
    real_time: bool = True
    home: bool = False
    """Enable and home every arm at start."""
    server: bool = True
    """Run the rosbridge server (off: client mode and/or UDP only)."""
    bridge: BridgeConfig = field(default_factory=BridgeConfig)
    rate: float = 100.0
    tf_rate: float = 50.0
    images: Literal["jpeg", "raw", "both", "none"] = "jpeg"
    image_rate: float = 30.0
    rig: str = "jhu_daVinci"
    udp: bool = False
    udp_ports: dict[str, int] = field(default_factory=dict)
    udp_ip: str = "127.0.0.1"
    ros_connect: str | None = None
    namespace: str = "/sim"
    remote_ros_version: Literal[1, 2] = 2
    duration: float | None = None
    console: bool = False
    """Install the surgeon console and teleoperations (MTMs as network devices fed by the
    client mode when ``ros_connect`` is set, else the simulated MTMs)."""
    runner: Literal["thread", "process"] = "thread"
    """Loop in a thread of this process, or in its own process (issue 3's runner)."""
    task: str | None = None
    """A training task (name or file) to do at the console: its path drawn in the scene,
    its fixture in the haptic loop, its repetitions measured (implies ``console``)."""
    condition: str | None = None
    """The task's condition: a condition name of the task or ``B:G_max`` (viscous guidance;
    None: the task's own fixture)."""
    task_log: str | None = None
    """CSV file each finished repetition is appended to."""


def task_condition(task, condition: str | None) -> dict | str | None:
    """``--condition``: a condition name of ``task``, or ``B:G_max`` for viscous guidance."""
    if condition is None or condition in {c.get("name") for c in task.conditions}:
        return condition
    try:
        B, G = (float(x) for x in condition.split(":"))
    except ValueError:
        names = [c.get("name") for c in task.conditions]
        raise ValueError(
            f"condition {condition!r} is neither one of {task.name!r}'s ({names}) nor B:G_max"
        ) from None
    return {"type": "viscous", "B": B, "G_max": G}


def build_simulation(
    scene: str, keyframe: str, seed: int, home: bool, console: bool, network_mtms: bool,
    qpos_probe: bool, task: str | None = None, condition: str | None = None,
    task_log: str | None = None,
):  # fmt: skip
    """The simulation of :func:`serve` (top level and picklable for the process runner)."""
    from davinci_sim.bridge.endoscope import QposProbe
    from davinci_sim.sim.simulation import Simulation

    path_task = None
    if task is not None:
        from davinci_sim.tasks import add_path_visual, load_task

        path_task = load_task(task)
        task_condition(path_task, condition)  # a bad condition fails before the model is built
    sim = Simulation(
        scene,
        seed=seed,
        keyframe=keyframe,
        edit_spec=None if path_task is None else lambda spec: add_path_visual(spec, path_task),
    )
    if console or path_task is not None:
        from davinci_sim.console.setup import install_console
        from davinci_sim.devices.network import NetworkDevice

        devices = {}
        if network_mtms:
            devices = {m: NetworkDevice(f"{m}/device") for m in ("MTML", "MTMR") if m in sim.arms}
        install_console(sim, devices=devices)
    if path_task is not None:
        from davinci_sim.tasks.session import install_task

        install_task(sim, path_task, condition=task_condition(path_task, condition), log=task_log)
    if qpos_probe:
        sim.add_component(QposProbe(sim))
    if home:
        for arm in sim.arms.values():
            arm.state_command("enable")
            arm.state_command("home")
    return sim


def serve(
    options: ServeOptions,
    *,
    stop: threading.Event | None = None,
    on_ready: Callable[[dict], None] | None = None,
) -> dict:
    """Run until ``stop`` is set or ``options.duration`` passes; returns final statistics.

    ``on_ready(info)`` is called once everything listens, with the server URL, the UDP
    ports and the client-mode URL.
    """
    from davinci_sim.bridge.client_mode import ClientModeConfig, RosClientMode
    from davinci_sim.bridge.console_node import ConsoleNode
    from davinci_sim.bridge.dvrk_node import DvrkNode
    from davinci_sim.bridge.endoscope import EndoscopeNode
    from davinci_sim.bridge.rosbridge.server import RosbridgeServer
    from davinci_sim.bridge.system_node import SystemNode
    from davinci_sim.bridge.task_node import TaskNode
    from davinci_sim.bridge.udp import UdpStreamer, default_streams
    from davinci_sim.sim.handle import ThreadedSimulation

    stop = stop or threading.Event()
    process = options.runner == "process"
    factory = functools.partial(
        build_simulation, options.scene, options.keyframe, options.seed, options.home,
        options.console, options.ros_connect is not None, options.images != "none",
        options.task, options.condition, options.task_log,
    )  # fmt: skip
    # Snapshots cost ~0.2 ms of the loop for the full system with the console: take them at
    # the publish rate, not every tick, so the 1 kHz loop keeps its margin.
    period = 1.0 / max(options.rate, 1.0)
    sim = None
    if process:
        from davinci_sim.sim.runtime.process import ProcessSimulation

        # Images: our render worker (render + JPEG in one process) from the published qpos.
        handle = ProcessSimulation(factory, real_time=options.real_time, snapshot_period=period)
    else:
        sim = factory()
        handle = ThreadedSimulation(sim, real_time=options.real_time, snapshot_period=period)
    arm_names = set()
    started: list = []
    info: dict = {}
    try:
        handle.start()
        started.append(handle)
        arm_names = set(handle.snapshot().arms)
        if options.server:
            nodes: list = [
                DvrkNode(handle, rate=options.rate, tf_rate=options.tf_rate),
                ConsoleNode(handle, rate=options.rate),
                TaskNode(handle),
                SystemNode(handle),
            ]
            if options.images != "none":
                nodes.append(EndoscopeNode(handle, options.scene, rate=options.image_rate,
                                           encoding=options.images, rig=options.rig,
                                           handle_frames=False))  # fmt: skip
            server = RosbridgeServer(options.bridge, nodes=nodes).start()
            started.append(server)
            info["url"] = server.url
        if options.udp:
            arms = [a for a in ("PSM1", "PSM2", "PSM3", "ECM", "MTML", "MTMR") if a in arm_names]
            streams = default_streams(arms, options.udp_ports)
            streams = [
                type(s)(s.arm, s.port, ip=options.udp_ip) if options.udp_ip != s.ip else s
                for s in streams
            ]
            udp = UdpStreamer(handle, streams).start()
            started.append(udp)
            info["udp"] = {s.arm: (s.ip, s.port, udp.local_port(s.arm)) for s in streams}
        if options.ros_connect:
            client = RosClientMode(
                handle,
                ClientModeConfig(
                    options.ros_connect,
                    namespace=options.namespace,
                    ros_version=options.remote_ros_version,
                    mtms=tuple(n for n in ("MTML", "MTMR") if n in arm_names) or ("MTML", "MTMR"),
                ),
            ).start()
            started.append(client)
            info["ros_connect"] = options.ros_connect
        if on_ready is not None:
            on_ready(info)
        end = None if options.duration is None else time.monotonic() + options.duration
        t0_wall, t0_sim = time.monotonic(), handle.snapshot().time
        while not stop.wait(0.1):
            if end is not None and time.monotonic() >= end:
                break
        wall = time.monotonic() - t0_wall
        info["sim_over_wall"] = (handle.snapshot().time - t0_sim) / wall if wall > 0 else 0.0
        stats = getattr(handle, "period_statistics", None)
        if callable(stats):
            info["period_statistics"] = stats()
    finally:
        for part in reversed(started):
            try:
                part.stop()
            except Exception:
                _log.exception("stopping %r failed", part)
        if sim is not None:
            sim.close()
    return info
