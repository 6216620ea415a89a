#!/usr/bin/env python3
"""The console and system of a dVRK from a script: power on and home every arm, teleop
scale, operator presence, clutch and camera events, teleoperation on and off, power off.
Public API (crtk_python / dvrk_python: ``dvrk.system``, ``dvrk.console``,
``dvrk.teleop_psm``, ``crtk.joystick_button``). The pedals are pressed by publishing on the
console's ``emulate_*`` topics, as the dVRK's GUI does. Run with
``davinci-sim run --scene psm1_ecm_mtmr examples/dvrk_scripts/console_events.py``.

Prints ``name: value`` lines.
"""

import argparse
import queue
import sys
import threading
import time

import crtk
import dvrk

try:  # a ROS installation's message class; davinci-sim's ral also takes the type's name
    from sensor_msgs.msg import Joy
except ImportError:
    Joy = "sensor_msgs/Joy"


def joy(value):
    """A Joy message with one button."""
    if isinstance(Joy, str):
        return {"buttons": [value]}
    msg = Joy()
    msg.buttons = [value]
    return msg


def next_event(events, value, timeout=5.0):
    """True once an event with ``value`` came through ``events`` within ``timeout`` s."""
    end = time.monotonic() + timeout
    while (left := end - time.monotonic()) > 0:
        try:
            if events.get(timeout=left) == value:
                return True
        except queue.Empty:
            break
    return False


def run(ral, args):
    system = dvrk.system(ral)
    console = dvrk.console(ral)
    teleop = dvrk.teleop_psm(ral, f"{args.mtm}_{args.psm}")
    psm = dvrk.psm(ral, args.psm)
    buttons = {
        name: crtk.joystick_button(ral, f"/console/{name}")
        for name in ("clutch", "camera", "operator_present")
    }
    emulate = {name: ral.publisher(f"/console/emulate_{name}", Joy) for name in buttons}
    enabled = threading.Event()
    ral.subscriber(
        "/console/teleop/enabled",
        "std_msgs/Bool",
        lambda msg: enabled.set() if msg.data else enabled.clear(),
    )
    ral.check_connections()

    system.power_on()
    print(f"power_on_enabled: {psm.wait_for_operating_state('ENABLED', 10)}")
    system.home()
    homed = psm.home(30)  # already on its way: returns once homed
    print(f"system_home_homed: {homed}")

    console.teleop_set_scale(0.35)
    teleop.set_scale(0.25)
    ral.create_rate(2).sleep()
    print(f"console_scale: {console.teleop_get_scale():.2f}")
    print(f"teleop_scale: {teleop.get_scale():.2f}")

    for name in ("operator_present", "clutch", "camera"):
        # (the events through a callback set before publishing: wait() waits for the next
        # event, and in one process the console's answer can come before wait() is called)
        events = queue.Queue()
        buttons[name].set_callback(events.put)
        emulate[name].publish(joy(1))
        pressed = next_event(events, 1)
        emulate[name].publish(joy(0))
        released = next_event(events, 0)
        buttons[name].set_callback(None)
        print(f"{name}_pressed_released: {pressed} {released}")
    events = queue.Queue()
    buttons["operator_present"].set_callback(events.put)
    emulate["operator_present"].publish(joy(1))
    next_event(events, 1)
    buttons["operator_present"].set_callback(None)

    console.teleop_start()
    print(f"teleop_enabled: {enabled.wait(5)}")
    console.teleop_stop()
    ral.create_rate(2).sleep()
    print(f"teleop_enabled_after_stop: {enabled.is_set()}")

    system.power_off()
    print(f"power_off_disabled: {psm.wait_for_operating_state('DISABLED', 10)}")
    print("done")


if __name__ == "__main__":
    argv = crtk.ral.parse_argv(sys.argv[1:])
    parser = argparse.ArgumentParser()
    parser.add_argument("-m", "--mtm", default="MTMR")
    parser.add_argument("-p", "--psm", default="PSM1")
    args = parser.parse_args(argv)
    ral = crtk.ral("console_events")
    ral.spin_and_execute(run, ral, args)
