"""A small study run from the web console's study tab: :class:`StudyJob`.

The page asks for a study of the served task (subjects, repetitions per condition); the job
runs :func:`davinci_sim.study.run_study` with the batch engine in a thread of the server's
process (its trials in one worker process: the 1 kHz loop keeps the other core), reports
progress as trials finish, and writes the outputs of ``davinci-sim study`` (``trials.csv``,
the figures, ``report.md``) into a folder of its own, which the server offers under
``/study/<file>``. One study at a time; the synthetic trainees are the study's own, so the
live console is not involved.

Each trial's row is kept as it finishes, through the same store as ``davinci-sim study``
(:class:`~davinci_sim.study.store.StudyRows`: ``trials.partial.jsonl``, one synced line a
row). With a ``root`` (``serve`` gives ``<data folder>/davinci-sim/studies``, beside the
trainee records), each study's folder stays: a study cut short (the server stopped, a
failure) keeps its rows there, and ``davinci-sim study ... --output <folder> --resume`` runs
the rest (the page is told the command). Without one, the folder is temporary.
"""

from __future__ import annotations

import logging
import shlex
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

_log = logging.getLogger("davinci_sim.web")

#: Largest study a page may start (trials = subjects x conditions x repetitions).
MAX_SUBJECTS = 10
MAX_REPETITIONS = 5


class StudyJob:
    """One study at a time, in a thread; ``notify(message)`` gets its progress messages
    (called from the job's thread: the server forwards them to every page). ``root``: the
    folder each study's own folder goes in (kept); None: a temporary folder per study."""

    def __init__(
        self, task: str, notify: Callable[[dict], None], root: str | Path | None = None
    ) -> None:
        self.task = task
        self.notify = notify
        self.root = None if root is None else Path(root)
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
        from davinci_sim.study.console_trial import CONSOLE_KINDS
        from davinci_sim.tasks import TaskError, load_task

        try:  # the study's trainees do path tasks and the needle exercises
            kind = load_task(self.task if not Path(self.task).suffix else Path(self.task)).kind
        except (TaskError, OSError) as e:
            return str(e)
        if kind not in ("path", *CONSOLE_KINDS):
            return (f"the study runs path tasks and {', '.join(CONSOLE_KINDS)}; {self.task!r} "
                    f"is a {kind} exercise")  # fmt: skip
        try:  # (a needle exercise's trainees run on the live engine only)
            config = StudyConfig(n_subjects=subjects, n_repetitions=repetitions,
                                 task=self.task, seed=seed, workers=1,
                                 engine="batch" if kind == "path" else "live")  # fmt: skip
        except (StudyError, ValueError) as e:
            return str(e)
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None
        if self.root is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="davinci-sim-study-")
            self.folder = Path(self._tmp.name)
        else:
            try:
                self.folder = _new_folder(self.root, Path(self.task).stem)
            except OSError as e:
                return f"cannot make the study's folder in {self.root}: {e.strerror or e}"
        self.files = []
        self._thread = threading.Thread(target=self._run, args=(config,), name="web-study",
                                        daemon=True)  # fmt: skip
        self._thread.start()
        return None

    def _run(self, config) -> None:
        from davinci_sim.study import plan_trials, run_study, write_outputs
        from davinci_sim.study.store import StudyRows

        total = len(plan_trials(config))
        self.notify({"op": "study", "state": "running", "done": 0, "total": total})
        store = None
        try:
            folder = self.folder
            assert folder is not None  # (start() made it)
            store = StudyRows.create(folder, config)
            result = run_study(config, on_row=store.append, progress=lambda done, n: self.notify(
                {"op": "study", "state": "running", "done": done, "total": n}))  # fmt: skip
            paths = write_outputs(result, folder)
            store.finish()
        except Exception as e:  # the server goes on; the page says what happened
            _log.exception("the web study failed")
            message = str(e)
            if store is not None:
                store.close()
                if store.rows and self.root is not None:
                    message += (f"; {len(store.rows)} of {total} trials are kept in "
                                f"{self.folder}: {resume_command(config, self.folder)} runs "
                                "the rest")  # fmt: skip
            self.notify({"op": "study", "state": "failed", "message": message})
            return
        self.files = [p.name for p in paths]
        report = (self.folder / "report.md").read_text()
        self.notify({"op": "study", "state": "done", "done": total, "total": total,
                     "files": self.files, "report": report,
                     "folder": None if self.root is None else str(self.folder),
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


def resume_command(config, folder: Path) -> str:
    """The ``davinci-sim study`` command that goes on with ``config``'s study in ``folder``."""
    words = ["davinci-sim", "study", "--task", config.task, "--subjects", str(config.n_subjects),
             "--repetitions", str(config.n_repetitions), "--seed", str(config.seed),
             "--output", str(folder), "--resume"]  # fmt: skip
    return shlex.join(words)


def _new_folder(root: Path, name: str) -> Path:
    """A new folder ``<root>/<name>-<UTC time>`` (a suffix when two start in one second)."""
    root.mkdir(parents=True, exist_ok=True)
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
    for k in range(100):
        folder = root / (f"{name}-{stamp}" + (f"-{k}" if k else ""))
        try:
            folder.mkdir()
            return folder
        except FileExistsError:
            continue
    raise FileExistsError(f"no free folder name for {name} in {root}")
