"""``davinci-sim run script.py [args]``: an unmodified dVRK Python script against the simulator.

:func:`run_script` starts what the script talks to — a simulation in this process with the
simulator's bridge reached in memory (:class:`~davinci_sim.compat.inprocess.InProcessBridge`),
or a connection to a running rosbridge server (``connect="ws://host:port"``: ``davinci-sim
serve`` or a real one) — installs it as the client of every ``crtk.ral``, puts the ``crtk``,
``dvrk`` and ``PyKDL`` modules and the ROS message packages (``std_msgs.msg`` …,
:mod:`~davinci_sim.compat.msgs`) on the import path and runs the script as ``__main__``.

A real ROS installation is not shadowed: if the real ``crtk`` and ``dvrk`` packages import
(a sourced ROS workspace), they are used — the script then talks ROS, not this simulator's
rosbridge, unless ``force_compat``. ``PyKDL`` is the real one when this interpreter can load
one, from its import path or the system's packages (Debian's ``python3-pykdl``, ROS: see
:mod:`~davinci_sim.compat.pykdl`), and our subset only when there is none.
:func:`module_choice` says which is which; the run prints it.
"""

from __future__ import annotations

import contextlib
import importlib.util
import json
import os
import pathlib
import runpy
import sys
import traceback
from collections.abc import Callable
from dataclasses import dataclass

from davinci_sim.sim.runtime.loop import frozen_heap

SHIM = pathlib.Path(__file__).parent / "shim"
ROS_SHIM = SHIM / "ros"  # crtk/, dvrk/
KDL_SHIM = SHIM / "kdl"  # PyKDL.py
MSG_SHIM = SHIM / "msgs"  # std_msgs/, geometry_msgs/, sensor_msgs/, crtk_msgs/ …


def _real_module(name: str) -> str | None:
    """Where an importable ``name`` that is not ours lives, or None."""
    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, ValueError):
        return None
    if spec is None:
        return None
    origin = spec.origin or (list(spec.submodule_search_locations or [""])[0])
    if origin and pathlib.Path(origin).resolve().is_relative_to(SHIM.resolve()):
        return None
    return origin or name


@dataclass(frozen=True)
class ModuleChoice:
    """Which ``crtk``/``dvrk`` and ``PyKDL`` a run uses (paths of the real ones, or None)."""

    real_crtk: str | None
    real_dvrk: str | None
    real_kdl: str | None
    force_compat: bool = False
    kdl_from_system: bool = False
    """``real_kdl`` is not on the import path: the system's, loaded by our ``PyKDL`` module."""

    @property
    def ours_for_ros(self) -> bool:
        return self.force_compat or not (self.real_crtk and self.real_dvrk)

    def describe(self) -> str:
        if self.ours_for_ros:
            ros = "crtk, dvrk: davinci-sim's (davinci_sim.compat)"
            if self.real_crtk or self.real_dvrk:
                ros += " (a real one is installed; " + (
                    "--force-compat)" if self.force_compat else "both are needed to use them)"
                )
        else:
            ros = f"crtk, dvrk: the installed ones ({self.real_crtk}, {self.real_dvrk})"
        if self.real_kdl:
            which = "the system's" if self.kdl_from_system else "the installed one"
            kdl = f"PyKDL: {which} ({self.real_kdl})"
        else:
            kdl = "PyKDL: davinci-sim's subset (davinci_sim.compat.kdl)"
        return f"{ros}; {kdl}"


def module_choice(force_compat: bool = False) -> ModuleChoice:
    from davinci_sim.compat import pykdl

    real_kdl, from_system = _real_module("PyKDL"), False
    if real_kdl is None and (system_kdl := pykdl.find()) is not None:
        real_kdl, from_system = str(system_kdl), True
    return ModuleChoice(_real_module("crtk"), _real_module("dvrk"), real_kdl, force_compat,
                        from_system)  # fmt: skip


def install_modules(choice: ModuleChoice) -> None:
    """Put our modules on ``sys.path`` as ``choice`` says: ``crtk``/``dvrk`` first (or not
    at all), ``PyKDL`` and the message packages last (found only if no other is)."""
    if choice.ours_for_ros and str(ROS_SHIM) not in sys.path:
        sys.path.insert(0, str(ROS_SHIM))
        for name in ("crtk", "dvrk"):  # a real one imported before us would win
            sys.modules.pop(name, None)
    for folder in (KDL_SHIM, MSG_SHIM):
        if str(folder) not in sys.path:
            sys.path.append(str(folder))


def _python_path(choice: ModuleChoice) -> str:
    """``PYTHONPATH`` for the script's child processes: the same modules."""
    parts = [os.environ.get("PYTHONPATH", "")]
    if choice.ours_for_ros:
        parts.insert(0, str(ROS_SHIM))
    parts += [str(KDL_SHIM), str(MSG_SHIM)]
    return os.pathsep.join(p for p in parts if p)


