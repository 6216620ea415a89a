"""As-fast-as-possible teleoperation tick: devices + console + teleoperation (IK) + physics +
force fields, with the simulated hands moving the MTMs.

Two set-ups: one MTM-PSM pair (MTMR -> PSM1, scene ``psm1_ecm_mtmr``) and the full system
with both MTMs following (MTMR -> PSM1, MTML -> PSM2). Force fields: the built-in contact
feedback and a viscous field on the tool velocity (the kind of field issue 4 adds). The bare
tick of the same scene (arms idle, no console) is measured for reference, and the ratio
teleop tick / bare tick reported (issue 9's figures: one pair ≤ 100 µs, both pairs ≤ 150 µs).

A third set-up is what ``make run`` ticks (``serve_seed_path``): the full scene homed, the
web console's rate inputs on both MTMs (held still: the operator reading the keys), the
``seed_path`` task session with its viscous fixture and the endoscope framed on the task,
both teleoperations following; ``serve_seed_path_trial`` the same while a repetition of the
task runs (the tool moved off point 1: the session's metrics accumulate every tick);
``serve_one_pair`` what ``serve --scene psm1_ecm_mtmr --task seed_path --home`` ticks, one
web-console hand (MTMR) holding still, MTMR -> PSM1 following: the one-pair bar on the
console's compiled path (the ``one_pair`` set-up's Python hands and field keep every tick in
Python); ``serve_camera`` ``serve_seed_path``'s system with the camera pedal held (the ECM
teleoperation following both hands, held still).

Beside each tick, ``<label>_mj_step_median_us`` is MuJoCo's own ``mj_step`` on the same
model at the same state (the set-up's state restored before each step, not timed), and
``<label>_teleop_over_mj_step_ratio`` the tick over it: what the Python of the tick costs
on top of the physics (issue 20's bar: ≤ 1.5 both pairs, ≤ 1.3 one pair). That tick is
``Simulation.tick``, one at a time in Python (the oracle). ``<label>_live_tick`` is the tick
as the live runners run it: passes of ``CHUNK_TICKS`` (4) ticks through
``Simulation.advance``, the console's compiled calls wherever its state allows
(``console/chunk.py``; ``<label>_compiled_share`` of the ticks), their write-back into the
components at the end of each 10 ms snapshot period (``LoopRunner.run``), per tick;
``<label>_chunk32_tick`` a script's passes of 32 ticks.

Each set-up is also profiled (cProfile, 1000 ticks): the JSON keeps the top entries by own
time, as shares of the profiled tick (proportions survive a busy machine better than times),
and the Python function calls per tick.
"""

from __future__ import annotations

import cProfile
import logging
import os
import pstats
import statistics
import time

import mujoco
import numpy as np

from common import summary, time_each, write
from davinci_sim.sim.runtime.loop import CHUNK_TICKS
from davinci_sim.sim.runtime.process import LoopOptions
from davinci_sim.sim.simulation import Simulation
from davinci_sim.system import (
    ConsoleDescription,
    SystemDescription,
    TaskDescription,
    build_simulation,
)
from davinci_sim.tasks.session import VIEW_DISTANCE
from davinci_sim.tasks.state import Phase


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


def serve_sim(trial: bool = False, task: str = "seed_path", scene: str = "full",
              hands: tuple[str, ...] = ("MTML", "MTMR")) -> Simulation:  # fmt: skip
    """What ``make run`` (``serve --task seed_path --home``) ticks, with the person at the
    web console holding both handles still after taking control; with ``trial``, the
    handle moved 3 cm so that the tool left point 1 and a repetition runs (its metrics
    accumulate every tick); ``task`` another exercise in its place; ``scene`` and ``hands``
    another system (``psm1_ecm_mtmr`` with ``("MTMR",)``: one pair)."""
    sim = build_simulation(
        SystemDescription(
            scene=scene,
            keyframe="surgical",
            console=ConsoleDescription(hand_inputs=hands),
            task=TaskDescription(task, frame_view=VIEW_DISTANCE),
            home=True,
            runner="none",
            real_time=False,
        )
    )
    sim.run_for(8.0)  # homing, then the endoscope framed on the task
    console = sim.components["console"]
    console.press("operator_present")
    console.teleop_enable(True)
    for hand in hands:
        sim.components[f"{hand}/hand"].grasp()
    teleops = [t for t in console.psm_teleops.values() if t.selected]
    if not sim.run_until(lambda: all(t.is_following() for t in teleops), 30):
        raise RuntimeError("the teleoperations did not start following")
    sim.run_for(0.5)
    if trial:
        device = sim.components["MTMR/device"]
        T = device.input().T_hrsv_tip.copy()
        T[2, 3] += 0.03
        device.move_hand(T)
        session = sim.components["task"]
        if not sim.run_until(lambda: session.monitor.phase == Phase.RUNNING, 5):
            raise RuntimeError(f"the repetition did not start: {session.monitor.phase}")
        sim.run_for(0.2)
    return sim


def camera_sim() -> Simulation:
    """``serve_sim``'s system with the camera pedal held: the ECM teleoperation following
    both hands (held still), the PSM teleoperations off."""
    sim = serve_sim()
    console = sim.components["console"]
    console.press("camera")
    if not sim.run_until(lambda: console.ecm_teleop.snapshot().following, 10):
        raise RuntimeError("the camera teleoperation did not start following")
    sim.run_for(0.2)
    return sim


