"""One assembly: a running system built from one description.

* :class:`SystemDescription` (with :class:`ConsoleDescription`, :class:`DeviceDescription`,
  :class:`TaskDescription`) — what the system is made of, as a frozen value;
* :func:`build_system` → :class:`System` — the simulation, console, task session, runner and
  stereo render pipeline, owned and stopped together; :func:`build_simulation` (the process
  runner's factory), :func:`new_simulation` and :func:`install_console_of` (the steps, for
  callers that prepare the arms in between), :func:`scene_model` (the renderers' model).

Layer: above ``tasks``/``operators`` (it uses sim, devices, console and tasks), below
``study``, ``bridge``, ``web`` and the CLI, which all build their systems here.
"""

from davinci_sim.system.build import (
    System,
    build_simulation,
    build_system,
    install,
    install_console_of,
    new_simulation,
    scene_model,
)
from davinci_sim.system.description import (
    ConsoleDescription,
    DeviceDescription,
    SystemDescription,
    TaskDescription,
    task_condition,
)

__all__ = [
    "ConsoleDescription",
    "DeviceDescription",
    "System",
    "SystemDescription",
    "TaskDescription",
    "build_simulation",
    "build_system",
    "install",
    "install_console_of",
    "new_simulation",
    "scene_model",
    "task_condition",
]
