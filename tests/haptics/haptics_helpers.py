"""A console on the light scene, following (the haptics tests need a teleoperation)."""

from __future__ import annotations

from davinci_sim.console import install_console
from davinci_sim.sim.simulation import Simulation


def teleop_sim(**options):
    """PSM1 + ECM + MTMR (surgical view) with a console; MTMR_PSM1 follows and the hand
    holds the handle."""
    sim = Simulation("psm1_ecm_mtmr", keyframe="surgical")
    console = install_console(sim, operator_present=True, teleop_enabled=True, **options)
    assert sim.run_until(console.psm_teleops["MTMR_PSM1"].is_following, 10)
    sim.components["MTMR/device"].grasp()
    return sim, console
