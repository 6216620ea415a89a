"""``davinci-sim serve``: a simulation with its ROS interfaces, assembled from options.

One function, :func:`serve`, describes the system its options ask for
(:func:`serve_description`: the scene, optionally the surgeon console and a training task, the
runner), builds and runs it with the one assembly (:func:`davinci_sim.system.build_system`:
a thread of this process, or the loop in its own process), and adds the bridge's parts: the
rosbridge server with the dVRK, console and endoscope nodes, the UDP streams, the client
mode. It runs until ``stop`` is set (Ctrl-C in the CLI) or ``duration`` passes, then stops
everything in reverse order.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

from davinci_sim.bridge.rosbridge.config import BridgeConfig
from davinci_sim.model.config import SceneConfig
from davinci_sim.sim.runtime.loop import frozen_heap
from davinci_sim.system.description import task_condition  # noqa: F401 (the CLI's check)

_log = logging.getLogger("davinci_sim.bridge")


@dataclass(frozen=True)
class ServeOptions:
    """Everything ``davinci-sim serve`` can be told."""

    scene: str | SceneConfig = "full"
    """A scene name or configuration (e.g. with the robot inaccuracy, ``joint_errors``)."""
    keyframe: str = "surgical"
    seed: int = 0
    real_time: bool = True
    stepped: bool = False
    """Process runner, ``real_time`` off: the simulation ticks only when asked (the web
    console's ``advance`` op; :attr:`~davinci_sim.system.SystemDescription.stepped`)."""
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
    ros_connect_timeout: float = 10.0
    """Client mode: the longest wait, s, for the remote to accept the connection and to
    answer at start (``serve`` fails with ``RosTimeoutError`` after it)."""
    robot_description: bool = True
    """Client mode: also publish the robot on the remote (``{ns}/robot_description``,
    ``/tf``, ``/tf_static``, ``{ns}/joint_states`` at ``tf_rate``; off to save bandwidth)."""
    duration: float | None = None
    console: bool = False
    """Install the surgeon console and teleoperations (MTMs as network devices fed by the
    client mode when ``ros_connect`` is set, else the simulated MTMs)."""
    runner: Literal["thread", "process"] = "thread"
    """Loop in a thread of this process, or in its own process (issue 3's runner)."""
    hand_inputs: tuple[str, ...] = ()
    """MTMs whose simulated hand a rate input steers (the web console's keyboard and
    gamepad; :class:`~davinci_sim.devices.hand_input.HandInput`)."""
    render_hz: float | None = None
    """The runner renders the stereo endoscope at this rate (one render process for every
    viewer: the image topics and the web console); None: the image topics start their own."""
    task: str | None = None
    """A training task (name or file) to do at the console: its path drawn in the scene,
    its fixture in the haptic loop, its repetitions measured (implies ``console``)."""
    condition: str | None = None
    """The task's condition: a condition name of the task or ``B:G_max`` (viscous guidance;
    None: the task's own fixture)."""
    task_log: str | None = None
    """CSV file each finished repetition is appended to."""
    realtime_priority: int | None = None
    """Process runner: SCHED_FIFO priority of the loop (needs the privilege; None: normal)."""
    frame_task: bool = False
    """Bring the endoscope closer to the task once the ECM is homed (the web console's
    view: the task fills the image)."""
    record_inputs: bool = False
    """Log every call with its tick and publish ``qpos`` (what ``serve --record`` needs:
    :func:`davinci_sim.records.recording.recording_description`)."""


class RealTimeWatch:
    """Says once when a real-time simulation falls behind the wall clock: the simulated time
    over the wall time of the last ``window`` seconds under ``threshold`` (after a first
    window of start-up, which is not judged)."""

    def __init__(self, window: float = 5.0, threshold: float = 0.95) -> None:
        self.window, self.threshold = window, threshold
        self._start: tuple[float, float] | None = None
        self._said = False
        self._skipped = False

    def observe(self, wall: float, sim_time: float) -> str | None:
        """The warning (once), or None; ``wall`` and ``sim_time`` in s."""
        if self._start is None:
            self._start = (wall, sim_time)
            return None
        w0, s0 = self._start
        if wall - w0 < self.window:
            return None
        factor = (sim_time - s0) / (wall - w0)
        self._start = (wall, sim_time)
        if not self._skipped:  # the first window includes the start-up
            self._skipped = True
            return None
        if self._said or factor >= self.threshold:
            return None
        self._said = True
        return (
            f"the simulation runs at {factor:.2f}x real time (over the last {self.window:g} s): "
            "this machine cannot keep the 1 kHz loop; close other programs, use --runner "
            "process and --realtime-priority, or fewer image topics"
        )


def serve_description(options: ServeOptions):
    """The :class:`~davinci_sim.system.SystemDescription` of ``options``: the scene, the
    console (its MTMs as network devices fed by the client mode with ``ros_connect``), the
    task, the runner; snapshots carry ``qpos`` when images are served."""
    from davinci_sim.model.config import scene_arms
    from davinci_sim.system import (
        ConsoleDescription,
        DeviceDescription,
        SystemDescription,
        TaskDescription,
    )

    console = None
    if options.console or options.task is not None:
        devices = {}
        if options.ros_connect is not None:
            arms = scene_arms(options.scene)
            devices = {m: DeviceDescription("network") for m in ("MTML", "MTMR") if m in arms}
        arms = scene_arms(options.scene)
        hands = tuple(m for m in options.hand_inputs if m not in devices and m in arms)
        console = ConsoleDescription(devices=devices, hand_inputs=hands)
    task = None
    if options.task is not None:
        from davinci_sim.tasks.session import VIEW_DISTANCE

        view = VIEW_DISTANCE if options.frame_task else None
        task = TaskDescription(options.task, condition=options.condition, log=options.task_log,
                               frame_view=view)  # fmt: skip
    return SystemDescription(
        scene=options.scene,
        keyframe=options.keyframe,
        seed=options.seed,
        console=console,
        task=task,
        home=options.home,
        runner=options.runner,
        real_time=options.real_time,
        stepped=options.stepped,
        # Snapshots cost ~0.2 ms of the loop for the full system with the console: take them
        # at the publish rate, not every tick, so the 1 kHz loop keeps its margin.
        snapshot_period=1.0 / max(options.rate, 1.0),
        # qpos in the snapshots: the images' renderer, the robot's /tf and /joint_states (the
        # built-in server's and the client mode's), and a recording's states.
        publish_qpos=options.server
        or options.images != "none"
        or options.render_hz is not None
        or (options.ros_connect is not None and options.robot_description)
        or options.record_inputs,
        record_inputs=options.record_inputs,
        render_hz=options.render_hz,
        realtime_priority=options.realtime_priority if options.runner == "process" else None,
    )


#: Longest wait, s, for the render pipeline's first frame before ``serve`` says it is ready
#: anyway (a render process that cannot start is logged and retried by the pipeline).
FIRST_FRAME_WAIT = 60.0


def _wait_first_frame(endoscope, stop: threading.Event, info: dict) -> None:
    """Wait until ``endoscope``'s render pipeline (started with the server) has its first
    frame, ``stop`` is set, or :data:`FIRST_FRAME_WAIT` passes; ``info["first_frame_s"]``:
    the wait, s."""
    t0 = time.monotonic()
    while not endoscope.ready.wait(0.05):
        if stop.is_set() or time.monotonic() - t0 > FIRST_FRAME_WAIT:
            _log.warning("no endoscope image after %.0f s; serving without waiting for it",
                         time.monotonic() - t0)  # fmt: skip
            return
    info["first_frame_s"] = time.monotonic() - t0


def serve(
    options: ServeOptions,
    *,
    stop: threading.Event | None = None,
    on_ready: Callable[[dict], None] | None = None,
    parts: Sequence[Callable[[Any, dict], Any]] = (),
    on_warning: Callable[[str], None] | None = None,
    system: Any = None,
    freeze_heap: bool = False,
) -> dict:
    """Run until ``stop`` is set or ``options.duration`` passes; returns final statistics.

    ``on_ready(info)`` is called once everything listens, with the server URL, the UDP
    ports and the client-mode URL. ``parts`` start more servers on the same system (the
    web console): each is called with the running :class:`~davinci_sim.system.System` and
    the ``info`` dict (to add its URLs), returns a started object with ``stop()``, and is
    stopped with the rest. ``on_warning(text)`` is told, once, when the simulation cannot
    keep real time (:class:`RealTimeWatch`; also logged and put on ``/rosout``).
    ``system``: a built, not started :class:`~davinci_sim.system.System` to serve instead
    of the one ``options`` describe (a replay's: ``davinci-sim replay``).
    ``freeze_heap``: run within :func:`~davinci_sim.sim.runtime.loop.frozen_heap` once
    started (the CLI, whose process this is; a caller embedding ``serve`` in a process of
    its own decides for that process).
    """
    from davinci_sim.bridge.client_mode import ClientModeConfig, RosClientMode
    from davinci_sim.bridge.console_node import ConsoleNode
    from davinci_sim.bridge.dvrk_node import DvrkNode
    from davinci_sim.bridge.endoscope import EndoscopeNode
    from davinci_sim.bridge.robot_node import RobotNode
    from davinci_sim.bridge.rosbridge.server import RosbridgeServer
    from davinci_sim.bridge.system_node import SystemNode
    from davinci_sim.bridge.task_node import TaskNode
    from davinci_sim.bridge.udp import UdpStreamer, default_streams
    from davinci_sim.system import build_system

    stop = stop or threading.Event()
    process = options.runner == "process"
    if system is None:
        system = build_system(serve_description(options))
    handle = system.handle
    arm_names = set()
    started: list = []
    info: dict = {}
    server = endoscope = None
    try:
        system.start()
        started.append(system)
        if process:
            info["loop"] = dict(getattr(handle, "info", {}) or {})
        arm_names = set(handle.snapshot().arms)
        if options.server:
            nodes: list = [
                DvrkNode(handle, rate=options.rate, tf_rate=options.tf_rate),
                ConsoleNode(handle, rate=options.rate),
                TaskNode(handle),
                SystemNode(handle),
                RobotNode(handle, system.model_source, rate=options.tf_rate),
            ]
            if options.images != "none":
                endoscope = EndoscopeNode(handle, options.scene, rate=options.image_rate,
                                          encoding=options.images, rig=options.rig,
                                          handle_frames=options.render_hz is not None,
                                          model=system.model_source)  # fmt: skip
                nodes.append(endoscope)
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
                    robot=options.robot_description,
                    tf_rate=options.tf_rate,
                ),
                model=system.model_source,
            ).start(options.ros_connect_timeout)
            started.append(client)
            info["ros_connect"] = options.ros_connect
        for make in parts:
            started.append(make(system, info))
        if endoscope is not None:  # ready means a subscriber's first image comes at once
            _wait_first_frame(endoscope, stop, info)
        # (a full collection over the start-up heap stalls the servers: the process's owner,
        # the CLI, asks to keep it out of the collector's reach for the run)
        with frozen_heap() if freeze_heap else contextlib.nullcontext():
            if on_ready is not None:
                on_ready(info)
            end = None if options.duration is None else time.monotonic() + options.duration
            t0_wall, t0_sim = time.monotonic(), handle.snapshot().time
            pace = RealTimeWatch() if options.real_time else None
            while not stop.wait(0.1):
                if end is not None and time.monotonic() >= end:
                    break
                warning = pace.observe(time.monotonic(), handle.snapshot().time) if pace else None
                if warning is not None:
                    info["real_time_warning"] = warning
                    _log.warning(warning)
                    if on_warning is not None:
                        on_warning(warning)
                    if server is not None:
                        server.call(lambda w=warning: server.bridge.rosout("warn", w))
            wall = time.monotonic() - t0_wall
            info["sim_over_wall"] = (handle.snapshot().time - t0_sim) / wall if wall > 0 else 0.0
            if process:  # (the thread runner has them too; `serve` reports the process's)
                info["period_statistics"] = handle.period_statistics()
    finally:
        for part in reversed(started):
            try:
                part.stop()
            except Exception:
                _log.exception("stopping %r failed", part)
        if not started:
            system.stop()  # (built, not started: release the simulation)
    return info