def run_path_as_main(script: str, args: list[str]) -> int:
    """Run ``script`` as ``__main__`` with ``sys.argv = [script, *args]``; its exit code as
    Python gives it (``sys.exit``'s value: None → 0, an int, or a message → printed, 1; an
    uncaught exception → its traceback, 1; Ctrl-C → 130)."""
    path = pathlib.Path(script)
    if not path.is_file():
        raise FileNotFoundError(f"no such script: {script}")
    argv, path0 = sys.argv, sys.path[:1]
    sys.argv = [str(path), *args]
    sys.path.insert(0, str(path.resolve().parent))
    try:
        runpy.run_path(str(path), run_name="__main__")
        return 0
    except SystemExit as e:
        if e.code is None:
            return 0
        if isinstance(e.code, int):
            return e.code
        print(e.code, file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    except Exception:  # the script's own error: its traceback, as python prints it
        traceback.print_exc()
        return 1
    finally:
        sys.argv = argv
        if sys.path[:1] != path0:
            sys.path.pop(0)


@dataclass(frozen=True)
class RunOptions:
    """What ``davinci-sim run`` is told besides the script."""

    connect: str | None = None
    """``ws://host:port`` of a running rosbridge server; None: a simulation in this process."""
    scene: str = "full"
    keyframe: str = "home"
    seed: int = 0
    console: bool = True
    """In-process: install the surgeon console (teleoperations, pedals), if the scene has
    MTMs."""
    home: bool = False
    """In-process: enable and home every arm at start (a script normally does it)."""
    rate: float = 100.0
    """In-process: publish rate of the arms' state topics, Hz (the dVRK's 100)."""
    token: str | None = None
    """``--connect``: the server's token, if it has one."""
    freeze_heap: bool = False
    """Run the script within :func:`~davinci_sim.sim.runtime.loop.frozen_heap` (the CLI:
    this process is the script's; a caller running scripts in its own process decides)."""
    force_compat: bool = False
    sim_time: bool = False
    """The script's ``ral`` on simulated time (ROS's ``use_sim_time``: its rates and ``now``
    follow the server's ``/clock``; :mod:`~davinci_sim.compat.ral`)."""


def run_script(script: str, args: list[str], options: RunOptions,
               say: Callable[[str], None] = print) -> int:  # fmt: skip
    """Run ``script`` (see the module docstring); returns its exit code."""
    from davinci_sim.compat import ral as ral_module
    from davinci_sim.compat.transport import RosbridgeClient, WebSocketConnection

    if not pathlib.Path(script).is_file():  # before starting anything
        raise FileNotFoundError(f"no such script: {script}")
    choice = module_choice(options.force_compat)
    say(f"davinci-sim run: {choice.describe()}")
    install_modules(choice)
    # (the script's environment, its subprocesses' too; put back as it was afterwards)
    stops: list = [_EnvRestore("PYTHONPATH"), _EnvRestore(ral_module.ENV_URL)]
    os.environ["PYTHONPATH"] = _python_path(choice)
    try:
        if options.connect:
            connection = WebSocketConnection(options.connect)
            say(f"davinci-sim run: connected to {options.connect}")
        else:
            system, bridge = _start_in_process(options)
            stops += [bridge, system]  # the loop stops first: no answer left for the bridge
            connection = bridge.connect()
            say(f"davinci-sim run: simulation {options.scene!r} in this process "
                f"(arms {', '.join(sorted(system.handle.snapshot().arms))})")  # fmt: skip
        client = RosbridgeClient(connection, description=options.connect or "in-process")
        stops.append(client)
        if options.token:
            connection.send(json.dumps({"op": "auth", "mac": options.token}))
        os.environ[ral_module.ENV_URL] = options.connect or ""
        if options.sim_time:  # (the script's subprocesses too; restored after)
            stops.append(_EnvRestore(ral_module.ENV_SIM_TIME))
            os.environ[ral_module.ENV_SIM_TIME] = "1"
        if options.connect:  # (in this process, the bridge's own log says them)
            echo_arm_messages(client, lambda text: print(text, file=sys.stderr, flush=True))
        ral_module.set_client(client)
        # (no full collection over the simulation mid-script: a late tick, a stale topic)
        with frozen_heap() if options.freeze_heap else contextlib.nullcontext():
            return run_path_as_main(script, args)
    finally:
        ral_module.set_client(None)
        for part in reversed(stops):
            part.close() if hasattr(part, "close") else part.stop()


class _EnvRestore:
    """Closing it puts an environment variable back as it was."""

    def __init__(self, name: str) -> None:
        self.name, self.value = name, os.environ.get(name)

    def close(self) -> None:
        if self.value is None:
            os.environ.pop(self.name, None)
        else:
            os.environ[self.name] = self.value


def echo_arm_messages(client, out: Callable[[str], None]) -> list[str]:
    """Pass every ``/<arm>/error`` and ``/<arm>/warning`` the server has to ``out`` (the
    dVRK mirrors them to its log; a script's refused command is said there); returns the
    topics. A server without ``/rosapi`` gives none."""
    try:
        listing = client.call_service("/rosapi/topics", {}, timeout=5.0)
    except (RuntimeError, TimeoutError, ConnectionError):
        return []
    pairs = zip(listing.get("topics", []), listing.get("types", []), strict=False)
    topics = [n for n, t in pairs if n.endswith(("/error", "/warning")) and t.endswith("String")]
    for name in topics:
        level = name.rsplit("/", 1)[1]

        def echo(msg: dict, level: str = level) -> None:
            out(f"[{level}] {msg.get('data', '')}")

        client.subscribe(name, "std_msgs/String", echo)
    return topics


def _start_in_process(options: RunOptions):
    from davinci_sim.compat.inprocess import InProcessBridge, dvrk_nodes
    from davinci_sim.model.config import scene_arms
    from davinci_sim.system import ConsoleDescription, SystemDescription, build_system

    has_mtm = any(a.startswith("MTM") for a in scene_arms(options.scene))
    description = SystemDescription(
        scene=options.scene,
        keyframe=options.keyframe,
        seed=options.seed,
        console=ConsoleDescription() if options.console and has_mtm else None,
        home=options.home,
        runner="thread",
        real_time=True,
        snapshot_period=1.0 / max(options.rate, 1.0),
    )
    system = build_system(description, start=True)
    try:
        bridge = InProcessBridge(system.handle, nodes=dvrk_nodes(system.handle, options.rate))
        bridge.start()
    except BaseException:
        system.stop()
        raise
    return system, bridge
