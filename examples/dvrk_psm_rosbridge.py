"""A dVRK-style PSM script over rosbridge (roslibpy only, no ROS installation).

It does what ``dvrk_arm_test.py`` / ``dvrk_psm_test.py`` do on a real dVRK (dvrk.md §3.3),
through the same topics and types (dvrk.md §2.2): enable and home through ``state_command``
and ``operating_state``; ``move_jp`` and wait on ``is_busy``; a ``servo_cp`` circle; jaw
open/close with ``jaw/move_jp``; read ``measured_cp``. Point it at the simulator
(``davinci-sim serve``) or at a real dVRK's rosbridge_server::

    python examples/dvrk_psm_rosbridge.py --host 127.0.0.1 --port 9090 --arm PSM1
"""

from __future__ import annotations

import argparse
import math
import sys
import threading
import time

import numpy as np
import roslibpy


def stamp_sec(header: dict) -> float:
    """Seconds of a header stamp in either ROS dialect."""
    s = header["stamp"]
    return s.get("sec", s.get("secs", 0)) + 1e-9 * s.get("nanosec", s.get("nsecs", 0))


def pose_to_matrix(pose: dict) -> np.ndarray:
    q, p = pose["orientation"], pose["position"]
    x, y, z, w = q["x"], q["y"], q["z"], q["w"]
    T = np.eye(4)
    T[:3, :3] = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    T[:3, 3] = p["x"], p["y"], p["z"]
    return T


