#!/usr/bin/env python3
"""Apply a wrench on an MTM's handle (``body.servo_cf``), as dvrk_python's MTM test does:
gravity compensation on, a force of -3 N along z in the base frame's orientation, the
handle drops; then no force and ``hold``. Public API (crtk_python / dvrk_python). Run with
``davinci-sim run --scene psm1_ecm_mtmr --no-console examples/dvrk_scripts/mtm_wrench.py``.

Prints ``name: value`` lines (mm, N).
"""

import argparse
import sys
import time

import crtk
import dvrk
import numpy


def run(ral, mtm, force):
    ral.check_connections()
    if not mtm.enable(10) or not mtm.home(20):
        sys.exit("failed to enable/home the MTM")
    print(f"gripper_measured_js_len: {len(mtm.gripper.measured_js()[0])}")
    start, _ = mtm.measured_cp()
    mtm.use_gravity_compensation(True)
    mtm.body_set_cf_orientation_absolute(True)
    mtm.body.servo_cf(numpy.array([0.0, 0.0, force, 0.0, 0.0, 0.0]))
    time.sleep(0.5)
    pushed, _ = mtm.measured_cp()
    print(f"dz_under_force_mm: {1000 * (pushed.p[2] - start.p[2]):.2f}")
    wrench, _ = mtm.body.measured_cf()
    print(f"measured_cf_len: {len(wrench)}")
    jacobian, _ = mtm.body.jacobian()
    print(f"jacobian_shape: {jacobian.shape[0]}x{jacobian.shape[1]}")
    mtm.body.servo_cf(numpy.zeros(6))
    mtm.hold()
    time.sleep(0.3)
    held, _ = mtm.measured_cp()
    time.sleep(0.3)
    still, _ = mtm.measured_cp()
    print(f"drift_after_hold_mm: {1000 * (still.p - held.p).Norm():.3f}")
    print("done")


if __name__ == "__main__":
    argv = crtk.ral.parse_argv(sys.argv[1:])
    parser = argparse.ArgumentParser()
    parser.add_argument("-a", "--arm", default="MTMR", choices=["MTML", "MTMR"])
    parser.add_argument("-f", "--force", type=float, default=-3.0, help="N along z")
    args = parser.parse_args(argv)
    ral = crtk.ral("mtm_wrench")
    mtm = dvrk.mtm(ral, args.arm)
    ral.spin_and_execute(run, ral, mtm, args.force)
