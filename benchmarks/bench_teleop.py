"""As-fast-as-possible teleoperation tick: devices + console + teleoperation (IK) + physics +
force fields, with the simulated hands moving the MTMs.

Two set-ups: one MTM-PSM pair (MTMR -> PSM1, scene ``psm1_ecm_mtmr``) and the full system
with both MTMs following (MTMR -> PSM1, MTML -> PSM2). Force fields: the built-in contact
feedback and a viscous field on the tool velocity (the kind of field issue 4 adds). The bare
tick of the same scene (arms idle, no console) is measured for reference, and the ratio
teleop tick / bare tick reported (issue 9's figures: one pair ≤ 100 µs, both pairs ≤ 150 µs).

Each set-up is also profiled (cProfile, 1000 ticks): the JSON keeps the top entries by own
time, as shares of the profiled tick (proportions survive a busy machine better than times).
"""

from __future__ import annotations

import cProfile
import logging
import os
import pstats

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


def profile_top(tick, ticks: int = 1000, top: int = 12) -> list[dict]:
    """The ``top`` functions by own time over ``ticks`` calls of ``tick``: name, calls per
    tick, own and cumulative share of the (profiled) tick."""
    profiler = cProfile.Profile()
    profiler.enable()
    for _ in range(ticks):
        tick()
    profiler.disable()
    stats = pstats.Stats(profiler).stats  # type: ignore[attr-defined]
    total = sum(entry[2] for entry in stats.values())
    rows = sorted(stats.items(), key=lambda kv: kv[1][2], reverse=True)[:top]
    out = []
    for (filename, line, name), (_, calls, own, cumulative, _) in rows:
        where = filename.split("davinci_sim/")[-1] if "davinci_sim/" in filename else filename
        out.append(
            {
                "function": f"{where}:{line}({name})" if line else name,
                "calls_per_tick": round(calls / ticks, 3),
                "own_share": round(own / total, 4),
                "cumulative_share": round(cumulative / total, 4),
            }
        )
    return out


def main(n: int = 5000) -> None:
    logging.getLogger("davinci_sim").setLevel(logging.ERROR)
    figures: dict = {"load_average_before": os.getloadavg()[0]}
    for label, scene in (("one_pair", "psm1_ecm_mtmr"), ("full_two_pairs", "full")):
        bare = Simulation(scene, keyframe="surgical")
        figures.update(summary(time_each(bare.tick, n), f"{label}_bare_tick"))
        sim = teleop_sim(scene)
        figures.update(summary(time_each(sim.tick, n), f"{label}_teleop_tick"))
        figures[f"{label}_teleop_over_bare_ratio"] = (
            figures[f"{label}_teleop_tick_median_us"] / figures[f"{label}_bare_tick_median_us"]
        )
        teleops = sim.components["console"].psm_teleops.values()
        following = [t.name for t in teleops if t.is_following()]
        figures[f"{label}_following"] = ",".join(following)
        figures[f"{label}_fields"] = ",".join(sim.components["console"].haptics.field_names())
        figures[f"{label}_profile_top"] = profile_top(sim.tick)
    figures["target_one_pair_teleop_tick_median_us"] = 100.0
    figures["target_full_two_pairs_teleop_tick_median_us"] = 150.0
    figures["load_average_after"] = os.getloadavg()[0]
    write("teleop", figures)


if __name__ == "__main__":
    main()