class Arm:
    """The part of ``dvrk.psm`` this script needs, over roslibpy."""

    def __init__(self, ros: roslibpy.Ros, name: str) -> None:
        self.ros, self.name = ros, name
        self._lock = threading.Condition()
        self._state: dict | None = None
        self._states: list[dict] = []
        self._js: dict | None = None
        self._cp: dict | None = None
        self._setpoint_cp: dict | None = None
        self._jaw: dict | None = None
        self.errors: list[str] = []
        self._sub("operating_state", "crtk_msgs/OperatingState", self._on_state)
        self._sub("measured_js", "sensor_msgs/JointState", lambda m: self._set("_js", m))
        self._sub("measured_cp", "geometry_msgs/PoseStamped", lambda m: self._set("_cp", m))
        self._sub("setpoint_cp", "geometry_msgs/PoseStamped",
                  lambda m: self._set("_setpoint_cp", m))  # fmt: skip
        self._sub("jaw/measured_js", "sensor_msgs/JointState", lambda m: self._set("_jaw", m))
        self._sub("error", "std_msgs/String", lambda m: self.errors.append(m["data"]))
        self._pubs: dict[str, roslibpy.Topic] = {}

    def _sub(self, suffix: str, type_name: str, callback) -> None:
        roslibpy.Topic(self.ros, f"/{self.name}/{suffix}", type_name).subscribe(callback)

    def _pub(self, suffix: str, type_name: str, msg: dict) -> None:
        if suffix not in self._pubs:
            self._pubs[suffix] = roslibpy.Topic(self.ros, f"/{self.name}/{suffix}", type_name)
        self._pubs[suffix].publish(roslibpy.Message(msg))

    def _set(self, attr: str, msg: dict) -> None:
        with self._lock:
            setattr(self, attr, msg)
            self._lock.notify_all()

    def _on_state(self, msg: dict) -> None:
        with self._lock:
            self._state = msg
            self._states.append(msg)
            self._lock.notify_all()

    def _wait(self, predicate, timeout: float) -> bool:
        with self._lock:
            return self._lock.wait_for(predicate, timeout)

    # -------------------------------------------------------------- operating state
    def operating_state(self) -> dict | None:
        return self._state

    def enable(self, timeout: float = 10.0) -> bool:
        self._pub("state_command", "crtk_msgs/StringStamped", {"string": "enable"})
        return self._wait(lambda: self._state and self._state["state"] == "ENABLED", timeout)

    def home(self, timeout: float = 30.0) -> bool:
        self._pub("state_command", "crtk_msgs/StringStamped", {"string": "home"})
        return self._wait(
            lambda: self._state and self._state["is_homed"] and not self._state["is_busy"],
            timeout,
        )

    def wait_for_busy(self, start: float, timeout: float = 30.0) -> bool:
        """crtk's ``wait_move_handle.wait``: busy after ``start``, then not busy."""
        started = self._wait(
            lambda: any(s["is_busy"] and stamp_sec(s["header"]) >= start for s in self._states),
            min(timeout, 2.0),
        )
        if not started:  # a move so short that it may have ended already
            return bool(self._state) and not self._state["is_busy"]
        return self._wait(lambda: not self._state["is_busy"], timeout)

    # -------------------------------------------------------------- joint space
    def measured_jp(self) -> np.ndarray:
        self._wait(lambda: self._js is not None, 5.0)
        return np.array(self._js["position"])

    def move_jp(self, goal) -> float:
        start = time.time()
        self._pub("move_jp", "sensor_msgs/JointState", {"position": [float(q) for q in goal]})
        return start

    # -------------------------------------------------------------- Cartesian space
    def measured_cp(self) -> np.ndarray:
        self._wait(lambda: self._cp is not None, 5.0)
        return pose_to_matrix(self._cp["pose"])

    def setpoint_cp(self) -> tuple[np.ndarray, str]:
        self._wait(lambda: self._setpoint_cp is not None, 5.0)
        return pose_to_matrix(self._setpoint_cp["pose"]), self._setpoint_cp["header"]["frame_id"]

    def servo_cp(self, T: np.ndarray, frame_id: str) -> None:
        R = T[:3, :3]
        w = math.sqrt(max(0.0, 1.0 + R[0, 0] + R[1, 1] + R[2, 2])) / 2
        x = (R[2, 1] - R[1, 2]) / (4 * w)
        y = (R[0, 2] - R[2, 0]) / (4 * w)
        z = (R[1, 0] - R[0, 1]) / (4 * w)
        pose = {
            "position": {"x": T[0, 3], "y": T[1, 3], "z": T[2, 3]},
            "orientation": {"x": x, "y": y, "z": z, "w": w},
        }
        self._pub("servo_cp", "geometry_msgs/PoseStamped",
                  {"header": {"frame_id": frame_id}, "pose": pose})  # fmt: skip

    # -------------------------------------------------------------- jaw
    def jaw_move_jp(self, angle: float) -> float:
        start = time.time()
        self._pub("jaw/move_jp", "sensor_msgs/JointState", {"position": [float(angle)]})
        return start

    def jaw_measured_jp(self) -> float:
        self._wait(lambda: self._jaw is not None, 5.0)
        return self._jaw["position"][0]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, default=9090)
    parser.add_argument("--arm", default="PSM1")
    args = parser.parse_args(argv)

    ros = roslibpy.Ros(args.host, args.port)
    ros.run()
    arm = Arm(ros, args.arm)
    ok = True

    def check(what: str, cond: bool) -> None:
        nonlocal ok
        ok = ok and cond
        print(f"{'ok  ' if cond else 'FAIL'} {what}", flush=True)

    check("enable", arm.enable(10))
    check("home", arm.home(30))

    # move_jp and wait on is_busy (dvrk_arm_test.py: yaw = pitch = 0, insertion 0.12)
    goal = np.array([0.2, -0.1, 0.12, 0.0, 0.0, 0.0])
    start = arm.move_jp(goal)
    check("move_jp: busy then done", arm.wait_for_busy(start, 20))
    error = np.max(np.abs(arm.measured_jp() - goal))
    check(f"move_jp reached the goal (max joint error {error:.4f})", error < 0.01)
    goal[:2] = 0.0
    check("move_jp back", arm.wait_for_busy(arm.move_jp(goal), 20))

    # servo_cp: a 1 cm circle in the camera frame over 2 s at 100 Hz
    T0, frame = arm.setpoint_cp()
    worst = 0.0
    for k in range(201):
        s = 2 * math.pi * k / 200
        T = T0.copy()
        T[:3, 3] += 0.01 * np.array([math.sin(s), 1 - math.cos(s), 0.0])
        arm.servo_cp(T, frame)
        time.sleep(0.01)
        if k == 50:  # a quarter of the way: the tip should get near (1, 1, 0) cm off
            # (waited for, up to 5 s: a busy machine runs the simulation slower than the
            # wall clock this loop streams by)
            deadline = time.monotonic() + 5.0
            while True:
                worst = np.linalg.norm(arm.measured_cp()[:3, 3] - T[:3, 3])
                if worst < 0.003 or time.monotonic() > deadline:
                    break
                time.sleep(0.02)
    check(f"servo_cp circle followed (error at a quarter turn {1000 * worst:.1f} mm)",
          worst < 0.003)  # fmt: skip

    # jaw open / close (dvrk_python: open 60°, close -20°)
    check("jaw open", arm.wait_for_busy(arm.jaw_move_jp(math.radians(60)), 10))
    check(f"jaw opened to {math.degrees(arm.jaw_measured_jp()):.0f} deg",
          abs(arm.jaw_measured_jp() - math.radians(60)) < math.radians(5))  # fmt: skip
    check("jaw close", arm.wait_for_busy(arm.jaw_move_jp(math.radians(-20)), 10))

    T = arm.measured_cp()
    print(f"measured_cp in {frame}: position {np.round(T[:3, 3], 4).tolist()} m", flush=True)
    if arm.errors:
        print("arm errors:", *arm.errors, sep="\n  ")
    ros.close()
    print("done" if ok else "some steps failed", flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
