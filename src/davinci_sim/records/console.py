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

import threading
from pathlib import Path

from davinci_sim.records.db import RecordsDB, RecordsError, check_name, default_path
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


class RecordsPart:
    """The records as a ``serve`` part (see :func:`records_part`): called with the running
    system, it attaches an :class:`AttemptRecorder` and returns it (``serve`` stops it with
    the rest). :meth:`set_trainee` changes whose attempts these are (the web console's
    trainee field), before or after the start."""

    def __init__(self, trainee: str, path: Path, task: str | None, condition: str | None,
                 source: str, component: str) -> None:  # fmt: skip
        self.default_trainee = check_name(trainee)
        self.trainee = self.default_trainee
        """Whose attempts are recorded now."""
        self.path = path
        self.task, self.condition = task, condition
        self.source, self.component = source, component
        self.recorder: AttemptRecorder | None = None
        self.task_name: str | None = None
        """The served task's name (what its attempts are recorded under)."""
        self._curve: tuple[tuple, bytes] | None = None
        self._curve_lock = threading.Lock()

    def __call__(self, system, info: dict) -> AttemptRecorder:
        loaded = None
        settings: dict = {}
        if self.task is not None:
            from davinci_sim.tasks import load_task

            loaded = load_task(self.task)
            settings = condition_settings(loaded, self.condition)
            self.task_name = loaded.name
        handle = system.handle
        component = self.component

        def on_error(text: str) -> None:
            handle.call(component, "report", "error", f"records: {text}")

        recorder = AttemptRecorder(self.path, self.trainee, task=loaded, settings=settings,
                                   source=self.source, on_error=on_error,
                                   component=component)  # fmt: skip
        info["records"] = str(self.path)
        info["trainee"] = recorder.trainee
        self.recorder = recorder.attach(handle)
        return self.recorder

    def set_trainee(self, name: str) -> str:
        """Record the next attempts as ``name``'s (a new session of theirs); an empty name
        goes back to the trainee ``serve`` was given. Returns whose they are now.

        Raises:
            RecordsError: a bad name (nothing changes).
        """
        name = check_name(name) if name.strip() else self.default_trainee
        if name != self.trainee:
            if self.recorder is not None:
                self.recorder.set_trainee(name)
            self.trainee = name
        return name

    def curve_png(self) -> bytes:
        """The current trainee's learning curves at the served task, as PNG
        (:func:`~davinci_sim.records.report.curves_png`; a one-line note while the trainee
        has no attempt there), drawn again only once another attempt is recorded or the
        trainee changed."""
        from davinci_sim.records.report import curves_png, note_png

        with self._curve_lock:
            # (read once: the page may change the trainee while this draws, and the drawing
            # must be the one of the trainee it is cached for)
            trainee = self.trainee
            recorded = 0 if self.recorder is None else len(self.recorder.recorded)
            key = (trainee, recorded)
            if self._curve is not None and self._curve[0] == key:
                return self._curve[1]
            try:
                with RecordsDB(self.path, create=False) as db:
                    png = curves_png(db, trainee, task=self.task_name, columns=2)
            except RecordsError:  # no attempt yet (or no file yet): a note instead
                at = f" at {self.task_name}" if self.task_name else ""
                png = note_png(f"no recorded attempt of {trainee}{at} yet")
            self._curve = (key, png)
            return png


def records_part(
    trainee: str,
    *,
    path: str | Path | None = None,
    task: str | None = None,
    condition: str | None = None,
    source: str = "serve",
    component: str = "task",
) -> RecordsPart:
    """A ``serve`` part recording ``trainee``'s attempts at the session of ``task`` (name or
    file; its metrics' units) in ``path`` (None: :func:`default_path`). The part adds
    ``records`` (the file) and ``trainee`` to the ready info.

    Raises:
        RecordsError: a bad trainee name.
    """
    path = Path(path) if path is not None else default_path()
    return RecordsPart(trainee, path, task, condition, source, component)