def mj_step_each(sim: Simulation, n: int, warmup: int = 50) -> list[float]:
    """Wall time (µs) of ``n`` bare ``mj_step`` calls on ``sim``'s model, each from ``sim``'s
    current integration state (restored before the step, untimed): the physics of the same
    scene in the same configuration, without any of the tick's Python."""
    model = sim.model
    data = mujoco.MjData(model)
    what = mujoco.mjtState.mjSTATE_INTEGRATION
    state = np.empty(mujoco.mj_stateSize(model, what))
    mujoco.mj_getState(model, sim.data, state, what)
    clock = time.perf_counter_ns
    out = []
    for i in range(n + warmup):
        mujoco.mj_setState(model, data, state, what)
        t0 = clock()
        mujoco.mj_step(model, data)
        if i >= warmup:
            out.append((clock() - t0) / 1000.0)
    return out


def live_ticks(sim: Simulation, label: str, n: int) -> dict:
    """The tick as the live runners run it: their snapshot periods (10 ticks), each in passes
    of ``CHUNK_TICKS`` ticks through ``Simulation.advance`` (the console's compiled calls
    where its state allows, else Python's ticks), the write-back deferred to the period's
    last pass (``LoopRunner.run``), per tick; a script's passes of 32 ticks; the share of
    ticks the compiled calls ran; both over the set-up's ``mj_step``."""
    chunker = sim.chunker
    ran = [0, 0]

    class Counted:
        """The chunker, its ticks counted."""

        def __call__(self, k: int, changed: bool = True, **kwargs) -> tuple[int, bool]:
            whole, post = chunker(k, changed, **kwargs)
            ran[0] += whole + int(post)
            return whole, post

        def flush(self) -> None:
            chunker.flush()

    out: dict = {}
    if chunker is not None:
        sim.set_chunker(Counted())
    start = sim.tick_count
    period = round(LoopOptions().snapshot_period / sim.dt)

    def live_period() -> None:
        # (unchanged: nothing but the passes runs between them, as a live runner's idle loop)
        done = 0
        while done < period:
            k = min(CHUNK_TICKS, period - done)
            done += k
            sim.advance(k, unchanged=True, defer=done < period)

    def script() -> None:
        sim.advance(32, unchanged=True)

    for name, k, run in (("live_tick", period, live_period), ("chunk32_tick", 32, script)):
        passes = time_each(run, max(1, n // k), warmup=max(1, 200 // k))
        out.update(summary([p / k for p in passes], f"{label}_{name}"))
        out[f"{label}_{name}_over_mj_step_ratio"] = out[
            f"{label}_{name}_median_us"
        ] / statistics.median(mj_step_each(sim, 500))
    if chunker is not None:
        sim.set_chunker(chunker)
    out[f"{label}_compiled_share"] = ran[0] / max(1, sim.tick_count - start)
    return out


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
    out: list[dict] = [{"python_calls_per_tick": sum(e[1] for e in stats.values()) / ticks}]
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
    for label, scene in (
        ("one_pair", "psm1_ecm_mtmr"),
        ("full_two_pairs", "full"),
        ("serve_seed_path", "full"),
        ("serve_seed_path_trial", "full"),
        ("serve_one_pair", "psm1_ecm_mtmr"),
        ("serve_camera", "full"),
    ):
        bare = Simulation(scene, keyframe="surgical")
        figures.update(summary(time_each(bare.tick, n), f"{label}_bare_tick"))
        if label == "serve_one_pair":  # (issue 20's one-pair bar on the console's own path)
            sim = serve_sim(scene=scene, hands=("MTMR",))
        elif label == "serve_camera":
            sim = camera_sim()
        elif label.startswith("serve_seed_path"):
            sim = serve_sim(trial=label.endswith("trial"))
        else:
            sim = teleop_sim(scene)
        figures.update(summary(time_each(sim.tick, n), f"{label}_teleop_tick"))
        figures.update(summary(mj_step_each(sim, n), f"{label}_mj_step"))
        tick = figures[f"{label}_teleop_tick_median_us"]
        figures[f"{label}_teleop_over_bare_ratio"] = tick / figures[f"{label}_bare_tick_median_us"]
        figures[f"{label}_teleop_over_mj_step_ratio"] = tick / figures[f"{label}_mj_step_median_us"]
        figures.update(live_ticks(sim, label, n))
        console = sim.components["console"]
        following = [t.name for t in console.psm_teleops.values() if t.is_following()]
        if console.ecm_teleop is not None and console.ecm_teleop.snapshot().following:
            following.append(console.ecm_teleop.name)
        figures[f"{label}_following"] = ",".join(following)
        figures[f"{label}_fields"] = ",".join(console.haptics.field_names())
        figures[f"{label}_profile_top"] = profile_top(sim.tick)
    figures["target_one_pair_teleop_tick_median_us"] = 100.0
    figures["target_full_two_pairs_teleop_tick_median_us"] = 150.0
    figures["load_average_after"] = os.getloadavg()[0]
    write("teleop", figures)


if __name__ == "__main__":
    main()
