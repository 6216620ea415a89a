"""``dvrk.console.teleop_get_scale()`` before anyone sets a scale: the dVRK's console emits the
default PSM teleoperation scale (0.2, dvrk.md 4.1) when it starts, and ``/console/teleop/scale``
is latched, so a script started later reads 0.2. dvrk_python's ``dvrk_console_test.py`` reads
it first and sets ``scale + 0.1``; it read 0.0 here (nothing published until a set_scale)."""

from __future__ import annotations

import time

import pytest
from transports import FAIL_AFTER, connected

from davinci_sim.compat import dvrk_api as dvrk
from davinci_sim.compat.ral import ral as make_ral
from davinci_sim.system import ConsoleDescription, SystemDescription, build_system


@pytest.fixture(params=["in-process", "rosbridge"])
def console_ral(request):
    """A fresh simulation with the surgeon console (no scale ever set) and a ``ral`` on it."""
    description = SystemDescription(scene="psm1_ecm_mtmr", keyframe="home",
                                    console=ConsoleDescription(), runner="thread",
                                    snapshot_period=0.01)  # fmt: skip
    system = build_system(description, start=True)
    with connected(system.handle, request.param):
        yield system, make_ral(f"test_scale_{request.param}")
    system.stop()


def read_scale(console, expected: float, timeout: float = 5.0) -> float:
    deadline = time.monotonic() + max(timeout, FAIL_AFTER)
    while console.teleop_get_scale() != pytest.approx(expected) and time.monotonic() < deadline:
        time.sleep(0.02)
    return console.teleop_get_scale()


def test_a_late_script_reads_the_startup_scale_then_its_own(console_ral):
    system, ral = console_ral
    assert system.handle.call("console", "scale").result(5.0) is None  # never set
    console = dvrk.console(ral)
    ral.check_connections(10)
    assert read_scale(console, 0.2) == pytest.approx(0.2)
    console.teleop_set_scale(0.3)  # what dvrk_console_test.py does next (0.2 + 0.1)
    assert read_scale(console, 0.3) == pytest.approx(0.3)
    assert system.handle.call("console", "scale").result(5.0) == pytest.approx(0.3)
