"""The ``dvrk`` Python package's classes (dvrk_python, dVRK 2.3+): ``arm``, ``psm`` (with
``jaw``), ``ecm``, ``mtm`` (with ``gripper``), ``suj``, ``console``, ``system``,
``teleop_psm``, built from ``crtk.utils`` as the originals are, on the same topics
(dvrk.md §3.2):

* ``arm(ral, name, connection_timeout=1.0)``: operating state, ``measured_js/cp/cv``,
  ``setpoint_js/cp``, ``hold``, ``free``, ``servo_jp/jr/jf/cp``, ``move_jp/jr/cp``,
  ``forward_kinematics``, ``inverse_kinematics``; ``arm.local`` (``measured_cp``,
  ``setpoint_cp``, ``forward_kinematics``), ``arm.body`` and ``arm.spatial``
  (``measured_cf``, ``servo_cf``, ``jacobian``); ``use_gravity_compensation``,
  ``body_set_cf_orientation_absolute``, ``trajectory_j_set_ratio``/``trajectory_j_ratio``;
* ``psm``: ``jaw`` (``measured_js``, ``setpoint_js``, ``servo_jp``, ``move_jp``,
  ``servo_jf``, ``open(angle=60°)``, ``close()`` to −20°, both moves with handles, waiting on
  the PSM's operating state), ``insert_jp(depth)``, ``set_tool_present``;
* ``mtm``: ``gripper.measured_js``, ``lock_orientation(PyKDL.Rotation)``,
  ``lock_orientation_as_is()``, ``unlock_orientation()``, ``servo_ci``;
* ``console``: ``teleop_start/stop``, ``teleop_set_scale``/``teleop_get_scale``,
  ``teleop_select/unselect``, ``teleop_is_selected``; ``system``: ``power_on/off``,
  ``home``, ``set_volume``, ``beep``, ``string_to_speech``; ``teleop_psm``: ``enable``,
  ``disable``, ``set_scale``, ``get_scale``; ``suj``: ``suj.PSM1`` … with operating state,
  ``measured_js/cp``, ``move_jp``, ``local.measured_cp``.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from davinci_sim.compat.crtk_utils import utils

_log = logging.getLogger("davinci_sim.compat")

#: Topics of dvrk_python the simulator does not serve: the simulated tool is always present.
#: ``check_connections`` does not wait for them; publishing to them says once that nothing
#: listens.
NOT_SIMULATED = frozenset({"emulate_tool_present"})
_said: set[str] = set()


def _not_simulated(topic: str) -> None:
    if topic not in _said:
        _said.add(topic)
        _log.warning("%s: the simulator does not serve this topic; the command is dropped", topic)


class arm:  # noqa: N801 (dvrk's name)
    """A dVRK arm over its CRTK topics (see the module docstring)."""

    class _MeasuredServoCf:
        def __init__(self, ral, connection_timeout: float) -> None:
            self._crtk_utils = utils(self, ral, connection_timeout)
            self._crtk_utils.add_measured_cf()
            self._crtk_utils.add_servo_cf()
            self._crtk_utils.add_jacobian()

    class _Local:
        def __init__(self, ral, connection_timeout: float) -> None:
            self._crtk_utils = utils(self, ral, connection_timeout)
            self._crtk_utils.add_measured_cp()
            self._crtk_utils.add_setpoint_cp()
            self._crtk_utils.add_forward_kinematics()

    def __init__(self, ral, arm_name: str, connection_timeout: float = 1.0) -> None:
        self._name = arm_name
        self._ral = ral.create_child(arm_name)
        u = self._crtk_utils = utils(self, self._ral, connection_timeout)
        u.add_operating_state()
        for add in ("setpoint_js", "setpoint_cp", "measured_js", "measured_cp", "measured_cv",
                    "hold", "free", "servo_jp", "servo_jr", "servo_cp", "servo_jf", "move_jp",
                    "move_jr", "move_cp", "forward_kinematics", "inverse_kinematics"):  # fmt: skip
            getattr(u, f"add_{add}")()
        self.spatial = self._MeasuredServoCf(self._ral.create_child("spatial"), connection_timeout)
        self.body = self._MeasuredServoCf(self._ral.create_child("body"), connection_timeout)
        self.local = self._Local(self._ral.create_child("local"), connection_timeout)
        self._cf_absolute_pub = self._ral.publisher("/body/set_cf_orientation_absolute",
                                                    "std_msgs/Bool", latch=True)  # fmt: skip
        self._gravity_pub = self._ral.publisher("/use_gravity_compensation", "std_msgs/Bool",
                                                latch=True)  # fmt: skip
        self._ratio_pub = self._ral.publisher("/trajectory_j/set_ratio", "std_msgs/Float64",
                                              latch=True)  # fmt: skip
        self._trajectory_j_ratio = 1.0
        self._ral.subscriber("/trajectory_j/ratio", "std_msgs/Float64", self._ratio_cb)

    def name(self) -> str:
        return self._name

    def ral(self):
        return self._ral

    def check_connections(self, timeout: float = 5.0) -> None:
        self._ral.check_connections(timeout)

    def body_set_cf_orientation_absolute(self, absolute: bool) -> None:
        """Body wrenches in the body's orientation (False) or the base frame's (True)."""
        self._cf_absolute_pub.publish({"data": bool(absolute)})

    def use_gravity_compensation(self, gravity_compensation: bool) -> None:
        self._gravity_pub.publish({"data": bool(gravity_compensation)})

    def trajectory_j_set_ratio(self, ratio: float) -> None:
        """Scale of the joint trajectories' velocity and acceleration limits, in ]0, 1]."""
        self._ratio_pub.publish({"data": float(ratio)})

    def _ratio_cb(self, msg) -> None:
        self._trajectory_j_ratio = float(msg.data)

    def trajectory_j_get_ratio(self) -> float:
        return self._trajectory_j_ratio

    def trajectory_j_ratio(self) -> float:
        return self._trajectory_j_ratio


