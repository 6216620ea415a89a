"""The simulation loop in its own process, served as a :class:`~davinci_sim.sim.handle.SimHandle`.

Python's GIL lets one thread run at a time, so a bridge, a web server or rendering in the
loop's process would stall the 1 kHz tick. :class:`ProcessSimulation` runs the loop in a
child process (started with ``spawn``; ``factory`` builds the simulation there) and talks
to it through:

* a socket pair for calls (``call``, ``call_at``: pickled, served between two ticks; results
  and exceptions come back as futures) and events (``subscribe``);
* shared memory (:mod:`~davinci_sim.sim.runtime.shm`), written by the loop without locks:
  the joint positions every tick, the published state every ``snapshot_period`` (MuJoCo
  arrays, arm operating states and base frames, the components' snapshots) and the period
  statistics (:mod:`~davinci_sim.sim.runtime.stats`).

:meth:`ProcessSimulation.snapshot` rebuilds a :class:`~davinci_sim.sim.handle.Snapshot` in the
calling process from the published state, on a mirror of the model, with the arms' own
methods: the operating states at once, every other field of an arm the first time it is
read (a bridge at 1 kHz reads a few of them: the full rebuild of 10 arms cost ~270 µs, the
joint states of 7 arms ~100 µs). Nothing of this runs in the loop. With ``render_hz``, a
third process renders the stereo endoscope from the joint positions
(:class:`~davinci_sim.sim.runtime.render.StereoRenderer`).

Real-time and as-fast-as-possible runs give the same results for the same inputs if the
inputs are given with :meth:`ProcessSimulation.call_at` (applied at a simulation tick);
:meth:`~ProcessSimulation.call` applies them at whatever tick they arrive.

Size: over 500 lines because the parent's handle and the child's loop speak one private
protocol (message kinds, shared buffers, published-state layout), kept side by side.
"""

from __future__ import annotations

import atexit
import functools
import itertools
import math
import multiprocessing as mp
import os
import pickle
import struct
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any

import numpy as np

from davinci_sim.sim.handle import (
    ArmSnapshot,
    EventCallback,
    Snapshot,
    arm_snapshot,
    event_sources,
    execute,
)
from davinci_sim.sim.runtime.loop import (
    CHUNK_TICKS,
    DEFAULT_MAX_LAG,
    DEFAULT_SPIN,
    LoopRunner,
    frozen_heap,
    realtime_idle_share,
    reduce_timer_slack,
)
from davinci_sim.sim.runtime.render import (
    QPOS_CAPACITY,
    QPOS_HEADER,
    RenderStatistics,
    StereoFrame,
    StereoRenderer,
)
from davinci_sim.sim.runtime.shm import LatestSlot, SharedBuffer
from davinci_sim.sim.runtime.stats import PeriodRecorder, PeriodStatistics, layout_size
from davinci_sim.sim.types import OperatingState

#: Header of a published state: tick (int64), time (float64); then the pickled state.
STATE_HEADER = struct.Struct("<qd")


@dataclass(frozen=True)
class LoopOptions:
    """How the loop process runs (see :class:`ProcessSimulation`)."""

    real_time: bool = True
    snapshot_period: float = 0.01
    stop_at_tick: int | None = None
    cpu: int | None = None
    realtime_priority: int | None = None
    start_paused: bool = False
    spin: float | None = None
    """s; None: :func:`_default_spin`."""
    max_lag: float = DEFAULT_MAX_LAG
    stepped: bool = False
    """Tick only up to the ticks :meth:`ProcessSimulation.advance` asks for."""


def _default_spin(chunk: int, sim, realtime_priority: bool) -> float:
    """The pacer's spin (s) when none is given; see :class:`ProcessSimulation`."""
    if chunk > 1 and sim.chunker is not None:  # (passes of several ticks)
        return 0.0
    return 50e-6 if realtime_priority else DEFAULT_SPIN


class LoopProcessError(RuntimeError):
    """The loop process failed (its traceback is in the message)."""


