"""``/system/*`` (dvrk.md §2.3): a dVRK script's power_on / home / power_off, the volume,
and the sound topics accepted without sound."""

from __future__ import annotations

import roslibpy
from bridge_helpers import wait_for

from davinci_sim.bridge.dvrk_node import DvrkNode
from davinci_sim.bridge.system_node import SystemNode


def _states(ros, arm):
    got = []
    roslibpy.Topic(ros, f"/{arm}/operating_state", "crtk_msgs/OperatingState").subscribe(got.append)
    return got


def _empty(ros, name):
    roslibpy.Topic(ros, name, "std_msgs/Empty").publish(roslibpy.Message({}))


def test_home_power_off_and_power_on_act_on_every_arm(handle, make_server, make_ros):
    ros = make_ros(make_server(nodes=[DvrkNode(handle), SystemNode(handle)]))
    psm, ecm = _states(ros, "PSM1"), _states(ros, "ECM")
    _empty(ros, "/system/home")
    assert wait_for(lambda: psm and psm[-1]["is_homed"] and ecm and ecm[-1]["is_homed"], 20)
    assert psm[-1]["state"] == "ENABLED" and ecm[-1]["state"] == "ENABLED"
    _empty(ros, "/console/power_off")  # the dVRK 2.2 name
    assert wait_for(lambda: psm[-1]["state"] == "DISABLED" and ecm[-1]["state"] == "DISABLED", 10)
    _empty(ros, "/system/power_on")
    assert wait_for(lambda: psm[-1]["state"] == "ENABLED", 10)
    # every arm, not only the two watched (they need not all turn in the same snapshot)
    assert wait_for(lambda: all(a.operating_state.state == "ENABLED"
                                for a in handle.snapshot().arms.values()), 10)  # fmt: skip


def test_volume_is_kept_and_bad_values_refused(handle, make_server, make_ros):
    ros = make_ros(make_server(nodes=[SystemNode(handle)]))
    volume = []
    roslibpy.Topic(ros, "/system/volume", "std_msgs/Float64").subscribe(
        lambda m: volume.append(m["data"])
    )
    assert wait_for(lambda: volume == [0.5], 5)  # latched
    set_volume = roslibpy.Topic(ros, "/system/set_volume", "std_msgs/Float64")
    set_volume.publish(roslibpy.Message({"data": 0.8}))
    assert wait_for(lambda: volume[-1] == 0.8, 5)
    set_volume.publish(roslibpy.Message({"data": 3.0}))  # refused: nothing changes
    roslibpy.Topic(ros, "/system/beep", "std_msgs/Float64MultiArray").publish(
        roslibpy.Message({"data": [0.1, 440.0, 0.5]})
    )
    roslibpy.Topic(ros, "/system/string_to_speech", "std_msgs/String").publish(
        roslibpy.Message({"data": "homing done"})
    )
    set_volume.publish(roslibpy.Message({"data": 0.2}))
    assert wait_for(lambda: volume[-1] == 0.2, 5)
    assert 3.0 not in volume
