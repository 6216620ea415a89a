"""``crtk.utils``, ``crtk.wait_move_handle``, ``crtk.joystick_button`` and the message
conversions, with crtk_python's semantics (1.4 and later, the dVRK 2.3+ client):

* ``utils(obj, ral, connection_timeout=1.0, operating_state_instance=None)`` and its
  ``add_*`` helpers put CRTK methods on ``obj`` for the topics under ``ral``'s namespace;
  adding one twice raises ``RuntimeWarning``.
* Readers return the value *and* its time stamp (s): ``measured_js()`` → (position,
  velocity, effort, t) as numpy arrays; ``measured_jp()`` → (position, t); ``measured_cp()``
  → (``PyKDL.Frame``, t); ``measured_cv()``/``measured_cf()`` → (6-array, t);
  ``jacobian()`` → (array, t). With ``wait_timeout`` they first wait that long for data.
  They raise ``TimeoutError`` if nothing was received yet, or the last message is older
  than ``connection_timeout`` s.
* ``operating_state()``, ``is_enabled()``, ``is_homed()``, ``is_busy()``; ``enable(t)``,
  ``disable(t)``, ``home(t)``, ``unhome(t)`` send the state command and wait up to ``t`` s
  (default 0) for the state, returning whether it was reached (True at once if already).
* Moves (``move_jp/jr/cp``) return a :class:`wait_move_handle`: ``wait(is_busy=False,
  timeout=30)`` waits for the arm to have been busy after the command and to be idle again
  (False on time-out or shutdown); ``is_busy()`` is True until an operating state newer
  than the command says otherwise.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

from davinci_sim.compat.ral import Message, stamp_of
from davinci_sim.compat.ral import to_dict as _as_dict


def kdl():
    """The PyKDL module the values are made of: the real one if importable, else ours."""
    try:
        import PyKDL

        return PyKDL
    except ImportError:
        from davinci_sim.compat import kdl as ours

        return ours


# =========================================================================== conversions
def FrameFromPoseMsg(pose) -> Any:
    """A ``PyKDL.Frame`` from a ``geometry_msgs/Pose`` (dict, Message or message object)."""
    d = _as_dict(pose)
    K = kdl()
    p, q = d["position"], d["orientation"]
    return K.Frame(K.Rotation.Quaternion(q["x"], q["y"], q["z"], q["w"]),
                   K.Vector(p["x"], p["y"], p["z"]))  # fmt: skip


def FrameToPoseMsg(frame) -> dict:
    x, y, z, w = frame.M.GetQuaternion()
    p = frame.p
    return {"position": {"x": p[0], "y": p[1], "z": p[2]},
            "orientation": {"x": x, "y": y, "z": z, "w": w}}  # fmt: skip


def _xyz(v) -> list[float]:
    return [float(v["x"]), float(v["y"]), float(v["z"])]


def ArrayFromTwistMsg(twist) -> np.ndarray:
    d = _as_dict(twist)
    return np.array(_xyz(d["linear"]) + _xyz(d["angular"]))


def ArrayFromWrenchMsg(wrench) -> np.ndarray:
    d = _as_dict(wrench)
    return np.array(_xyz(d["force"]) + _xyz(d["torque"]))


def _six_values(value, what: str) -> list[float]:
    a = np.asarray(list(value), dtype=float).ravel()
    if a.shape != (6,):
        raise ValueError(f"{what} needs 6 values, got {a.shape[0]}")
    return [float(v) for v in a]


def ArrayToTwistMsg(values) -> dict:
    v = _six_values(values, "a twist")
    return {"linear": dict(zip("xyz", v[:3], strict=True)),
            "angular": dict(zip("xyz", v[3:], strict=True))}  # fmt: skip


def ArrayToWrenchMsg(values) -> dict:
    v = _six_values(values, "a wrench")
    return {"force": dict(zip("xyz", v[:3], strict=True)),
            "torque": dict(zip("xyz", v[3:], strict=True))}  # fmt: skip


def _floats(values) -> list[float]:
    return [float(v) for v in np.asarray(values, dtype=float).ravel()]


# =========================================================================== wait handle
class wait_move_handle:  # noqa: N801 (crtk's name)
    """Returned by the move commands; see the module docstring."""

    def __init__(self, class_instance, ral) -> None:
        self._inst = class_instance
        self._ral = ral
        self._start_time = ral.now()
        if not class_instance:
            self.wait = self._unsupported
            self.is_busy = self._unsupported

    def _unsupported(self, *args, **kwargs):
        raise RuntimeWarning("can't wait, class doesn't support CRTK operating state")

    def wait(self, is_busy: bool = False, timeout: float = 30.0) -> bool:
        if self._ral.is_shutdown():
            return False
        return self._inst.wait_for_busy(is_busy=is_busy, start_time=self._start_time,
                                        timeout=timeout)  # fmt: skip

    def is_busy(self, timeout: float = 30.0) -> bool:
        if self._ral.now() - self._start_time > timeout:
            raise RuntimeWarning("is_busy() called after timeout")
        return self._inst.is_busy(start_time=self._start_time)


# =========================================================================== utils
class _Stream:
    """The last message of one subscribed topic and when it came (``time.time_ns``)."""

    def __init__(self) -> None:
        self.msg: dict = {}
        self.received_ns = 0

    def __call__(self, msg: Message) -> None:
        self.msg = msg.to_dict()
        self.received_ns = time.time_ns()


#: A stamp further than this from the local clock (s) is not on the same clock (a server
#: stamping with simulation time): its receive time is used instead.
_SAME_CLOCK = 10.0


class utils:  # noqa: N801 (crtk's name)
    """Adds CRTK methods to ``class_instance`` (see the module docstring)."""

    def __init__(self, class_instance, ral, connection_timeout: float = 1.0,
                 operating_state_instance=None) -> None:  # fmt: skip
        self._obj = class_instance
        self._os_instance = operating_state_instance
        self._ral = ral
        self._connection_timeout = float(connection_timeout)
        self._os_event = threading.Event()
        ral.on_shutdown(self._os_event.set)

    # ------------------------------------------------------------ helpers
    def _attach(self, name: str, fn) -> None:
        setattr(self._obj, name, fn)

    def _check_new(self, name: str) -> None:
        if hasattr(self._obj, name):
            raise RuntimeWarning(f"{name} already exists")

    def _fresh(self, stream: _Stream, wait_timeout: float | None) -> dict:
        limit_ns = self._connection_timeout * 1e9
        if wait_timeout is not None:
            end = time.monotonic() + wait_timeout
            while time.time_ns() - stream.received_ns >= limit_ns:
                if time.monotonic() >= end:
                    raise TimeoutError(f"no data received within {wait_timeout} seconds")
                time.sleep(0.001)
        if time.time_ns() - stream.received_ns < limit_ns:
            return stream.msg
        if stream.received_ns == 0:
            raise TimeoutError("no data received yet")
        raise TimeoutError(f"last data received more than {self._connection_timeout} seconds ago")

    def _subscribe(self, topic: str, type_name: str) -> _Stream:
        stream = _Stream()
        # only the newest is read: a client busy elsewhere must not fall behind a queue
        self._ral.subscriber(topic, type_name, stream, queue_size=1)
        return stream

    # ------------------------------------------------------------ operating state
    def add_operating_state(self) -> None:
        self._check_new("operating_state")
        self._os = {"state": "", "is_homed": False, "is_busy": False}
        self._os_time = 0.0
        self._os_count = 0  # operating states received (a command waits for a newer one)
        self._last_busy_time = self._ral.now()
        self._ral.subscriber("operating_state", "crtk_msgs/OperatingState", self._os_cb)
        self._state_pub = self._ral.publisher("state_command", "crtk_msgs/StringStamped",
                                              latch=True)  # fmt: skip
        for name in ("operating_state", "wait_for_operating_state", "state_command",
                     "is_enabled", "enable", "is_disabled", "disable", "home", "unhome",
                     "is_homed", "is_busy", "wait_for_busy"):  # fmt: skip
            self._attach(name, getattr(self, f"_{name}"))
        if self._os_instance:
            raise RuntimeWarning(f"over writing operating state for {self._ral.namespace()}")
        self._os_instance = self._obj

    def _os_cb(self, msg: Message) -> None:
        now = self._ral.now()
        d = msg.to_dict()
        stamp = stamp_of(d)
        if not stamp or abs(stamp - now) > _SAME_CLOCK:
            stamp = now
        if d.get("is_busy") and stamp > self._last_busy_time:
            self._last_busy_time = stamp
        if stamp >= self._os_time:
            self._os, self._os_time = d, stamp
        self._os_count += 1
        self._os_event.set()

    def _operating_state(self, extra=None):
        return (self._os["state"], self._os_time) if extra else self._os["state"]

    def _wait_until(self, done, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while True:
            if self._ral.is_shutdown():
                return False
            if done():
                return True
            left = end - time.monotonic()
            if left <= 0:
                return False
            self._os_event.clear()
            if done():
                return True
            self._os_event.wait(min(left, 0.1))

    def _wait_for_operating_state(self, expected_state: str, timeout: float) -> bool:
        if timeout < 0.0:
            return False
        return self._wait_until(lambda: self._os["state"] == expected_state, timeout)

    def _state_command(self, state: str) -> None:
        self._os_event.clear()
        self._state_pub.publish(self._ral.set_timestamp({"string": state}))

    def _is_enabled(self) -> bool:
        return self._os["state"] == "ENABLED"

    def _is_disabled(self) -> bool:
        return self._os["state"] == "DISABLED"

    def _is_homed(self, extra=None):
        return (self._os["is_homed"], self._os_time) if extra else self._os["is_homed"]

    def _command_and_wait(self, command: str, reached, timeout: float) -> bool:
        if reached():
            self._state_command(command)
            return True
        sent = self._os_count
        self._state_command(command)
        if timeout < 0.0:
            return False
        # only a state that came after the command counts (not one already on its way)
        return self._wait_until(lambda: self._os_count > sent and reached(), timeout)

    def _enable(self, timeout: float = 0.0) -> bool:
        return self._command_and_wait("enable", self._is_enabled, timeout)

    def _disable(self, timeout: float = 0.0) -> bool:
        return self._command_and_wait("disable", self._is_disabled, timeout)

    def _home(self, timeout: float = 0.0) -> bool:
        return self._command_and_wait(
            "home", lambda: self._os["is_homed"] and not self._os["is_busy"], timeout
        )

    def _unhome(self, timeout: float = 0.0) -> bool:
        return self._command_and_wait(
            "unhome", lambda: not self._os["is_homed"] and not self._os["is_busy"], timeout
        )

    def _is_busy(self, start_time=None, extra=None):
        if start_time is None:
            start_time = self._ral.now()
        result = bool(self._os["is_busy"]) if self._os_time > start_time else True
        return (result, self._os_time) if extra else result

    def _wait_for_busy(self, is_busy: bool = False, start_time=None, timeout: float = 30.0):
        start_time = start_time or self._ral.now()
        left = timeout - (self._ral.now() - start_time)
        if left < 0:
            return False
        if is_busy:
            return self._wait_until(lambda: self._last_busy_time > start_time, left)
        return self._wait_until(
            lambda: self._last_busy_time > start_time and not self._os["is_busy"], left
        )

    # ------------------------------------------------------------ joint states
    def _add_js(self, kind: str) -> None:
        self._check_new(f"{kind}_js")
        stream = self._subscribe(f"{kind}_js", "sensor_msgs/JointState")

        def js(wait_timeout=None):
            m = self._fresh(stream, wait_timeout)
            return (np.array(m.get("position", []), dtype=float),
                    np.array(m.get("velocity", []), dtype=float),
                    np.array(m.get("effort", []), dtype=float), stamp_of(m))  # fmt: skip

        def field(name: str):
            def get(wait_timeout=None):
                m = self._fresh(stream, wait_timeout)
                return np.array(m.get(name, []), dtype=float), stamp_of(m)

            return get

        self._attach(f"{kind}_js", js)
        for suffix, name in (("jp", "position"), ("jv", "velocity"), ("jf", "effort")):
            self._attach(f"{kind}_{suffix}", field(name))

    def add_setpoint_js(self) -> None:
        self._add_js("setpoint")

    def add_measured_js(self) -> None:
        self._add_js("measured")

    # ------------------------------------------------------------ Cartesian states
    def _add_reader(self, name: str, type_name: str, convert) -> None:
        self._check_new(name)
        stream = self._subscribe(name, type_name)

        def read(wait_timeout=None):
            m = self._fresh(stream, wait_timeout)
            return convert(m), stamp_of(m)

        self._attach(name, read)

    def add_setpoint_cp(self) -> None:
        self._add_reader("setpoint_cp", "geometry_msgs/PoseStamped",
                         lambda m: FrameFromPoseMsg(m["pose"]))  # fmt: skip

    def add_measured_cp(self) -> None:
        self._add_reader("measured_cp", "geometry_msgs/PoseStamped",
                         lambda m: FrameFromPoseMsg(m["pose"]))  # fmt: skip

    def add_measured_cv(self) -> None:
        self._add_reader("measured_cv", "geometry_msgs/TwistStamped",
                         lambda m: ArrayFromTwistMsg(m["twist"]))  # fmt: skip

    def add_measured_cf(self) -> None:
        self._add_reader("measured_cf", "geometry_msgs/WrenchStamped",
                         lambda m: ArrayFromWrenchMsg(m["wrench"]))  # fmt: skip

    def add_jacobian(self) -> None:
        def matrix(m: dict) -> np.ndarray:
            dims = m.get("layout", {}).get("dim", [])
            J = np.asarray(m.get("data", []), dtype=float)
            if len(dims) >= 2:
                J = J.reshape(int(dims[0]["size"]), int(dims[1]["size"]))
            return J

        self._add_reader("jacobian", "std_msgs/Float64MultiArray", matrix)

    # ------------------------------------------------------------ commands
    def _add_command(self, name: str, type_name: str, build, *, move: bool = False) -> None:
        self._check_new(name)
        pub = self._ral.publisher(name, type_name)

        def command(*args):
            msg = build(*args)
            if move:
                handle = wait_move_handle(self._os_instance, self._ral)
                pub.publish(self._ral.set_timestamp(msg))
                return handle
            pub.publish(self._ral.set_timestamp(msg) if "header" in _STAMPED[type_name] else msg)
            return None

        self._attach(name, command)

    def add_hold(self) -> None:
        self._add_command("hold", "std_msgs/Empty", lambda: {})

    def add_free(self) -> None:
        self._add_command("free", "std_msgs/Empty", lambda: {})

    def add_servo_jp(self) -> None:
        def build(setpoint_p, setpoint_v=()):
            return {"position": _floats(setpoint_p), "velocity": _floats(setpoint_v)}

        self._add_command("servo_jp", "sensor_msgs/JointState", build)

    def add_servo_jr(self) -> None:
        self._add_command("servo_jr", "sensor_msgs/JointState",
                          lambda d: {"position": _floats(d)})  # fmt: skip

    def add_servo_jf(self) -> None:
        self._add_command("servo_jf", "sensor_msgs/JointState",
                          lambda e: {"effort": _floats(e)})  # fmt: skip

    def add_servo_cp(self) -> None:
        self._add_command("servo_cp", "geometry_msgs/PoseStamped",
                          lambda f: {"pose": FrameToPoseMsg(f)})  # fmt: skip

    def add_servo_cf(self) -> None:
        self._add_command("servo_cf", "geometry_msgs/WrenchStamped",
                          lambda w: {"wrench": ArrayToWrenchMsg(w)})  # fmt: skip

    def add_servo_cv(self) -> None:
        self._add_command("servo_cv", "geometry_msgs/TwistStamped",
                          lambda t: {"twist": ArrayToTwistMsg(t)})  # fmt: skip

    def add_move_jp(self) -> None:
        self._add_command("move_jp", "sensor_msgs/JointState",
                          lambda g: {"position": _floats(g)}, move=True)  # fmt: skip

    def add_move_jr(self) -> None:
        self._add_command("move_jr", "sensor_msgs/JointState",
                          lambda d: {"position": _floats(d)}, move=True)  # fmt: skip

    def add_move_cp(self) -> None:
        self._add_command("move_cp", "geometry_msgs/PoseStamped",
                          lambda f: {"pose": FrameToPoseMsg(f)}, move=True)  # fmt: skip

    # ------------------------------------------------------------ services
    def add_forward_kinematics(self) -> None:
        self._check_new("forward_kinematics")
        service = self._ral.service_client("forward_kinematics",
                                           "crtk_msgs/QueryForwardKinematics")  # fmt: skip

        def forward_kinematics(jp, extra=None):
            r = service({"jp": _floats(jp)}).to_dict()
            frame = FrameFromPoseMsg(r["cp"])
            return (frame, r.get("result"), r.get("message")) if extra else frame

        self._attach("forward_kinematics", forward_kinematics)

    def add_inverse_kinematics(self) -> None:
        self._check_new("inverse_kinematics")
        service = self._ral.service_client("inverse_kinematics",
                                           "crtk_msgs/QueryInverseKinematics")  # fmt: skip

        def inverse_kinematics(jp, cp, extra=None):
            r = service({"jp": _floats(jp), "cp": FrameToPoseMsg(cp)}).to_dict()
            jp_out = np.array(r.get("jp", []), dtype=float)
            return (jp_out, r.get("result"), r.get("message")) if extra else jp_out

        self._attach("inverse_kinematics", inverse_kinematics)


#: Which command types carry a header (stamped with ``ral.now()`` as crtk does).
_STAMPED = {
    "std_msgs/Empty": (),
    "sensor_msgs/JointState": ("header",),
    "geometry_msgs/PoseStamped": ("header",),
    "geometry_msgs/WrenchStamped": ("header",),
    "geometry_msgs/TwistStamped": ("header",),
}


# =========================================================================== joystick
class joystick_button:  # noqa: N801 (crtk's name)
    """A ``sensor_msgs/Joy`` button (a foot pedal, a console event such as
    ``/console/clutch`` or ``/console/operator_present``): ``value()`` is the last
    ``buttons[index]`` (None before any; 1 pressed, 0 released, 2 quick tap),
    ``wait(timeout, value)`` waits for the next event (with that value, if given),
    ``set_callback(fn)`` calls ``fn(value)`` on each event."""

    def __init__(self, ral, button_name: str, index: int = 0) -> None:
        self._index = index
        self._value = None
        self._user_callback = None
        self._event = threading.Event()
        self._subscriber = ral.subscriber(button_name, "sensor_msgs/Joy", self._callback)

    def _callback(self, msg: Message) -> None:
        buttons = msg.to_dict().get("buttons", [])
        if self._index >= len(buttons):
            return
        self._value = buttons[self._index]
        self._event.set()
        if self._user_callback is not None:
            self._user_callback(self._value)

    def set_callback(self, callback=None) -> None:
        self._user_callback = callback

    def value(self):
        return self._value

    def wait(self, timeout: float | None = None, value=None) -> bool:
        """True once an event (with ``value`` if given) arrived; False on time-out.
        (crtk_python's own ``wait`` returns False in both cases; True here tells them
        apart, and a script testing neither is unaffected.)"""
        end = None if timeout is None else time.monotonic() + timeout
        while True:
            self._event.clear()
            left = None if end is None else max(0.0, end - time.monotonic())
            if not self._event.wait(left):
                return False
            if value is None or value == self._value:
                return True
