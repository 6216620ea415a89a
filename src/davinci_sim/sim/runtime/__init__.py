"""Running the simulation: real-time pacing, period statistics, the loop in its own process.

* :class:`LoopRunner` — ticks a simulation in this thread, paced or as fast as possible.
* :class:`ProcessSimulation` — the loop in a child process behind the ``SimHandle`` protocol,
  with shared-memory state and an optional stereo render process.
* :class:`PeriodStatistics` — achieved rate, period percentiles and maximum, overruns.
"""

from davinci_sim.sim.runtime.loop import LoopRunner, Pacer, reduce_timer_slack
from davinci_sim.sim.runtime.process import LoopProcessError, ProcessSimulation
from davinci_sim.sim.runtime.render import RenderStatistics, StereoFrame
from davinci_sim.sim.runtime.stats import PeriodRecorder, PeriodStatistics

__all__ = [
    "LoopProcessError",
    "LoopRunner",
    "Pacer",
    "PeriodRecorder",
    "PeriodStatistics",
    "ProcessSimulation",
    "RenderStatistics",
    "StereoFrame",
    "reduce_timer_slack",
]
