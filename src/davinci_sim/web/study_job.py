"""A small study run from the web console's study tab: :class:`StudyJob`.

The page asks for a study of the served task (subjects, repetitions per condition); the job
runs :func:`davinci_sim.study.run_study` with the batch engine in a thread of the server's
process (its trials in one worker process: the 1 kHz loop keeps the other core), reports
progress as trials finish, and writes the outputs of ``davinci-sim study`` (``trials.csv``,
the figures, ``report.md``) into a folder of its own, which the server offers under
``/study/<file>``. One study at a time; the synthetic trainees are the study's own, so the
live console is not involved.
"""

from __future__ import annotations

import logging
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path

_log = logging.getLogger("davinci_sim.web")

#: Largest study a page may start (trials = subjects x conditions x repetitions).
MAX_SUBJECTS = 10
MAX_REPETITIONS = 5


class StudyJob:
    """One study at a time, in a thread; ``notify(message)`` gets its progress messages
    (called from the job's thread: the server forwards them to every page)."""

    def __init__(self, task: str, notify: Callable[[dict], None]) -> None:
        self.task = task
        self.notify = notify
        self.folder: Path | None = None
        self.files: list[str] = []
        self._thread: threading.Thread | None = None
        self._tmp: tempfile.TemporaryDirectory | None = None

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self, subjects: int, repetitions: int, seed: int = 0) -> str | None:
        """Start a study; returns None, or why it cannot start."""
        if self.running:
            return "a study is already running"
        if not 1 <= subjects <= MAX_SUBJECTS:
            return f"subjects must be in 1..{MAX_SUBJECTS}"
        if not 1 <= repetitions <= MAX_REPETITIONS:
            return f"repetitions must be in 1..{MAX_REPETITIONS}"
        from davinci_sim.study import StudyConfig, StudyError
        from davinci_sim.tasks import TaskError, load_task

        try:  # the study's trials, engines and report are the path kind's
            kind = load_task(self.task if not Path(self.task).suffix else Path(self.task)).kind
        except (TaskError, OSError) as e:
            return str(e)
        if kind != "path":
            return f"the study runs path tasks; {self.task!r} is a {kind} exercise"
        try:
            config = StudyConfig(n_subjects=subjects, n_repetitions=repetitions,
                                 task=self.task, seed=seed, workers=1)  # fmt: skip
        except (StudyError, ValueError) as e:
            return str(e)
        if self._tmp is not None:
            self._tmp.cleanup()
        self._tmp = tempfile.TemporaryDirectory(prefix="davinci-sim-study-")
        self.folder = Path(self._tmp.name)
        self.files = []
        self._thread = threading.Thread(target=self._run, args=(config,), name="web-study",
                                        daemon=True)  # fmt: skip
        self._thread.start()
        return None

    def _run(self, config) -> None:
        from davinci_sim.study import plan_trials, run_study, write_outputs

        total = len(plan_trials(config))
        self.notify({"op": "study", "state": "running", "done": 0, "total": total})
        try:
            result = run_study(config, progress=lambda done, n: self.notify(
                {"op": "study", "state": "running", "done": done, "total": n}))  # fmt: skip
            paths = write_outputs(result, self.folder)
        except Exception as e:  # the server goes on; the page says what happened
            _log.exception("the web study failed")
            self.notify({"op": "study", "state": "failed", "message": str(e)})
            return
        self.files = [p.name for p in paths]
        report = (self.folder / "report.md").read_text()
        self.notify({"op": "study", "state": "done", "done": total, "total": total,
                     "files": self.files, "report": report,
                     "seconds": round(result.wall_time, 1)})  # fmt: skip

    def file(self, name: str) -> bytes | None:
        """A file of the last study's outputs (None: not one of them)."""
        if self.folder is None or name not in self.files:
            return None
        return (self.folder / name).read_bytes()

    def close(self) -> None:
        if self._thread is not None:
            self._thread.join(timeout=0.1)
        if self._tmp is not None and not self.running:
            self._tmp.cleanup()
            self._tmp = None
