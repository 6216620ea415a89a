"""The 1 kHz tick calls every compiled kernel with the argument types its module's warm-up
compiled at import: no kernel gets a second signature inside the loop (with a cold numba
cache that is a compile of seconds in the simulation thread, the stall the warm-up exists
to prevent; a read-only or transposed array is enough to cause one)."""

from __future__ import annotations

import importlib
import pkgutil

import pytest

import davinci_sim
from davinci_sim.kinematics import jit
from davinci_sim.system import (
    ConsoleDescription,
    SystemDescription,
    TaskDescription,
    build_simulation,
)


@pytest.mark.skipif(not jit.ENABLED, reason="numba is off: nothing is compiled")
def test_the_live_tick_compiles_no_new_kernel_signature():
    for module in pkgutil.walk_packages(davinci_sim.__path__, "davinci_sim."):
        importlib.import_module(module.name)
    # Every kernel compiled at import: from here the build, the homing and the following
    # must call each with a signature it has.
    from davinci_sim.console import haptic_row, teleop_row
    from davinci_sim.devices import device_row
    from davinci_sim.sim import cartesian_kernel
    from davinci_sim.tasks import path_row

    # (and the kernels a live part calls itself: servo_cp's, the teleoperation's, the MTM's)
    direct = (cartesian_kernel.servo_cp_row, teleop_row.follow_tick, device_row.hand_read_row,
              device_row.render_row, path_row.path_tick_rows, path_row.live_path_row,
              haptic_row.fixture_render)  # fmt: skip
    before = {k.__qualname__: len(k.dispatcher.signatures) for k in jit.KERNELS}
    before.update({k.__name__: len(k.signatures) for k in direct})
    console = ConsoleDescription(
        operator_present=True, teleop_enabled=True, contact_feedback=True, scripted_hands=True
    )
    sim = build_simulation(
        SystemDescription("psm1_ecm_mtmr", console=console, task=TaskDescription("seed_path"))
    )
    teleop = sim.components["console"].psm_teleops["MTMR_PSM1"]
    assert sim.run_until(teleop.is_following, 30)
    sim.run_for(0.3)  # following: teleoperation, hand, haptics, fixture, task session
    assert sim.components["console"].haptics.requested("MTMR") is not None
    after = {k.__qualname__: len(k.dispatcher.signatures) for k in jit.KERNELS}
    after.update({k.__name__: len(k.signatures) for k in direct})
    assert after == before


_IMPORTS_IN_THE_LOOP = """
import sys
from davinci_sim.system import (ConsoleDescription, SystemDescription, TaskDescription,
                                build_simulation)
console = ConsoleDescription(operator_present=True, teleop_enabled=True, contact_feedback=True,
                             scripted_hands=True)
sim = build_simulation(SystemDescription("psm1_ecm_mtmr", console=console,
                                         task=TaskDescription("seed_path")))
teleop = sim.components["console"].psm_teleops["MTMR_PSM1"]
before = set(sys.modules)
assert sim.run_until(teleop.is_following, 30)
sim.run_for(0.3)
print(sorted(set(sys.modules) - before))
"""


def test_the_live_tick_imports_nothing():
    """A fresh process (as ``make run``'s loop process): once the system is built, its
    ticks — homing, alignment, following, the haptic loop with the task's fixture, the task
    session — import no module. A module imported at its first use inside the loop (a
    kernel's warm-up with it) stalls the loop for its compile: 1.8 s seen in ``make run``
    with a cold numba cache."""
    import json
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", _IMPORTS_IN_THE_LOOP], capture_output=True,
                         text=True, timeout=600, check=True)  # fmt: skip
    imported = json.loads(out.stdout.strip().splitlines()[-1].replace("'", '"'))
    assert imported == []
