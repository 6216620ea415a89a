"""A handle on a running simulation for code outside the tick: bridges, GUIs, scripts.

The loop that ticks a :class:`~davinci_sim.sim.simulation.Simulation` owns it; nothing else
touches it. Other code goes through a :class:`SimHandle`:

* :meth:`SimHandle.call` queues ``target.method(*args)``; the loop runs it between two ticks
  and resolves the returned future with the result (or the exception);
* :meth:`SimHandle.snapshot` returns the latest :class:`Snapshot` the loop published (immutable
  values, safe to read from any thread and to send to another process);
* :meth:`SimHandle.subscribe` delivers arm events (``error``, ``warning``, ``status``,
  ``operating_state``), and the events of components that have ``channels`` (console,
  teleoperations, devices: ``clutch``, ``current_state``, ``following`` …), as
  ``callback(source, event, payload)``. Callbacks run in the loop's
  thread: they must be quick and thread-safe (hand the event over, e.g. with
  ``loop.call_soon_threadsafe``).

:class:`ThreadedSimulation` is the in-process implementation: the loop in a daemon thread,
paced at real time or as fast as possible.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import Future
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from davinci_sim.kinematics.chain import DHChain
from davinci_sim.sim import arm_laws as laws
from davinci_sim.sim.inputs import log_call
from davinci_sim.sim.types import CartesianPose, CartesianTwist, JointState, OperatingState

if TYPE_CHECKING:
    from davinci_sim.sim.simulation import Simulation

EventCallback = Callable[[str, str, object], None]

#: Attribute paths a call may use below an arm, e.g. ``PSM1/jaw`` or ``MTMR/body``.
ARM_SUBTARGETS = ("jaw", "gripper", "local", "body", "spatial")


class ArmSnapshot:
    """State of one arm at one tick, as the dVRK publishes it (dvrk.md 2.2).

    The operating state and the joint states (arm, jaw, gripper) are copied when the snapshot
    is taken. The Cartesian fields (``measured_cp``, ``setpoint_cp``, ``local_*``,
    ``measured_cv``) are computed from those joints, with the arm's own laws
    (:mod:`~davinci_sim.sim.arm_laws`), the first
    time they are read: taking a snapshot costs the loop the copies only, and a reader pays
    for the poses it uses. Treat it as immutable.
    """

    def __init__(
        self,
        name: str,
        arm_type: str,
        operating_state: OperatingState,
        measured_js: JointState,
        setpoint_js: JointState,
        *,
        chain: DHChain,
        base_frame: tuple[np.ndarray, str],
        jaw_measured_js: JointState | None = None,
        jaw_setpoint_js: JointState | None = None,
        gripper_measured_js: JointState | None = None,
    ) -> None:
        self.name = name
        self.arm_type = arm_type
        self.operating_state = operating_state
        self.measured_js = measured_js
        self.setpoint_js = setpoint_js
        self.jaw_measured_js = jaw_measured_js
        self.jaw_setpoint_js = jaw_setpoint_js
        self.gripper_measured_js = gripper_measured_js
        self._chain = chain
        self._T_ref_base, self._reference = base_frame

    @cached_property
    def _measured(self) -> tuple[np.ndarray, np.ndarray]:
        # Arm._measured_kinematics: pose and spatial Jacobian of the measured joints.
        return laws.tip_kinematics(self._chain, self.measured_js.position)

    @cached_property
    def _setpoint(self) -> np.ndarray:
        return laws.tip_pose(self._chain, self.setpoint_js.position)  # Arm._pose

    @cached_property
    def measured_cp(self) -> CartesianPose:
        T = laws.pose_in_reference(self._T_ref_base, self._measured[0])
        return CartesianPose(T, self._reference, self.name, self.measured_js.timestamp)

    @cached_property
    def setpoint_cp(self) -> CartesianPose:
        T = laws.pose_in_reference(self._T_ref_base, self._setpoint)
        moving = f"{self.name}_setpoint"
        return CartesianPose(T, self._reference, moving, self.setpoint_js.timestamp)

    @cached_property
    def local_measured_cp(self) -> CartesianPose:
        T = self._measured[0].copy()
        return CartesianPose(T, f"{self.name}_base", self.name, self.measured_js.timestamp)

    @cached_property
    def local_setpoint_cp(self) -> CartesianPose:
        moving = f"{self.name}_setpoint"
        t = self.setpoint_js.timestamp
        return CartesianPose(self._setpoint.copy(), f"{self.name}_base", moving, t)

    @cached_property
    def measured_cv(self) -> CartesianTwist:
        R = self._T_ref_base[:3, :3]
        twist = laws.twist_in_reference(R, self._measured[1], self.measured_js.velocity)
        return CartesianTwist(twist, self._reference, self.name, self.measured_js.timestamp)


@dataclass(frozen=True)
class Snapshot:
    """Everything published at one tick: sim time (s), tick count, arms, other components."""

    time: float
    tick: int
    arms: Mapping[str, ArmSnapshot]
    extras: Mapping[str, Any] = field(default_factory=dict)
    """Published state of other components (console, teleops …), by component name."""


def arm_snapshot(name: str, arm) -> ArmSnapshot:
    """The :class:`ArmSnapshot` of one arm now (call from the loop's thread)."""
    jaw = getattr(arm, "jaw", None)
    gripper = getattr(arm, "gripper", None)
    return ArmSnapshot(
        name,
        arm.kin.arm_type,
        arm.operating_state(),
        arm.measured_js(),
        arm.setpoint_js(),
        chain=arm.chain,
        base_frame=arm.base_frame(),
        jaw_measured_js=jaw.measured_js() if jaw else None,
        jaw_setpoint_js=jaw.setpoint_js() if jaw else None,
        gripper_measured_js=gripper.measured_js() if gripper else None,
    )


def take_snapshot(sim: Simulation) -> Snapshot:
    """The :class:`Snapshot` of ``sim`` now (call from the loop's thread)."""
    sim.flush()
    arms = {name: arm_snapshot(name, arm) for name, arm in sim.arms.items()}
    extras = {name: comp.snapshot() for name, comp in sim.components.items()}
    return Snapshot(sim.time, sim.tick_count, arms, extras)


def event_sources(sim: Simulation) -> dict[str, Any]:
    """Name -> ``Channels`` of every arm and of every component that has ``channels``."""
    sources: dict[str, Any] = {name: arm.channels for name, arm in sim.arms.items()}
    for name, component in sim.components.items():
        channels = getattr(component, "channels", None)
        if channels is not None and hasattr(channels, "subscribe"):
            sources[name] = channels
    return sources


def resolve_target(sim: Simulation, target: str) -> object:
    """The object a call's ``target`` names: an arm (``PSM1``), an arm part (``PSM1/jaw``,
    ``MTMR/body`` …), a registered component (``console``, ``MTMR_PSM1``) or ``sim``.

    Raises:
        KeyError: for an unknown target (the message lists the known ones).
    """
    if target == "sim":
        return sim
    if target in sim.components:
        return sim.components[target]
    head, _, sub = target.rpartition("/")
    if target in sim.arms:
        return sim.arms[target]
    if head in sim.arms and sub in ARM_SUBTARGETS and hasattr(sim.arms[head], sub):
        return getattr(sim.arms[head], sub)
    known = sorted([*sim.arms, *sim.components, "sim"])
    raise KeyError(f"unknown target {target!r}; known: {known} (+ '<arm>/{{jaw,local,body,...}}')")


def execute(sim: Simulation, target: str, method: str, args: tuple, kwargs: dict) -> Any:
    """Run one call in the loop's thread. Only public methods can be called; the call is
    logged first when the simulation has an input log (:mod:`~davinci_sim.sim.inputs`).
    The components are written back first (:meth:`Simulation.flush`): the call reads them."""
    sim.flush()
    if method.startswith("_"):
        raise AttributeError(f"{method!r} is not a public method")
    fn = getattr(resolve_target(sim, target), method, None)
    if not callable(fn):
        raise AttributeError(f"{target!r} has no method {method!r}")
    log_call(sim, target, method, args, kwargs)
    return fn(*args, **kwargs)


class SimHandle(Protocol):
    """What code outside the loop may do with a running simulation."""

    def call(self, target: str, method: str, *args: Any, **kwargs: Any) -> Future: ...

    def snapshot(self) -> Snapshot: ...

    def subscribe(self, callback: EventCallback) -> Callable[[], None]: ...


@dataclass(frozen=True)
class _Call:
    target: str
    method: str
    args: tuple
    kwargs: dict
    future: Future
    tick: int | None = None
    """Run right before this simulation tick (``call_at``); None: between the next two."""


class ThreadedSimulation:
    """Runs a simulation in a daemon thread and serves it as a :class:`SimHandle`.

    The loop is :class:`~davinci_sim.sim.runtime.loop.LoopRunner`, the one the process
    runner uses: the same pacing, period statistics (:meth:`period_statistics`) and inputs
    at given ticks (:meth:`call_at`).

    Args:
        sim: the simulation (the thread owns it from :meth:`start` on).
        real_time: pace ticks by the wall clock (1 tick per ``sim.dt``); else as fast as
            possible. A paced loop that falls behind catches up tick after tick; it only
            sleeps (no spinning: the bridge threads of this process need the interpreter).
        snapshot_period: sim-time interval between published snapshots, s. The default is
            the dVRK's 10 ms publish period (dvrk.md 2.1): a full-system snapshot with the
            console costs about 0.2 ms of the loop's time (the joint states and components'
            states; poses are computed by whoever reads them), a fifth of a 1 ms tick.
        render_hz: render the stereo endoscope at this rate in a render process
            (:class:`~davinci_sim.sim.runtime.render.StereoRenderer`, fed the joint positions
            after every tick; :meth:`stereo_frame`); None: no renderer.
        render_model: picklable callable returning the model to render (e.g. with a task's
            drawing); None: the simulation's scene.
        speed: with ``real_time``, simulated seconds per wall second (a replay; 1: real
            time).
        start_paused: the loop waits for :meth:`resume` before its first tick (schedule
            inputs with :meth:`call_at` first, for a reproducible run).
        clock, sleep: the wall clock (s) and how to wait, for the pacing (tests pass a
            virtual clock).
    """

    def __init__(
        self,
        sim: Simulation,
        *,
        real_time: bool = True,
        snapshot_period: float = 0.01,
        render_hz: float | None = None,
        render_model: Callable[[], Any] | None = None,
        start_paused: bool = False,
        clock: Callable[[], float] = time.perf_counter,
        sleep: Callable[[float], None] | None = None,
        speed: float = 1.0,
    ):
        from davinci_sim.sim.runtime.loop import (  # (runtime imports this module)
            CHUNK_TICKS,
            LoopRunner,
        )

        self.sim = sim
        self.real_time = real_time
        self._snapshot_ticks = max(1, round(snapshot_period / sim.dt))
        self._runner = LoopRunner(
            sim,
            real_time=real_time,
            speed=speed,
            spin=0.0,
            max_lag=math.inf,
            clock=clock,
            sleep=sleep,
            chunk=CHUNK_TICKS,
        )
        self._calls: queue.SimpleQueue[_Call] = queue.SimpleQueue()
        self._subscribers: list[EventCallback] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._snapshot = take_snapshot(sim)
        for name, source in event_sources(sim).items():
            source.subscribe(lambda ev, payload, name=name: self._emit(name, ev, payload))
        self._render = (render_hz, render_model)
        self._renderer = None
        self._resume = threading.Event()
        if not start_paused:
            self._resume.set()

    # ------------------------------------------------------------- SimHandle
    def call(self, target: str, method: str, *args: Any, **kwargs: Any) -> Future:
        future: Future = Future()
        self._calls.put(_Call(target, method, args, kwargs, future))
        return future

    def call_at(self, tick: int, target: str, method: str, *args: Any, **kwargs: Any) -> Future:
        """Run ``target.method(...)`` right before simulation tick ``tick`` (deterministic
        input: the same in real-time and fast runs). The future fails if the tick passed."""
        future: Future = Future()
        self._calls.put(_Call(target, method, args, kwargs, future, int(tick)))
        return future

    def snapshot(self) -> Snapshot:
        return self._snapshot

    def subscribe(self, callback: EventCallback) -> Callable[[], None]:
        with self._lock:
            self._subscribers.append(callback)

        def unsubscribe() -> None:
            with self._lock:
                if callback in self._subscribers:
                    self._subscribers.remove(callback)

        return unsubscribe

    @property
    def renders(self) -> bool:
        """Whether this runner renders the stereo endoscope (``render_hz``)."""
        return self._render[0] is not None

    def stereo_frame(self):
        """The latest rendered stereo pair (``render_hz`` must be set), or None yet."""
        if self._renderer is None:
            raise RuntimeError("no renderer: create the ThreadedSimulation with render_hz")
        return self._renderer.frame()

    def render_statistics(self):
        if self._renderer is None:
            raise RuntimeError("no renderer: create the ThreadedSimulation with render_hz")
        return self._renderer.statistics()

    def period_statistics(self):
        """The loop's timing so far (:class:`~davinci_sim.sim.runtime.stats.PeriodStatistics`)."""
        return self._runner.recorder.statistics()

    # ------------------------------------------------------------- lifecycle
    def start(self) -> ThreadedSimulation:
        if self._thread is None:
            rate, model = self._render
            if rate is not None and self._renderer is None:
                from davinci_sim.sim.runtime.render import StereoRenderer

                self._renderer = StereoRenderer(self.sim.config, rate, model=model).start()
            self._stop.clear()
            self._thread = threading.Thread(target=self._run, name="davinci-sim", daemon=True)
            self._thread.start()
        return self

    def resume(self) -> None:
        """Start ticking (after ``start_paused``)."""
        self._resume.set()

    def stop(self, timeout: float = 5.0) -> None:
        self._stop.set()
        self._resume.set()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None
        if self._renderer is not None:
            self._renderer.stop()
            self._renderer = None

    def __enter__(self) -> ThreadedSimulation:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    # ------------------------------------------------------------- the loop
    def _emit(self, source: str, event: str, payload: object) -> None:
        with self._lock:
            subscribers = list(self._subscribers)
        for cb in subscribers:
            cb(source, event, payload)

    def _resolve(self, c: _Call) -> None:
        try:
            c.future.set_result(execute(self.sim, c.target, c.method, c.args, c.kwargs))
        except Exception as e:  # the caller gets the error; the loop carries on
            c.future.set_exception(e)

    def _run_calls(self) -> bool:
        """Run the calls queued since the last pass; False when there were none."""
        served = False
        while True:
            try:
                c = self._calls.get_nowait()
            except queue.Empty:
                return served
            served = True
            if not c.future.set_running_or_notify_cancel():
                continue
            if c.tick is None:
                self._resolve(c)
                continue
            try:
                self._runner.call_at(c.tick, self._resolve, c)
            except ValueError as e:
                c.future.set_exception(e)

    def _publish(self) -> None:
        sim = self.sim
        if sim.tick_count % self._snapshot_ticks == 0:
            self._snapshot = take_snapshot(sim)
        if self._renderer is not None:
            self._renderer.feed(sim.tick_count, sim.time, sim.data.qpos)

    def _run(self) -> None:
        self._resume.wait()
        self._run_calls()  # (calls made while paused, e.g. call_at for the first ticks)
        self._runner.run(until=self._stop.is_set, before_tick=self._run_calls,
                         after_tick=self._publish, every=self._snapshot_ticks)  # fmt: skip
        self._run_calls()