class _Jaw:
    def __init__(self, ral, connection_timeout: float, operating_state_instance) -> None:
        self._crtk_utils = utils(self, ral, connection_timeout, operating_state_instance)
        for add in ("measured_js", "setpoint_js", "servo_jp", "move_jp", "servo_jf"):
            getattr(self._crtk_utils, f"add_{add}")()

    def close(self):
        """Close the jaw (to −20°, squeezing what it holds); a move handle."""
        return self.move_jp(np.array([math.radians(-20.0)]))

    def open(self, angle: float = math.radians(60.0)):
        """Open the jaw to ``angle`` rad; a move handle."""
        return self.move_jp(np.array([angle]))


class psm(arm):  # noqa: N801
    def __init__(self, ral, arm_name: str, connection_timeout: float = 5.0) -> None:
        super().__init__(ral, arm_name, connection_timeout)
        self.jaw = _Jaw(self.ral().create_child("/jaw"), connection_timeout,
                        operating_state_instance=self)  # fmt: skip
        self._tool_present_pub = self.ral().publisher("/emulate_tool_present", "std_msgs/Bool",
                                                      latch=True)  # fmt: skip

    def insert_jp(self, depth: float):
        """Move the insertion joint to ``depth`` m (the others stay); a move handle."""
        jp, _ = self.setpoint_jp()
        goal = np.copy(jp)
        goal[2] = depth
        return self.move_jp(goal)

    def set_tool_present(self, tool_present: bool) -> None:
        _not_simulated(self._tool_present_pub.topic_name)
        self._tool_present_pub.publish({"data": bool(tool_present)})


class ecm(arm):  # noqa: N801
    def __init__(self, ral, arm_name: str, connection_timeout: float = 5.0) -> None:
        super().__init__(ral, arm_name, connection_timeout)

    def insert_jp(self, depth: float):
        jp, _ = self.setpoint_jp()
        goal = np.copy(jp)
        goal[2] = depth
        return self.move_jp(goal)


class _Gripper:
    def __init__(self, ral, connection_timeout: float) -> None:
        self._crtk_utils = utils(self, ral, connection_timeout)
        self._crtk_utils.add_measured_js()


class mtm(arm):  # noqa: N801
    def __init__(self, ral, arm_name: str, connection_timeout: float = 5.0) -> None:
        super().__init__(ral, arm_name, connection_timeout)
        self.gripper = _Gripper(self.ral().create_child("/gripper"), connection_timeout)
        self._lock_pub = self.ral().publisher("lock_orientation", "geometry_msgs/Quaternion",
                                              latch=True)  # fmt: skip
        self._unlock_pub = self.ral().publisher("unlock_orientation", "std_msgs/Empty",
                                                latch=True)  # fmt: skip
        self._servo_ci_pub = self.ral().publisher("servo_ci", "crtk_msgs/CartesianImpedance")

    def lock_orientation_as_is(self) -> None:
        current, ts = self.setpoint_cp()
        if not ts:
            raise RuntimeError("setpoint_cp is not valid")
        self.lock_orientation(current.M)

    def lock_orientation(self, orientation) -> None:
        """Hold the handle at ``orientation`` (a ``PyKDL.Rotation`` in the MTM's base)."""
        x, y, z, w = orientation.GetQuaternion()
        self._lock_pub.publish({"x": x, "y": y, "z": z, "w": w})

    def unlock_orientation(self) -> None:
        self._unlock_pub.publish({})

    def servo_ci(self, gains) -> None:
        """Cartesian impedance: ``gains`` a ``crtk_msgs/CartesianImpedance`` message."""
        self._servo_ci_pub.publish(gains)


