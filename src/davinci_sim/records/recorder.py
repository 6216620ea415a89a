"""Recording every attempt of a training session as it finishes.

:class:`AttemptRecorder` listens to a :class:`~davinci_sim.tasks.session.TaskSession`'s
``results`` events — through a running simulation's handle (:meth:`AttemptRecorder.attach`:
``SimHandle.subscribe``, the same for the thread and the process runner) or a session's
own channels (:meth:`AttemptRecorder.on_channel`) — and writes each finished repetition's
row to the records as one attempt of the current trainee's session
(:meth:`RecordsDB.record_attempt <davinci_sim.records.db.RecordsDB.record_attempt>`, one
committed transaction).

The writes happen in the recorder's own thread, never in the simulation's loop: an event
only queues the row (the thread runner calls subscribers from its loop thread, and a commit
waits for the disk). A write that fails (disk full, a locked or unusable file) does not stop
anything: the recorder reports it with ``on_error(text)`` — ``serve`` puts it on the
session's message channel, as the session does when its CSV log cannot be written — and
tries again with the next attempt; the rows it could not write stay in
:attr:`AttemptRecorder.failed`.

A session row (``TaskSession._record``) is ``task``, ``condition``, ``repetition``, then
the task's declared metrics; any further numeric column is stored as a metric too, and the
score columns :data:`SCORE_KEYS` (when the task's scoring adds them) go to the attempt's
score.

An attempt's end time is the wall-clock time its row reached the recorder; its start is
that minus the row's ``completion_time`` (simulated seconds: the wall-clock start in a
real-time session, an approximation in a faster one), NULL when the row has none.
"""

from __future__ import annotations

import logging
import math
import queue
import threading
from collections.abc import Callable, Mapping
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

from davinci_sim.records.db import MetricInfo, RecordsDB, RecordsError, Score, check_name, now

_log = logging.getLogger("davinci_sim.records")

#: The columns of a session row that are not metrics (``tasks.session.SESSION_COLUMNS``).
ROW_KEYS = ("task", "condition", "repetition")
#: Row columns read as the attempt's score: overall score, passed (bool), pass mark.
SCORE_KEYS = {"score": "score", "passed": "passed", "pass_mark": "pass_mark"}
#: Row columns that say how the attempt ran, not how it went: stored with its settings (an
#: adaptive fixture's B of that repetition, ``tasks.session``), never as a metric.
SETTING_KEYS = ("guidance_B",)


def metric_info(task) -> dict[str, MetricInfo]:
    """Unit and better direction of each metric ``task`` declares (its ``METRICS``)."""
    return {
        m.name: MetricInfo(unit=m.unit, better=getattr(m, "better", None))
        for m in getattr(task, "METRICS", ())
    }


def scoring_marks(task) -> Callable[[Mapping[str, Any]], tuple[dict, float | None]] | None:
    """The pass marks of ``task``'s attempts from its scoring, when the task has one (the
    trainer scores' ``Task.scoring``: ``score(values).marks``, metric → mark in its unit,
    and ``pass_score``, the overall score to reach, %); None without scoring."""
    scoring = getattr(task, "scoring", None)
    if scoring is None or not callable(getattr(scoring, "score", None)):
        return None

    def marks(row: Mapping[str, Any]) -> tuple[dict, float | None]:
        values = {k: v for k, v in row.items() if isinstance(v, int | float)}
        return dict(getattr(scoring.score(values), "marks", {}) or {}), getattr(
            scoring, "pass_score", None
        )

    return marks


def split_row(row: Mapping[str, Any]) -> tuple[dict, Score | None]:
    """A session row's metrics (every column but :data:`ROW_KEYS`, :data:`SCORE_KEYS` and
    :data:`SETTING_KEYS`) and its score (None when the row has none of the score columns)."""
    skip = (*ROW_KEYS, *SCORE_KEYS, *SETTING_KEYS)
    metrics = {k: v for k, v in row.items() if k not in skip}
    found = {field: row[key] for key, field in SCORE_KEYS.items() if key in row}
    if not found:
        return metrics, None
    passed = found.get("passed")
    return metrics, Score(
        score=found.get("score"),
        passed=None if passed is None else bool(passed),
        pass_mark=found.get("pass_mark"),
    )


