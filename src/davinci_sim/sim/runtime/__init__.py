"""Running the simulation: real-time pacing, period statistics, the loop in its own process.

* :class:`LoopRunner` — ticks a simulation in this thread, paced or as fast as possible: the
  one loop of both runners (``ThreadedSimulation`` runs it in a thread).
* :class:`ProcessSimulation` — the loop in a child process behind the ``SimHandle`` protocol,
  with shared-memory state and an optional stereo render process.
* :class:`StereoRenderer` — the one stereo render pipeline: the endoscope rendered in its
  own process from joint positions in shared memory (both runners' ``render_hz``, the
  bridge's image topics).
* :class:`PeriodStatistics` — achieved rate, period percentiles and maximum, overruns.
"""

from davinci_sim.sim.runtime.loop import LoopRunner, Pacer, reduce_timer_slack
from davinci_sim.sim.runtime.process import LoopProcessError, ProcessSimulation
from davinci_sim.sim.runtime.render import QposProbe, RenderStatistics, StereoFrame, StereoRenderer
from davinci_sim.sim.runtime.stats import PeriodRecorder, PeriodStatistics

__all__ = [
    "LoopProcessError",
    "LoopRunner",
    "Pacer",
    "PeriodRecorder",
    "PeriodStatistics",
    "ProcessSimulation",
    "QposProbe",
    "RenderStatistics",
    "StereoFrame",
    "StereoRenderer",
    "reduce_timer_slack",
]