class ProcessSimulation:
    """A simulation loop in a child process; implements ``SimHandle``.

    Args:
        factory: picklable callable returning the :class:`~davinci_sim.sim.simulation.
            Simulation` (with its components) in the child, e.g.
            ``functools.partial(davinci_sim.system.build_simulation, description)``.
        real_time: 1 tick per ``sim.dt`` of wall time; else as fast as possible.
        snapshot_period: sim time between published states, s (the dVRK publishes at
            100 Hz: 0.01).
        render_hz: render the stereo endoscope at this rate in a render process (None: no;
            :class:`~davinci_sim.sim.runtime.render.StereoRenderer`, from the joint positions
            the loop writes every tick).
        render_model: picklable callable returning the model the renderer draws (e.g. with a
            task's path, :func:`davinci_sim.system.build.scene_model`); None: the scene's.
        mirror_edit: the ``edit_spec`` the loop's simulation was built with (a task's
            drawing and objects): the mirror here, which computes snapshots from the
            published state, must have the same joints (a peg board's free rings).
        stop_at_tick: the loop stops by itself before this tick.
        start_paused: the loop waits for :meth:`resume` before its first tick (schedule
            inputs with :meth:`call_at` first, for a reproducible run).
        loop_cpu, render_cpu: pin the processes to these CPUs (None: let the OS choose).
        render_threads: rasteriser threads of the renderer (Mesa llvmpipe; None: its default,
            one per core). With the loop on SCHED_FIFO, an unpinned renderer with one thread
            per core also uses the loop core's idle time without delaying the loop.
        realtime_priority: SCHED_FIFO priority for the loop process (needs the privilege;
            :attr:`info` tells whether it was applied).
        spin: the pacer busy-waits this long before each deadline, s. Default: none when
            the loop runs its ticks in passes (a console's simulation, no ``stop_at_tick``:
            a pass of up to 4 ticks woken a sleep's overshoot late, tens of µs, still ends
            in time, and spinning before each of its 300 passes a second costs a few % of a
            core); else 200 µs, or 50 µs with ``realtime_priority`` (a real-time thread
            wakes up on time, and its spinning counts against the kernel's real-time budget
            of 95% of a core).
        state_capacity: bytes for one published state.
        start_timeout: s to wait for the child to build the simulation.
        stepped: the loop ticks (as fast as it can) only up to the ticks :meth:`advance`
            asks for, serving calls while it waits: for a script that must see each state
            before the simulation goes on (``serve``'s ``stepped``: the web console's
            ``advance`` op).
    """

    def __init__(
        self,
        factory: Callable[[], Any],
        *,
        real_time: bool = True,
        snapshot_period: float = 0.01,
        render_hz: float | None = None,
        render_model: Callable[[], Any] | None = None,
        mirror_edit: Callable[[Any], None] | None = None,
        stop_at_tick: int | None = None,
        start_paused: bool = False,
        loop_cpu: int | None = None,
        render_cpu: int | None = None,
        render_threads: int | None = None,
        realtime_priority: int | None = None,
        spin: float | None = None,
        state_capacity: int = 4 << 20,
        start_timeout: float = 120.0,
        stepped: bool = False,
    ) -> None:
        if not callable(factory):
            raise TypeError(f"factory must be callable, got {factory!r}")
        if stepped and real_time:
            raise ValueError("a stepped loop runs as fast as it can: real_time must be False")
        if not (math.isfinite(snapshot_period) and snapshot_period > 0):
            raise ValueError(f"snapshot_period must be > 0 s, got {snapshot_period!r}")
        if render_hz is not None and not (math.isfinite(render_hz) and render_hz > 0):
            raise ValueError(f"render_hz must be > 0 or None, got {render_hz!r}")
        self._factory = factory
        self._options = LoopOptions(
            real_time=real_time,
            snapshot_period=snapshot_period,
            stop_at_tick=stop_at_tick,
            start_paused=start_paused,
            cpu=loop_cpu,
            realtime_priority=realtime_priority,
            spin=spin,
            stepped=stepped,
        )
        self._render_hz = render_hz
        self._render_model = render_model
        self._mirror_edit = mirror_edit
        self._render_cpu = render_cpu
        self._render_threads = render_threads
        self._state_capacity = state_capacity
        self._start_timeout = start_timeout
        self.info: dict[str, Any] = {}
        """What the loop process reported when ready (scene, dt, components, priority …)."""
        self._proc: mp.process.BaseProcess | None = None
        self._renderer: StereoRenderer | None = None
        self._conn = None
        self._send_lock = threading.Lock()
        self._futures: dict[int, Future] = {}
        self._ids = itertools.count(1)
        self._subscribers: list[EventCallback] = []
        self._sub_lock = threading.Lock()
        self._reader: threading.Thread | None = None
        self._buffers: dict[str, SharedBuffer] = {}
        self._state: LatestSlot | None = None
        self._qpos: LatestSlot | None = None
        self._mirror = None
        self._snap_lock = threading.Lock()
        self._mirror_lock = threading.Lock()
        self._mirror_holds = None
        self._snap_cache: tuple[bytes, Snapshot] | None = None
        self._stopped = threading.Event()
        self._final_stats: PeriodStatistics | None = None
        self._error: str | None = None

    # ------------------------------------------------------------ lifecycle
    def start(self) -> ProcessSimulation:
        if self._proc is not None:
            return self
        ctx = mp.get_context("spawn")
        self._buffers["stats"] = SharedBuffer(layout_size())
        self._buffers["state"] = SharedBuffer(LatestSlot.size_for(self._state_capacity))
        self._buffers["qpos"] = SharedBuffer(LatestSlot.size_for(QPOS_CAPACITY))
        parent, child = ctx.Pipe(duplex=True)
        paths = {k: b.path for k, b in self._buffers.items()}
        self._proc = ctx.Process(
            target=_loop_main,
            args=(self._factory, self._options, child, paths),
            name="davinci-sim-loop",
            daemon=True,
        )
        self._proc.start()
        child.close()
        self._conn = parent
        atexit.register(self.stop)
        if not parent.poll(self._start_timeout):
            self.stop()
            raise LoopProcessError(f"the loop process did not start in {self._start_timeout} s")
        kind, payload = parent.recv()
        if kind != "ready":
            self.stop()
            raise LoopProcessError(f"the loop process failed to start:\n{payload}")
        self.info = payload
        self._state = LatestSlot(self._buffers["state"])
        self._qpos = LatestSlot(self._buffers["qpos"])
        from davinci_sim.sim.simulation import Simulation

        self._mirror = Simulation(payload["scene"], edit_spec=self._mirror_edit)
        if self._mirror.model.nq != payload["nq"] or self._mirror.model.nu != payload["nu"]:
            self.stop()
            raise LoopProcessError(
                "the scene rebuilt here differs from the loop's (nq/nu): a factory must not "
                "change the generated model"
            )
        self._reader = threading.Thread(target=self._read_loop, name="davinci-sim-events")
        self._reader.daemon = True
        self._reader.start()
        if self._render_hz is not None:
            self._renderer = StereoRenderer(
                payload["scene"],
                self._render_hz,
                model=self._render_model,
                qpos_path=self._buffers["qpos"].path,
                cpu=self._render_cpu,
                threads=self._render_threads,
            ).start()
        return self

    def stop(self, timeout: float = 10.0) -> PeriodStatistics | None:
        """Stop the loop (and the renderer); returns the final period statistics."""
        if self._proc is None:
            return self._final_stats
        if self._proc.is_alive() and self._conn is not None:
            try:
                self._send(("stop",))
            except OSError:
                pass
            if self._reader is not None:
                self._stopped.wait(timeout)
        self._proc.join(timeout)
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(timeout)
        if self._renderer is not None:
            self._renderer.stop(timeout)
            self._renderer = None
        if self._final_stats is None and "stats" in self._buffers:
            self._final_stats = PeriodRecorder(
                buffer=self._buffers["stats"].mm, clear=False
            ).statistics()
        self._proc = None
        if self._conn is not None:
            self._conn.close()
        for future in list(self._futures.values()):
            if not future.done():
                future.set_exception(LoopProcessError("the loop process stopped"))
        self._futures.clear()
        if self._reader is not None:
            self._reader.join(timeout)
        if self._mirror is not None:
            self._mirror.close()
        with self._snap_lock:  # a reader in another thread must not read closed memory
            self._state = None
        for buffer in self._buffers.values():
            buffer.close()
        self._buffers.clear()
        atexit.unregister(self.stop)
        return self._final_stats

    def __enter__(self) -> ProcessSimulation:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    @property
    def is_running(self) -> bool:
        return self._proc is not None and self._proc.is_alive() and not self._stopped.is_set()

    # ------------------------------------------------------------ SimHandle
    def call(self, target: str, method: str, *args: Any, **kwargs: Any) -> Future:
        """Queue ``target.method(*args, **kwargs)``; it runs between two ticks."""
        return self._request(("call", target, method, args, kwargs))

    def call_at(self, tick: int, target: str, method: str, *args: Any, **kwargs: Any) -> Future:
        """Run ``target.method(...)`` right before simulation tick ``tick`` (deterministic
        input: the same in real-time and fast runs). The future fails if the tick passed."""
        return self._request(("call_at", int(tick), target, method, args, kwargs))

    def snapshot(self) -> Snapshot:
        """The latest published state as a :class:`Snapshot` (rebuilt in this process)."""
        with self._snap_lock:
            if self._state is None:
                raise LoopProcessError("the loop process is not running (not started, or stopped)")
            data = self._state.read()
            if data is None:
                raise LoopProcessError("the loop process has not published a state yet")
            key = data[: STATE_HEADER.size]
            if self._snap_cache is not None and self._snap_cache[0] == key:
                return self._snap_cache[1]
            snap = self._rebuild(pickle.loads(data[STATE_HEADER.size :]))
            self._snap_cache = (key, snap)
            return snap

    def latest_qpos(self) -> tuple[int, float, np.ndarray] | None:
        """The joint positions the loop wrote after its last tick (every tick, where the
        published state comes every ``snapshot_period``): ``(tick, time s, qpos)``, or None
        before the first or once stopped. For a view drawn from the joints (the page's
        endoscope): up to a snapshot period fresher than :meth:`snapshot`'s."""
        with self._snap_lock:  # (stop closes the buffers)
            slot = self._qpos if self._state is not None else None
            message = None if slot is None else slot.read()
        if message is None:
            return None
        tick, t, nq = QPOS_HEADER.unpack_from(message)
        return tick, t, np.frombuffer(message, np.float64, nq, QPOS_HEADER.size).copy()

    def subscribe(self, callback: EventCallback) -> Callable[[], None]:
        """Events as ``callback(source, event, payload)``; callbacks run in this handle's
        reader thread: keep them quick and thread-safe."""
        with self._sub_lock:
            self._subscribers.append(callback)

        def unsubscribe() -> None:
            with self._sub_lock:
                if callback in self._subscribers:
                    self._subscribers.remove(callback)

        return unsubscribe

    # ------------------------------------------------------------ extensions
    def period_statistics(self) -> PeriodStatistics:
        """The loop's timing so far (readable at any time, also after :meth:`stop`)."""
        if "stats" not in self._buffers:
            if self._final_stats is None:
                raise LoopProcessError("not started")
            return self._final_stats
        return PeriodRecorder(buffer=self._buffers["stats"].mm, clear=False).statistics()

    def resume(self) -> None:
        """Start ticking (after ``start_paused``)."""
        if self.is_running:
            self._send(("resume",))

    @property
    def stepped(self) -> bool:
        """Whether the loop ticks only when :meth:`advance` asks (``stepped``)."""
        return self._options.stepped

    def advance(self, seconds: float) -> Future:
        """A stepped loop: tick ``seconds`` of simulated time more (rounded to ticks, at
        least one) after the ticks already asked for; calls sent before this are served
        before its ticks. The future gives the tick reached, once the state there is
        published (:meth:`snapshot` reads it)."""
        if not self.stepped:
            raise RuntimeError("advance: this loop is not stepped (it ticks by itself)")
        if not (math.isfinite(seconds) and seconds > 0):
            raise ValueError(f"advance: seconds must be > 0, got {seconds!r}")
        return self._request(("advance", max(1, round(seconds / self.info["dt"]))))

    def reset_period_statistics(self) -> None:
        """Start the period statistics afresh (e.g. after a warm-up), from the next tick."""
        if self.is_running:
            self._send(("reset_statistics",))

    @property
    def renders(self) -> bool:
        """Whether this runner renders the stereo endoscope (``render_hz``)."""
        return self._render_hz is not None

    def stereo_frame(self) -> StereoFrame | None:
        """The latest rendered stereo pair (``render_hz`` must be set), or None yet."""
        if self._renderer is None:
            raise LoopProcessError("no renderer: create the ProcessSimulation with render_hz")
        return self._renderer.frame()

    def render_statistics(self) -> RenderStatistics:
        if self._renderer is None:
            raise LoopProcessError("no renderer: create the ProcessSimulation with render_hz")
        return self._renderer.statistics()

    def wait_for_tick(self, tick: int, timeout: float = 10.0) -> bool:
        """Wait (polling snapshots) until the published tick reaches ``tick``."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if self._state is not None and self.snapshot().tick >= tick:
                return True
            if not self.is_running:
                return self._state is not None and self.snapshot().tick >= tick
            time.sleep(0.002)
        return False

    def wait_stopped(self, timeout: float = 60.0) -> bool:
        """Wait until the loop stopped by itself (``stop_at_tick``)."""
        return self._stopped.wait(timeout)

    # ------------------------------------------------------------ internals
    def _send(self, message) -> None:
        with self._send_lock:
            self._conn.send(message)

    def _request(self, message) -> Future:
        future: Future = Future()
        if not self.is_running:
            future.set_exception(LoopProcessError(self._error or "the loop process is not running"))
            return future
        call_id = next(self._ids)
        self._futures[call_id] = future
        try:
            self._send((message[0], call_id, *message[1:]))
        except (OSError, pickle.PicklingError, TypeError, AttributeError) as e:
            self._futures.pop(call_id, None)
            future.set_exception(e)
        return future

    def _read_loop(self) -> None:
        conn = self._conn
        while True:
            try:
                message = conn.recv()
            except (EOFError, OSError):
                break
            kind = message[0]
            if kind == "result":
                _, call_id, ok, value = message
                future = self._futures.pop(call_id, None)
                if future is not None and future.set_running_or_notify_cancel():
                    if ok:
                        future.set_result(value)
                    else:
                        future.set_exception(value)
            elif kind == "event":
                _, source, event, payload = message
                with self._sub_lock:
                    subscribers = list(self._subscribers)
                for cb in subscribers:
                    try:
                        cb(source, event, payload)
                    except Exception:  # a faulty subscriber must not stop the reader
                        traceback.print_exc()
            elif kind == "stopped":
                self._final_stats = message[1]
                self._stopped.set()
            elif kind == "error":
                self._error = message[1]
                self._stopped.set()
        self._stopped.set()
        for future in list(self._futures.values()):
            if not future.done():
                future.set_exception(LoopProcessError(self._error or "the loop process exited"))

    def _rebuild(self, published) -> Snapshot:
        """The snapshot of a published state: operating states at once, every other field of
        an arm computed on the mirror when first read (a bridge at 1 kHz reads a few)."""
        tick, t, _, states, _, extras = published
        arms = {
            name: _MirroredArmSnapshot(self, published, name, OperatingState(state, homed, busy, t))
            for name, (state, homed, busy) in states.items()
        }
        return Snapshot(t, tick, arms, extras)

    def _arm_field(self, published, snapshot: ArmSnapshot, attribute: str):
        """``attribute`` of the arm snapshot of ``published``, computed by the arm's own
        methods on the mirror loaded with that state."""
        name = snapshot.name
        with self._mirror_lock:
            if self._mirror_holds is not published:
                self._load_mirror(published)
            arm = self._mirror.arms[name]
            field_of = _LAZY_FIELDS.get(attribute)
            if field_of is not None:
                return field_of(arm)
            full = arm_snapshot(name, arm)  # the rest (arm type, chain, base frame …) at once
        full.operating_state = snapshot.operating_state
        for key, value in vars(full).items():
            if key != "operating_state":
                snapshot.__dict__.setdefault(key, value)
        return full if attribute == "_full" else getattr(full, attribute)

    def _load_mirror(self, published) -> None:
        tick, t, arrays, _, bases, _ = published
        m = self._mirror
        d = m.data
        d.qpos[:] = arrays["qpos"]
        d.qvel[:] = arrays["qvel"]
        d.actuator_force[:] = arrays["actuator_force"]
        d.time = t
        m.servo.q_ref[:] = arrays["q_ref"]
        m.servo.qd_ref[:] = arrays["qd_ref"]
        m.servo.tau_ff[:] = arrays["tau_ff"]
        m.set_encoder_reading(arrays["noisy_qpos"])
        m.tick_count = tick
        for name, (T, reference) in bases.items():
            m.arms[name].set_base_frame(T, reference)
        self._mirror_holds = published


def _jaw(arm, method):
    part = getattr(arm, "jaw", None)
    return getattr(part, method)() if part else None


#: Fields of an arm's snapshot computed one by one (what ``arm_snapshot`` computes them with).
_LAZY_FIELDS = {
    "measured_js": lambda arm: arm.measured_js(),
    "setpoint_js": lambda arm: arm.setpoint_js(),
    "jaw_measured_js": lambda arm: _jaw(arm, "measured_js"),
    "jaw_setpoint_js": lambda arm: _jaw(arm, "setpoint_js"),
    "gripper_measured_js": lambda arm: (
        arm.gripper.measured_js() if getattr(arm, "gripper", None) else None
    ),
}


def _plain_arm_snapshot(fields: dict) -> ArmSnapshot:
    snapshot = ArmSnapshot.__new__(ArmSnapshot)
    snapshot.__dict__.update(fields)
    return snapshot


class _MirroredArmSnapshot(ArmSnapshot):
    """An :class:`ArmSnapshot` rebuilt in the reader: its operating state is set at once,
    each other field is computed on the mirror the first time it is read, then kept."""

    def __init__(self, reader, published, name: str, operating_state: OperatingState) -> None:
        d = self.__dict__  # (ArmSnapshot.__init__ would compute every field now)
        d["name"] = name
        d["operating_state"] = operating_state
        d["_published"] = published
        d["_reader"] = reader

    def __reduce_ex__(self, protocol):  # sent elsewhere: a plain, complete ArmSnapshot
        full = self._reader._arm_field(self._published, self, "_full")
        return _plain_arm_snapshot, (dict(vars(full)),)

    def __getattr__(self, attribute: str):  # only for attributes not computed yet
        if attribute.startswith("__") or attribute in ("_published", "_reader"):
            raise AttributeError(attribute)
        value = self._reader._arm_field(self._published, self, attribute)
        self.__dict__[attribute] = value
        return value


# ---------------------------------------------------------------- the loop process
def _apply_process_options(options: LoopOptions) -> dict:
    applied = {"timer_slack": reduce_timer_slack(), "cpu": None, "realtime_priority": None}
    if options.cpu is not None and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {options.cpu})
        applied["cpu"] = options.cpu
    return applied


def _apply_realtime_priority(options: LoopOptions, applied: dict) -> None:
    """SCHED_FIFO for the loop, once the simulation is built: seconds of building on FIFO
    would hold the CPU from the other processes starting, and use up Linux's real-time
    share of the second the loop then starts in (a 56 ms stop in its first ticks)."""
    if options.realtime_priority is not None and hasattr(os, "sched_setscheduler"):
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(options.realtime_priority))
            applied["realtime_priority"] = options.realtime_priority
        except (PermissionError, OSError) as e:
            applied["realtime_priority_error"] = str(e)


def _published_state(sim) -> bytes:
    sim.flush()  # (the components as the ticks left them; a no-op at a period's end)
    d = sim.data
    servo = sim.servo
    arrays = {
        "qpos": d.qpos.copy(),
        "qvel": d.qvel.copy(),
        "actuator_force": d.actuator_force.copy(),
        "q_ref": servo.q_ref.copy(),
        "qd_ref": servo.qd_ref.copy(),
        "tau_ff": servo.tau_ff.copy(),
        "noisy_qpos": None if (q := sim.encoder_noise_sample) is None else q.copy(),
    }
    states = {}
    bases = {}
    for name, arm in sim.arms.items():
        s = arm.operating_state()
        states[name] = (s.state, s.is_homed, s.is_busy)
        user_base = arm.user_base_frame()
        if user_base is not None:  # a base frame set at run time
            bases[name] = user_base
    extras = {name: c.snapshot() for name, c in sim.components.items()}
    body = pickle.dumps((sim.tick_count, sim.time, arrays, states, bases, extras), protocol=5)
    return STATE_HEADER.pack(sim.tick_count, sim.time) + body


def _loop_main(factory, options: LoopOptions, conn, paths: dict) -> None:
    try:
        applied = _apply_process_options(options)
        sim = factory()
        from davinci_sim.sim.simulation import Simulation

        if not isinstance(sim, Simulation):
            raise TypeError(f"the factory must return a Simulation, got {type(sim).__name__}")
        _apply_realtime_priority(options, applied)
        buffers = {k: SharedBuffer(path=p) for k, p in paths.items()}
        recorder = PeriodRecorder(sim.dt, real_time=options.real_time, buffer=buffers["stats"].mm)
        state_slot = LatestSlot(buffers["state"])
        qpos_slot = LatestSlot(buffers["qpos"])
        # (ticks in compiled calls of up to CHUNK_TICKS; one at a time to stop at a tick)
        chunk = CHUNK_TICKS if options.stop_at_tick is None else 1
        spin = options.spin
        if spin is None:
            spin = _default_spin(chunk, sim, bool(applied["realtime_priority"]))
        runner = LoopRunner(
            sim,
            real_time=options.real_time,
            recorder=recorder,
            spin=spin,
            max_lag=options.max_lag,
            # (a FIFO loop that never sleeps is stopped by Linux for 50 ms a second)
            min_idle=realtime_idle_share() if applied["realtime_priority"] else 0.0,
            chunk=chunk,
        )
        outgoing: deque = deque()
        dropped = [0]

        def on_event(source, event, payload) -> None:
            if len(outgoing) > 10000:
                dropped[0] += 1
                return
            outgoing.append(("event", source, event, payload))

        for name, source in event_sources(sim).items():
            source.subscribe(lambda ev, payload, name=name: on_event(name, ev, payload))
        snapshot_ticks = max(1, round(options.snapshot_period / sim.dt))
        state_slot.write(_published_state(sim))
        qpos_slot.write(QPOS_HEADER.pack(sim.tick_count, sim.time, sim.model.nq), sim.data.qpos)
        conn.send(
            (
                "ready",
                {
                    "scene": sim.config,
                    "dt": sim.dt,
                    "nq": sim.model.nq,
                    "nu": sim.model.nu,
                    "arms": list(sim.arms),
                    "components": list(sim.components),
                    "pid": os.getpid(),
                    **applied,
                },
            )
        )
        stop = [False]
        paused = [options.start_paused]
        advances: deque = deque()  # (stepped: (tick, call id) answered once reached)

        def reply(call_id: int, fn) -> None:
            try:
                outgoing.append(("result", call_id, True, fn()))
            except Exception as e:  # the caller gets the error; the loop carries on
                outgoing.append(("result", call_id, False, e))

        def serve() -> bool:
            served = False
            while conn.poll():
                served = True
                message = conn.recv()
                kind = message[0]
                if kind == "call":
                    _, call_id, target, method, args, kwargs = message
                    reply(call_id, functools.partial(execute, sim, target, method, args, kwargs))
                elif kind == "call_at":
                    _, call_id, tick, target, method, args, kwargs = message
                    try:
                        fn = functools.partial(execute, sim, target, method, args, kwargs)
                        runner.call_at(tick, reply, call_id, fn)
                    except ValueError as e:
                        outgoing.append(("result", call_id, False, e))
                elif kind == "reset_statistics":
                    runner.recorder = PeriodRecorder(
                        sim.dt, real_time=options.real_time, buffer=buffers["stats"].mm
                    )
                elif kind == "advance":
                    _, call_id, ticks = message  # (after the ticks asked for before)
                    last = advances[-1][0] if advances else sim.tick_count
                    advances.append((last + ticks, call_id))
                elif kind == "resume":
                    paused[0] = False
                elif kind == "stop":
                    stop[0] = True
            return served

        def flush() -> None:
            while outgoing:
                message = outgoing.popleft()
                try:
                    conn.send(message)
                except (pickle.PicklingError, TypeError, AttributeError) as e:
                    if message[0] == "result":
                        conn.send(("result", message[1], False, RuntimeError(f"unpicklable: {e}")))

        def after() -> None:
            qpos_slot.write(QPOS_HEADER.pack(sim.tick_count, sim.time, sim.model.nq), sim.data.qpos)
            reached = bool(advances) and sim.tick_count >= advances[0][0]
            if sim.tick_count % snapshot_ticks == 0 or reached:
                state_slot.write(_published_state(sim))
            while advances and sim.tick_count >= advances[0][0]:  # (the state published)
                outgoing.append(("result", advances.popleft()[1], True, sim.tick_count))
            if outgoing:
                flush()

        def done() -> bool:
            return stop[0] or (
                options.stop_at_tick is not None and sim.tick_count >= options.stop_at_tick
            )

        serve()  # calls sent while the loop was starting
        flush()
        while paused[0] and not stop[0]:
            if conn.poll(0.05):
                serve()
                flush()
        with frozen_heap():  # no full collection over the model and system mid-run
            if options.stepped:
                waited = [False]  # (calls served while waiting: the next pass must see them)

                def serve_pass() -> bool:
                    served = serve() or waited[0]
                    waited[0] = False
                    return served

                while not done():
                    if advances:  # (as fast as it can, to the first advance's tick)
                        runner.run(ticks=advances[0][0] - sim.tick_count, until=done,
                                   before_tick=serve_pass, after_tick=after,
                                   every=snapshot_ticks)  # fmt: skip
                    elif conn.poll(0.002):
                        waited[0] = serve() or waited[0]
                        flush()
                stats = runner.recorder.statistics()
            else:
                stats = runner.run(until=done, before_tick=serve, after_tick=after,
                                   every=snapshot_ticks)  # fmt: skip
        state_slot.write(_published_state(sim))
        flush()
        if dropped[0]:
            print(f"davinci-sim loop: {dropped[0]} events dropped (reader too slow)")
        conn.send(("stopped", stats))
        # Serve late calls until the parent closes the connection.
        while not stop[0]:
            if conn.poll(0.1):
                serve()
                flush()
    except (EOFError, BrokenPipeError, ConnectionResetError):
        pass
    except BaseException:
        try:
            conn.send(("error", traceback.format_exc()))
        except OSError:
            pass
        raise
    finally:
        try:
            conn.close()
        except OSError:
            pass