class suj:  # noqa: N801
    class _Arm:
        class _Local:
            def __init__(self, ral, connection_timeout: float) -> None:
                self._crtk_utils = utils(self, ral, connection_timeout)
                self._crtk_utils.add_measured_cp()

        def __init__(self, ral, connection_timeout: float) -> None:
            self._ral = ral
            u = self._crtk_utils = utils(self, ral, connection_timeout)
            for add in ("operating_state", "measured_js", "measured_cp", "move_jp"):
                getattr(u, f"add_{add}")()
            self.local = self._Local(ral.create_child("/local"), connection_timeout)

        def ral(self):
            return self._ral

    def __init__(self, ral, connection_timeout: float = 1.0) -> None:
        self._ral = ral.create_child("SUJ")
        for name in ("ECM", "PSM1", "PSM2", "PSM3"):
            setattr(self, name, self._Arm(self._ral.create_child(name), connection_timeout))

    def ral(self):
        return self._ral


class console:  # noqa: N801
    def __init__(self, ral, console_name: str = "console") -> None:
        self._ral = ral.create_child(console_name)
        self._teleop_scale = 0.0
        self._teleop_selected: dict[str, bool] = {}
        r = self._ral
        self._enable_pub = r.publisher("/teleop/enable", "std_msgs/Bool")
        self._set_scale_pub = r.publisher("/teleop/set_scale", "std_msgs/Float64")
        self._select_pub = r.publisher("/teleop/select", "std_msgs/String")
        self._unselect_pub = r.publisher("/teleop/unselect", "std_msgs/String")
        r.subscriber("/teleop/scale", "std_msgs/Float64", self._scale_cb, latch=True)
        r.subscriber("/teleop/selected", "std_msgs/String", self._selected_cb(True), latch=True)
        r.subscriber("/teleop/unselected", "std_msgs/String", self._selected_cb(False),
                     latch=True)  # fmt: skip

    def _scale_cb(self, msg) -> None:
        self._teleop_scale = float(msg.data)

    def _selected_cb(self, selected: bool):
        def cb(msg) -> None:
            self._teleop_selected[msg.data] = selected

        return cb

    def teleop_start(self) -> None:
        self._enable_pub.publish({"data": True})

    def teleop_stop(self) -> None:
        self._enable_pub.publish({"data": False})

    def teleop_set_scale(self, scale: float) -> None:
        self._set_scale_pub.publish({"data": float(scale)})

    def teleop_get_scale(self) -> float:
        return self._teleop_scale

    def teleop_select(self, teleop_name: str) -> None:
        self._select_pub.publish({"data": teleop_name})

    def teleop_unselect(self, teleop_name: str) -> None:
        self._unselect_pub.publish({"data": teleop_name})

    def teleop_is_selected(self, teleop_name: str) -> bool:
        return self._teleop_selected.get(teleop_name, False)


class system:  # noqa: N801
    def __init__(self, ral, system_namespace: str = "system") -> None:
        self._ral = r = ral.create_child(system_namespace)
        self._power_off_pub = r.publisher("/power_off", "std_msgs/Empty")
        self._power_on_pub = r.publisher("/power_on", "std_msgs/Empty")
        self._home_pub = r.publisher("/home", "std_msgs/Empty")
        self._set_volume_pub = r.publisher("/set_volume", "std_msgs/Float64")
        self._beep_pub = r.publisher("/beep", "std_msgs/Float64MultiArray")
        self._speech_pub = r.publisher("/string_to_speech", "std_msgs/String")

    def power_off(self) -> None:
        self._power_off_pub.publish({})

    def power_on(self) -> None:
        self._power_on_pub.publish({})

    def home(self) -> None:
        self._home_pub.publish({})

    def set_volume(self, volume: float) -> None:
        self._set_volume_pub.publish({"data": float(volume)})

    def beep(self, duration: float, frequency: float, volume: float = 1.0) -> None:
        dim = {"label": "values", "size": 3, "stride": 1}
        values = [float(duration), float(frequency), float(volume)]
        self._beep_pub.publish({"layout": {"dim": [dim], "data_offset": 0}, "data": values})

    def string_to_speech(self, string: str) -> None:
        self._speech_pub.publish({"data": str(string)})


class teleop_psm:  # noqa: N801
    def __init__(self, ral, teleop_name: str) -> None:
        self._ral = r = ral.create_child(teleop_name)
        self._scale = 0.0
        self._set_scale_pub = r.publisher("/set_scale", "std_msgs/Float64")
        self._state_command_pub = r.publisher("/state_command", "crtk_msgs/StringStamped")
        r.subscriber("/scale", "std_msgs/Float64", self._scale_cb)

    def _scale_cb(self, msg) -> None:
        self._scale = float(msg.data)

    def set_scale(self, scale: float) -> None:
        self._set_scale_pub.publish({"data": float(scale)})

    def get_scale(self) -> float:
        return self._scale

    def enable(self) -> None:
        self._state_command_pub.publish({"string": "enable"})

    def disable(self) -> None:
        self._state_command_pub.publish({"string": "disable"})
