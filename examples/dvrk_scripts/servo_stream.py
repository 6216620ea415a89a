#!/usr/bin/env python3
"""Stream ``servo_jp`` at 200 Hz for about 1 s: a cosine of ±5° on the first two joints
of an arm, with velocities, as dvrk_python's arm test does (public API: crtk_python /
dvrk_python). Run with ``davinci-sim run examples/dvrk_scripts/servo_stream.py -a PSM1``.

Prints ``name: value`` lines: the commands sent, the loop's achieved rate (Hz), and how far
the measured joints lag the last command (degrees).
"""

import argparse
import math
import sys
import time

import crtk
import dvrk
import numpy


def run(ral, arm, rate_hz, duration):
    ral.check_connections()
    if not arm.enable(10) or not arm.home(20):
        sys.exit("failed to enable/home the arm")
    start = numpy.copy(arm.setpoint_jp()[0])
    if arm.name().startswith(("PSM", "ECM")):
        start.fill(0.0)
        start[2] = 0.12
    arm.move_jp(start).wait()
    amplitude = math.radians(5.0)
    samples = int(rate_hz * duration)
    rate = ral.create_rate(rate_hz)
    goal = numpy.copy(start)
    t0 = time.monotonic()
    for i in range(samples):
        phase = 2.0 * math.pi * i / samples
        goal[0] = start[0] + amplitude * (1.0 - math.cos(phase))
        goal[1] = start[1] + amplitude * (1.0 - math.cos(phase))
        velocity = numpy.zeros(len(goal))
        velocity[0:2] = amplitude * math.sin(phase) * 2.0 * math.pi / duration
        arm.servo_jp(goal, velocity)
        if i == samples // 2:
            jp, _ = arm.measured_jp()
            print(f"mid_stream_yaw_deg: {math.degrees(jp[0] - start[0]):.3f}")
        rate.sleep()
    elapsed = time.monotonic() - t0
    print(f"servo_jp_sent: {samples}")
    print(f"loop_rate_hz: {samples / elapsed:.1f}")
    # the arm settles on the last command (a generous deadline: a busy simulator may run
    # slower than real time, and the last commands may still be on their way)
    t1 = time.monotonic()
    while time.monotonic() - t1 < 30.0:
        jp, _ = arm.measured_jp()
        setpoint, _ = arm.setpoint_jp()
        if numpy.max(numpy.abs(jp[0:2] - goal[0:2])) < math.radians(0.2) and numpy.allclose(
            setpoint[0:2], goal[0:2], atol=1e-9
        ):
            break
        time.sleep(0.01)
    print(f"final_error_deg: {math.degrees(numpy.max(numpy.abs(jp[0:2] - goal[0:2]))):.3f}")
    setpoint, _ = arm.setpoint_jp()
    print(
        f"setpoint_error_deg: {math.degrees(numpy.max(numpy.abs(setpoint[0:2] - goal[0:2]))):.3f}"
    )
    print("done")


if __name__ == "__main__":
    argv = crtk.ral.parse_argv(sys.argv[1:])
    parser = argparse.ArgumentParser()
    parser.add_argument("-a", "--arm", default="PSM1", help="arm name")
    parser.add_argument("-r", "--rate", type=float, default=200.0, help="servo rate, Hz")
    parser.add_argument("-d", "--duration", type=float, default=1.0, help="s")
    args = parser.parse_args(argv)
    ral = crtk.ral("servo_stream")
    arm = dvrk.arm(ral, args.arm, connection_timeout=5.0)
    ral.spin_and_execute(run, ral, arm, args.rate, args.duration)
