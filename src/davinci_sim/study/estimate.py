"""How long a study will take, estimated before it starts from a quick calibration here.

The batch engine's wall time per 1 ms tick is about ``a + b·n`` for n running trials
(``benchmarks/bench_study.py``): ``a`` the laws' fixed cost per tick (numpy calls, one row
or many), ``b`` per running trial (mostly its ``mj_step``). A chunk of trials lasting
``T_i`` ticks each then takes about ``a·max(T_i) + b·ΣT_i`` (the chunk runs until its last
trial ends; ended trials stop costing), and the chunks run side by side, one per worker
process (:func:`~davinci_sim.study.runner.processes`); adaptive conditions' rounds
(:mod:`davinci_sim.study.adaptive`) run one after the other, each as long as its slowest
chunk. :func:`estimate_study` measures
``a`` and ``b`` on this machine as it is now (the mean tick of a one-trial batch and of a
batch of the largest chunk, each timed for ≥ 0.15 s; ~1 s in all with the set-up) and
takes each trial's duration from its trainee's plan (the strokes' durations plus the
visuomotor delay and the reaction time, capped by the timeout), a little longer than the
trial (the task ends within the finish tolerance).

The calibration builds the trial set-up in this process (compiling the model, and the
laws on a cold numba cache): the study's trials reuse it — in this process, and in worker
processes started by fork — so it is not a cost added to the study. The calibration sees
how busy the machine is while it runs (a tick waiting for the core is slower), but not the
load the study's own worker processes add: with fewer free cores than workers the study
takes longer than estimated.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from davinci_sim.study.adaptive import rounds
from davinci_sim.study.config import StudyConfig, plan_trials
from davinci_sim.study.runner import chunks, processes
from davinci_sim.study.trial import TrialSpec, load_spec_task, setup_trial, trial_inputs

#: Ticks timed for the calibration, at least (after a few not timed) ...
CALIBRATION_TICKS = 30
#: ... and wall time spent timing each batch, at least, s: long enough to see the share of
#: the CPU this process gets now (on a busy machine a tick waits for the core).
CALIBRATION_S = 0.15


@dataclass(frozen=True)
class StudyEstimate:
    """An estimate of a study's wall time on this machine (see the module docstring)."""

    n_trials: int
    """Trials to run."""
    processes: int
    """Worker processes (1: the trials run in the calling process)."""
    tick_s: float
    """``a``: wall time of a tick of a batch, fixed part, s."""
    trial_tick_s: float
    """``b``: wall time of a tick per running trial, s."""
    trial_sim_s: float
    """Mean planned duration of a trial, simulated s."""
    wall_s: float
    """Estimated wall time of running the trials, s."""
    calibration_s: float
    """Wall time the calibration took (set-up included), s."""

    def line(self) -> str:
        """The estimate in one line, for the terminal."""
        who = "this process" if self.processes == 1 else f"{self.processes} worker processes"
        # (two significant digits below 10 s: a short study's 0.03 s is not "0.0 s")
        wall = f"{self.wall_s:.0f}" if self.wall_s >= 10 else f"{self.wall_s:.2g}"
        return (
            f"estimate: {self.n_trials} trials on {who}, about {wall} s "
            f"(trials ~{self.trial_sim_s:.1f} s simulated each; a tick here costs "
            f"{self.tick_s * 1e3:.2f} ms + {self.trial_tick_s * 1e6:.0f} µs per running trial)"
        )


def planned_durations(specs: list[TrialSpec]) -> np.ndarray:
    """Each trial's planned duration, simulated s (trainee's plan, capped by its timeout)."""
    task = load_spec_task(specs[0])
    setup = setup_trial(task)
    params, trainee = trial_inputs(specs, task, setup.T_world_camera, np.zeros(3))
    t = trainee.durations.sum(axis=1) + params.delay + params.reaction_time
    return np.minimum(t, [s.timeout for s in specs])


def _mean_time(step, ticks: int) -> float:
    """Mean wall time of a tick, s, ``step()`` running one (returning None) or several
    (returning how many), over at least ``ticks`` ticks and :data:`CALIBRATION_S` (the
    mean, not the median: waiting for the core is part of it)."""
    for _ in range(3):
        step()
    n, t0 = 0, time.perf_counter()
    while n < ticks or time.perf_counter() - t0 < CALIBRATION_S:
        n += step() or 1
    return (time.perf_counter() - t0) / n


def _tick_cost(specs: list[TrialSpec], ticks: int) -> float:
    """Wall time of one tick of a batch of ``specs`` as the study runs it (a chunk of
    ticks at a time where it can), s."""
    from davinci_sim.study import batch_chunk
    from davinci_sim.study.batch import TrialBatch

    batch = TrialBatch(specs)
    if batch_chunk.can_chunk(batch):
        return _mean_time(lambda: batch_chunk.advance(batch), ticks)
    return _mean_time(batch.tick, ticks)


def _live_tick_cost(specs: list[TrialSpec], ticks: int) -> float:
    """Wall time of one tick of the live trial simulation (without the trainee's hand), s."""
    return _mean_time(setup_trial(load_spec_task(specs[0])).sim.tick, ticks)


def estimate_study(
    config: StudyConfig, specs: list[TrialSpec] | None = None, *, ticks: int = CALIBRATION_TICKS
) -> StudyEstimate:
    """Estimate the wall time of running ``specs`` (default: every trial of ``config``) as
    :func:`~davinci_sim.study.runner.run_study` would, calibrated here (~1 s)."""
    t0 = time.perf_counter()
    specs = plan_trials(config) if specs is None else list(specs)
    if not specs:
        return StudyEstimate(0, 1, 0.0, 0.0, 0.0, 0.0, 0.0)
    if config.backend == "local":
        n_proc = processes(len(specs), config.workers)
    else:
        n_proc = min(config.workers, len(specs))
    parts = chunks(len(specs), n_proc)
    durations = planned_durations(specs)
    dt = setup_trial(load_spec_task(specs[0])).sim.dt
    if config.engine == "live":  # one trial after the other: no shared part
        a, b = 0.0, _live_tick_cost(specs, ticks)
    else:
        a = _tick_cost(specs[:1], ticks)
        largest = max(parts, key=len)
        if len(largest) > 1:
            c = _tick_cost([specs[i] for i in largest], ticks)
            b = max(c - a, 0.0) / (len(largest) - 1)
        else:
            b = 0.0
        a = max(a - b, 0.0)
    wall = 0.0
    of_round = rounds(specs)  # (adaptive conditions run in rounds, one after the other)
    for r in sorted(set(of_round)):
        members = [i for i, k in enumerate(of_round) if k == r]
        slowest = 0.0
        for part in chunks(len(members), min(n_proc, len(members))):
            T = durations[[members[i] for i in part]] / dt
            slowest = max(slowest, a * float(T.max()) + b * float(T.sum()))
        wall += slowest
    return StudyEstimate(
        n_trials=len(specs),
        processes=n_proc,
        tick_s=a,
        trial_tick_s=b,
        trial_sim_s=float(durations.mean()),
        wall_s=wall,
        calibration_s=time.perf_counter() - t0,
    )
