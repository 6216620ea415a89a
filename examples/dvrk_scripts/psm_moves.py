#!/usr/bin/env python3
"""Enable and home a PSM, move it in joint space and in Cartesian space, open and close
its jaw: a script in the style of dvrk_python's examples, written against the public API
(crtk_python / dvrk_python, dVRK 2.3+). It runs unchanged on a real dVRK (ROS 2) and with
``davinci-sim run examples/dvrk_scripts/psm_moves.py -a PSM1``.

Each result is printed as ``name: value`` (distances in mm, angles in degrees).
"""

import argparse
import math
import sys

import crtk
import dvrk
import numpy
import PyKDL


class example_application:
    def __init__(self, ral, arm_name):
        self.ral = ral
        self.arm = dvrk.psm(ral, arm_name)

    def home(self):
        self.ral.check_connections()
        print("starting enable")
        if not self.arm.enable(10):
            sys.exit("failed to enable within 10 seconds")
        print("starting home")
        if not self.arm.home(20):
            sys.exit("failed to home within 20 seconds")
        print(f"operating_state: {self.arm.operating_state()}")
        print(f"is_homed: {self.arm.is_homed()}")

    def joint_moves(self):
        goal = numpy.copy(self.arm.setpoint_jp()[0])
        goal.fill(0)
        goal[2] = 0.12  # insertion past the cannula
        handle = self.arm.move_jp(goal)
        print(f"busy_after_move_jp: {handle.is_busy()}")
        print(f"move_jp_wait: {handle.wait()}")
        jp, _ = self.arm.measured_jp()
        angles = [0, 1, 3, 4, 5]  # (joint 2 is the insertion, in m)
        error = numpy.max(numpy.abs(jp[angles] - goal[angles]))
        print(f"move_jp_error_deg: {math.degrees(error):.3f}")
        print(f"move_jp_insertion_error_mm: {1000 * abs(jp[2] - goal[2]):.3f}")
        # a relative move: 5 degrees on the first joint, then back
        delta = numpy.zeros(len(goal))
        delta[0] = math.radians(5.0)
        self.arm.move_jr(delta).wait()
        jp, _ = self.arm.measured_jp()
        print(f"move_jr_yaw_deg: {math.degrees(jp[0]):.3f}")
        self.arm.move_jr(-delta).wait()
        self.arm.insert_jp(0.13).wait()
        print(f"insert_jp_mm: {1000 * self.arm.measured_jp()[0][2]:.3f}")

    def cartesian_moves(self):
        start, _ = self.arm.setpoint_cp()
        goal = PyKDL.Frame(start.M, start.p)
        goal.p[0] += 0.02  # 2 cm along x of the arm's base frame
        goal.M = start.M * PyKDL.Rotation.RotZ(math.radians(20.0))
        print(f"move_cp_wait: {self.arm.move_cp(goal).wait()}")
        cp, _ = self.arm.measured_cp()
        print(f"move_cp_error_mm: {1000 * (cp.p - goal.p).Norm():.3f}")
        error = goal.M.Inverse() * cp.M
        print(f"move_cp_rotation_error_deg: {math.degrees(error.GetRotAngle()[0]):.3f}")
        self.arm.move_cp(start).wait()
        cp, _ = self.arm.measured_cp()
        print(f"move_cp_back_error_mm: {1000 * (cp.p - start.p).Norm():.3f}")

    def jaw(self):
        print(f"jaw_open_wait: {self.arm.jaw.open(angle=math.radians(50.0)).wait()}")
        print(f"jaw_open_deg: {math.degrees(self.arm.jaw.measured_jp()[0][0]):.2f}")
        print(f"jaw_close_wait: {self.arm.jaw.close().wait()}")
        print(f"jaw_closed_deg: {math.degrees(self.arm.jaw.measured_jp()[0][0]):.2f}")

    def run(self):
        self.home()
        self.joint_moves()
        self.cartesian_moves()
        self.jaw()
        print("done")


if __name__ == "__main__":
    argv = crtk.ral.parse_argv(sys.argv[1:])  # skip the script's name and ROS arguments
    parser = argparse.ArgumentParser()
    parser.add_argument(
        "-a", "--arm", type=str, default="PSM1", choices=["PSM1", "PSM2", "PSM3"], help="arm name"
    )
    args = parser.parse_args(argv)
    ral = crtk.ral("psm_moves")
    application = example_application(ral, args.arm)
    ral.spin_and_execute(application.run)
