"""The trainee records at the console: a part of ``davinci-sim serve`` that records every
attempt of the served task session.

:func:`records_part` returns what :func:`davinci_sim.bridge.app.serve` takes as a *part*: a
callable given the running :class:`~davinci_sim.system.System`, which attaches an
:class:`~davinci_sim.records.recorder.AttemptRecorder` to the system's handle (every
repetition the session finishes, whoever does it: a person at the web console, a ROS
client, a synthetic trainee) and is stopped with the rest. A write that fails is put on the
session's message channel (``TaskSession.report``: the web console's messages, the bridge's
``/rosout``), as the session's CSV log does, and the simulation goes on.
"""

from __future__ import annotations

from pathlib import Path

from davinci_sim.records.db import default_path
from davinci_sim.records.recorder import AttemptRecorder


def condition_settings(task, condition: str | dict | None) -> dict:
    """The fixture entry of ``task``'s ``condition`` as ``serve`` gives it (a condition name,
    ``B:G_max``, a fixture entry, None for the task's own fixture)."""
    from davinci_sim.system.description import task_condition

    spec = task_condition(task, condition)
    if spec is None:
        spec = task.fixture_spec
    elif isinstance(spec, str):
        spec = task.condition(spec)
    return dict(spec)


def records_part(
    trainee: str,
    *,
    path: str | Path | None = None,
    task: str | None = None,
    condition: str | None = None,
    source: str = "serve",
    component: str = "task",
):
    """A ``serve`` part recording ``trainee``'s attempts at the session of ``task`` (name or
    file; its metrics' units) in ``path`` (None: :func:`default_path`). The part adds
    ``records`` (the file) and ``trainee`` to the ready info. The recorder is also returned
    by the part, so a page can change the trainee (``set_trainee``)."""
    path = Path(path) if path is not None else default_path()

    def start(system, info: dict) -> AttemptRecorder:
        loaded = None
        settings: dict = {}
        if task is not None:
            from davinci_sim.tasks import load_task

            loaded = load_task(task)
            settings = condition_settings(loaded, condition)
        handle = system.handle

        def on_error(text: str) -> None:
            handle.call(component, "report", "error", f"records: {text}")

        recorder = AttemptRecorder(path, trainee, task=loaded, settings=settings, source=source,
                                   on_error=on_error, component=component)  # fmt: skip
        info["records"] = str(path)
        info["trainee"] = recorder.trainee
        return recorder.attach(handle)

    return start