class AttemptRecorder:
    """Writes each finished repetition of a task session to the records; see the module
    docstring.

    Args:
        path: the records file (None: :func:`~davinci_sim.records.db.default_path`).
        trainee: whose attempts these are.
        task: the session's task (its declared metrics give the units and directions, its
            ``kind`` the attempt's kind); None: units unknown.
        settings: the condition's fixture entry (JSON-able dict) stored with the attempts
            whose condition label is ``condition``; other labels (the condition changed
            at the console) are stored with ``{"label": label}`` unless the task names them.
        condition: the label of ``settings`` (the session's ``condition``).
        source: what ran the session (``serve``, ``web`` …), stored with the session.
        on_error: told each failure, as one line of text (default: logged).
        component: the session's component name (the events' source).
        pass_marks: ``row -> (marks, pass_score)``: each metric's pass mark in the attempt
            (name → value in its unit) and the overall score it had to reach (None: none),
            stored with the attempt; default: the task's scoring's (:func:`scoring_marks`),
            none without it.
    """

    def __init__(
        self,
        path: str | Path | None,
        trainee: str,
        *,
        task=None,
        settings: Mapping | None = None,
        condition: str | None = None,
        source: str = "",
        on_error: Callable[[str], None] | None = None,
        component: str = "task",
        pass_marks: Callable[[Mapping[str, Any]], tuple[dict, float | None]] | None = None,
    ) -> None:
        self.path = path
        self.pass_marks = pass_marks if pass_marks is not None else scoring_marks(task)
        self.trainee = check_name(trainee)
        self.task = task
        self.info = metric_info(task) if task is not None else {}
        self.settings = dict(settings or {})
        self.condition = condition
        self.source = source
        self.on_error = on_error
        self.component = component
        self.recorded: list[int] = []
        """Ids of the attempts written so far."""
        self._pending: list[tuple[dict, datetime]] = []
        """Rows of the current session not written yet (retried, oldest first)."""
        self._abandoned: list[dict] = []
        self._queue: queue.Queue = queue.Queue()
        self._thread: threading.Thread | None = None
        self._unsubscribe: Callable[[], None] | None = None
        self._db: RecordsDB | None = None
        self._session: int | None = None

    @property
    def failed(self) -> list[dict]:
        """Rows not written: those still retried and those given up on (the trainee changed
        or the recorder stopped while the file could not be written)."""
        return [*self._abandoned, *(row for row, _ in self._pending)]

    # ------------------------------------------------------------ wiring
    def attach(self, handle) -> AttemptRecorder:
        """Record the ``results`` events of ``handle``'s session; starts the recorder."""
        if self.condition is None:  # the label the session gives its condition
            try:
                state = (handle.snapshot().extras or {}).get(self.component)
            except Exception:  # (a loop process that has not published yet)
                state = None
            label = getattr(state, "condition", None)
            self.condition = label if isinstance(label, str) else None
        self._unsubscribe = handle.subscribe(self.on_event)
        return self.start()

    def on_event(self, source: str, event: str, payload: object) -> None:
        """A handle's event (``callback(source, event, payload)``): queues a session's row."""
        if source == self.component and event == "results" and isinstance(payload, Mapping):
            self.submit(payload)

    def on_channel(self, event: str, payload: object) -> None:
        """A session's own channel event (``Channels.subscribe``): queues its row."""
        self.on_event(self.component, event, payload)

    def submit(self, row: Mapping[str, Any]) -> None:
        """Queue one finished repetition's row, with the wall-clock time it ended."""
        self._queue.put(("row", dict(row), datetime.now(UTC)))

    def set_trainee(self, name: str) -> None:
        """From now on, the attempts are ``name``'s (a new session of theirs).

        Raises:
            RecordsError: a bad name (nothing changes).
        """
        name = check_name(name)
        self._queue.put(("trainee", name, None))

    # ------------------------------------------------------------ lifecycle
    def start(self) -> AttemptRecorder:
        """Start the writer thread; it opens the file and starts the trainee's session at
        once (its start time: now), saying so with ``on_error`` if it cannot."""
        if self._thread is None:
            self._queue.put(("open", None, None))
            self._thread = threading.Thread(target=self._run, name="records", daemon=True)
            self._thread.start()
        return self

    def flush(self, timeout: float | None = None) -> bool:
        """Wait until every queued row is written (or failed); False on timeout."""
        done = threading.Event()
        self._queue.put(("flush", done, None))
        return done.wait(timeout)

    def stop(self, timeout: float | None = 10.0) -> None:
        """Write what is queued, end the session, close the file."""
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None
        if self._thread is not None:
            self._queue.put(("stop", None, None))
            self._thread.join(timeout)
            self._thread = None

    # ------------------------------------------------------------ the writer thread
    def _run(self) -> None:
        while True:
            what, value, when = self._queue.get()
            if what == "row":
                self._pending.append((value, when))
                self._write_pending()
            elif what == "open":
                self._try_open()
            elif what == "trainee":
                self._give_up_pending()
                self._end_session()
                self.trainee = value
                self._try_open()
            elif what == "flush":
                value.set()
            elif what == "stop":
                self._give_up_pending()
                self._end_session()
                if self._db is not None:
                    self._db.close()
                    self._db = None
                return

    def _open(self) -> RecordsDB:
        if self._db is None:
            self._db = RecordsDB(self.path)
        if self._session is None:
            self._session = self._db.start_session(self.trainee, source=self.source)
        return self._db

    def _try_open(self) -> None:
        try:
            self._open()
        except Exception as e:  # said now; tried again with the next attempt
            where = self._db.path if self._db is not None else self.path or "the records"
            self._report(f"cannot start {self.trainee!r}'s session in {where}: {_reason(e)}")
            self._reset_connection()

    def _end_session(self) -> None:
        if self._db is not None and self._session is not None:
            try:
                self._db.end_session(self._session)
            except Exception as e:  # (the attempts are in; only the end time is lost)
                self._report(f"cannot end the records session in {self._db.path}: {e}")
        self._session = None

    def _write_pending(self) -> None:
        """Write the pending rows, oldest first; stop at the first that fails (said for
        the newest row only: the older ones were said when they came)."""
        while self._pending:
            row, ended = self._pending[0]
            try:
                self._write(row, ended)
            except Exception as e:  # disk full, locked, unusable: the simulation goes on
                newest = self._pending[-1][0]
                where = self._db.path if self._db is not None else self.path or "the records"
                waiting = len(self._pending)
                self._report(f"cannot record repetition {newest.get('repetition')} of "
                             f"{self.trainee!r} in {where}: {_reason(e)} ({waiting} "
                             "attempt(s) kept, tried again with the next)")  # fmt: skip
                # The connection and the session stay: a lock or a full disk passes, and
                # the next attempt goes into the same session (a file that could not be
                # opened or a session that could not start are tried again by _open).
                return
            self._pending.pop(0)

    def _give_up_pending(self) -> None:
        """Before the session ends: one more try, then the rows left are given up on (they
        are not written in another trainee's session)."""
        if not self._pending:
            return
        self._write_pending()
        if self._pending:
            self._abandoned.extend(row for row, _ in self._pending)
            self._report(f"{len(self._pending)} attempt(s) of {self.trainee!r} could not be "
                         "recorded and are given up")  # fmt: skip
            self._pending.clear()

    def _write(self, row: dict, ended: datetime) -> None:
        """Write one row as an attempt of the session (raises what the file raises)."""
        db = self._open()
        metrics, score = split_row(row)
        marks, pass_score = self.pass_marks(row) if self.pass_marks is not None else ({}, None)
        if score is not None and pass_score is not None:
            score = Score(score.score, score.passed, pass_score)
        self.recorded.append(
            db.record_attempt(
                self._session,
                task=str(row.get("task", getattr(self.task, "name", ""))),
                kind=getattr(self.task, "kind", None),
                condition=str(row.get("condition", "")),
                settings={
                    **self._settings_of(str(row.get("condition", ""))),
                    **{k: row[k] for k in SETTING_KEYS if row.get(k) is not None},
                },
                repetition=row.get("repetition"),
                started_at=_started(ended, metrics.get("completion_time")),
                ended_at=ended.isoformat(timespec="milliseconds"),
                metrics=metrics,
                info=self.info,
                score=score,
                pass_marks=marks,
            )
        )

    def _reset_connection(self) -> None:
        """Drop the connection after a failed start: the next attempt reopens the file
        and starts the session."""
        if self._db is not None:
            try:
                self._db.close()
            except Exception:
                pass
        self._db = None
        self._session = None

    def _settings_of(self, label: str) -> dict:
        if self.condition is None or label == self.condition:
            return self.settings
        try:  # a condition the task names
            spec = self.task.condition(label) if self.task is not None else None
        except Exception:
            spec = None
        return dict(spec) if isinstance(spec, Mapping) else {"label": label}

    def _report(self, text: str) -> None:
        _log.warning("%s", text)
        if self.on_error is not None:
            try:
                self.on_error(text)
            except Exception:
                _log.exception("records: reporting an error failed")


def _started(ended: datetime, completion_time) -> str | None:
    """The attempt's start: its end minus the completion time (s), when the row has one."""
    try:
        seconds = float(completion_time)
    except (TypeError, ValueError):
        return None
    if not math.isfinite(seconds) or seconds < 0:
        return None
    return (ended - timedelta(seconds=seconds)).isoformat(timespec="milliseconds")


def _reason(e: Exception) -> str:
    return str(e) if isinstance(e, RecordsError) else f"{type(e).__name__}: {e}"


__all__ = ["AttemptRecorder", "metric_info", "now", "split_row"]
