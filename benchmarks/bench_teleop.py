"""As-fast-as-possible teleoperation tick: devices + console + teleoperation (IK) + physics +
force fields, with the simulated hands moving the MTMs.

Two set-ups: one MTM-PSM pair (MTMR -> PSM1, scene ``psm1_ecm_mtmr``) and the full system
with both MTMs following (MTMR -> PSM1, MTML -> PSM2). Force fields: the built-in contact
feedback and a viscous field on the tool velocity (the kind of field issue 4 adds). The bare
tick of the same scene (arms idle, no console) is measured for reference.
"""

from __future__ import annotations

import logging
import os

from common import summary, time_each, write
from davinci_sim.sim.simulation import Simulation
from davinci_sim.system import ConsoleDescription, SystemDescription, build_simulation


def viscous(state):
    """-2 N·s/m on the tool-tip velocity (camera axes = HRSV axes)."""
    return -2.0 * state.v_camera_tip


def teleop_sim(scene: str) -> Simulation:
    console = ConsoleDescription(
        operator_present=True, teleop_enabled=True, contact_feedback=True, scripted_hands=True
    )
    sim = build_simulation(SystemDescription(scene, console=console))
    console = sim.components["console"]
    console.haptics.add_field(viscous)
    teleops = [t for t in console.psm_teleops.values() if t.selected]
    if not sim.run_until(lambda: all(t.is_following() for t in teleops), 30):
        raise RuntimeError("the teleoperations did not start following")
    sim.run_for(0.5)  # the hands are moving
    return sim


def main(n: int = 5000) -> None:
    logging.getLogger("davinci_sim").setLevel(logging.ERROR)
    figures: dict = {"load_average_before": os.getloadavg()[0]}
    for label, scene in (("one_pair", "psm1_ecm_mtmr"), ("full_two_pairs", "full")):
        bare = Simulation(scene, keyframe="surgical")
        figures.update(summary(time_each(bare.tick, n), f"{label}_bare_tick"))
        sim = teleop_sim(scene)
        figures.update(summary(time_each(sim.tick, n), f"{label}_teleop_tick"))
        teleops = sim.components["console"].psm_teleops.values()
        following = [t.name for t in teleops if t.is_following()]
        figures[f"{label}_following"] = ",".join(following)
    figures["target_teleop_tick_median_us"] = 300.0
    figures["load_average_after"] = os.getloadavg()[0]
    write("teleop", figures)


if __name__ == "__main__":
    main()
