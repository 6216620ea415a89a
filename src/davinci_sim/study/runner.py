"""Running the trials of a study: batched engines on a local process pool or on Ray.

The plan's trials are dealt round-robin into one chunk per worker (so every chunk holds a
mix of subjects, conditions and practice levels, and the chunks take about as long), and
each chunk runs as one :class:`~davinci_sim.study.batch.TrialBatch` (engine ``batch``) or
trial by trial on the live simulator (engine ``live``,
:func:`~davinci_sim.study.trial.run_trial`, the slow reference). Every backend and worker
count gives the same rows, in the plan's order: a trial's result depends only on its
:class:`~davinci_sim.study.trial.TrialSpec`.

Each trial's row reaches the caller (``run_study``'s ``on_row``) as soon as the trial ends,
in the parent process, so that it can be kept before the study ends
(:mod:`davinci_sim.study.store`); trials whose rows were kept by an interrupted run are not
run again (``done``). Adaptive conditions run in rounds, each trial's B resolved from its
subject's earlier rows (:mod:`davinci_sim.study.adaptive`). The local backend starts a
worker process per chunk only when there is more than one chunk, and never more processes
than trials or usable cores (a batch pays a fixed cost per tick, once per process: more
processes than cores only add to it).
"""

from __future__ import annotations

import multiprocessing
import os
import queue
import signal
import time
import traceback
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import NamedTuple

from tqdm import tqdm

from davinci_sim.study import adaptive
from davinci_sim.study.config import StudyConfig, plan_trials
from davinci_sim.study.trial import TrialSpec, run_trial

#: A sink of finished rows: ``on_row(k, row)``, k the trial's position in the list run.
RowSink = Callable[[int, dict], None]


class StudyResult(NamedTuple):
    config: StudyConfig
    rows: list[dict]
    """One row per trial, in the plan's order (subject, condition block, repetition)."""
    wall_time: float
    """Wall time of running the trials, s (of this run only, when resumed)."""
    resumed: int = 0
    """Trials whose rows an earlier, interrupted run kept (not run again)."""


def run_chunk(
    specs: list[TrialSpec],
    engine: str,
    progress=None,
    on_row: RowSink | None = None,
    record: str | None = None,
) -> list[dict]:
    """Run ``specs`` with ``engine``; ``progress`` (a queue or None) gets the number of
    trials that end, as they end; ``on_row(k, row)`` gets the row of ``specs[k]`` as soon
    as that trial ends; ``record``: a folder the batch engine records each trial to."""
    report = (lambda k: None) if progress is None else progress.put
    if engine == "live":
        rows = []
        for k, spec in enumerate(specs):
            rows.append(run_trial(spec))
            report(1)
            if on_row is not None:
                on_row(k, rows[-1])
        return rows
    from davinci_sim.study.batch import run_batch

    if record is None:
        return run_batch(specs, on_done=report, on_row=on_row)
    from davinci_sim.study.recording import BatchRecorder

    recorder = BatchRecorder(record, specs)

    def recorded(k: int, row: dict) -> None:
        recorder.row(k, row)
        if on_row is not None:
            on_row(k, row)

    try:
        return run_batch(specs, on_done=report, on_row=recorded, on_tick=recorder.tick)
    finally:
        recorder.close()


def chunks(n: int, workers: int) -> list[list[int]]:
    """Indices ``0..n-1`` dealt round-robin into at most ``workers`` non-empty chunks."""
    return [list(range(i, n, workers)) for i in range(min(workers, n))]


def usable_cores() -> int:
    """CPU cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def processes(n_trials: int, workers: int) -> int:
    """Worker processes the local backend uses for ``n_trials`` trials with ``workers``
    asked for: at most one per trial and per usable core; 1 means no process is started
    (the trials run in the calling process)."""
    return max(1, min(workers, n_trials, usable_cores()))


def _local(specs: list[TrialSpec], workers: int, engine: str, on_row: RowSink,
           record: str | None = None) -> None:  # fmt: skip
    parts = chunks(len(specs), processes(len(specs), workers))
    if len(parts) == 1:
        run_chunk(specs, engine, on_row=on_row, record=record)
        return
    _pool(specs, parts, engine, on_row, record)


def _worker(k: int, specs: list[TrialSpec], part: list[int], engine: str, out,
            record: str | None = None) -> None:  # fmt: skip
    """A worker process: runs one chunk, sending ``("row", i, row)`` as each trial ends
    (i: the position in the list the parent runs), then ``("done", k)`` or
    ``("error", k, text)``. It stops when its parent is gone (checked at each row)."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # (not the parent's handler, if any)
    parent = os.getppid()  # (a fork server's, or the study's: whichever started it)

    def send(j: int, row: dict) -> None:
        if os.getppid() != parent:  # orphaned (the parent was killed): the rows have no reader
            raise SystemExit(1)
        out.put(("row", part[j], row))

    try:
        run_chunk(specs, engine, on_row=send, record=record)
    except KeyboardInterrupt:  # Ctrl-C reaches the whole process group: the parent reports
        return
    except Exception as e:
        out.put(("error", k, f"{type(e).__name__}: {e}\n{traceback.format_exc()}"))
        return
    out.put(("done", k))


def _pool(specs: list[TrialSpec], parts: list[list[int]], engine: str, on_row: RowSink,
          record: str | None = None) -> None:  # fmt: skip
    """One worker process per chunk (forked where possible: they inherit what the parent
    has built, e.g. the compiled laws and the trial set-up); rows reach ``on_row`` in this
    process as trials end. An exception here (Ctrl-C) stops the workers."""
    ctx = multiprocessing.get_context()
    out = ctx.Queue()
    procs = [
        ctx.Process(
            target=_worker,
            args=(k, [specs[i] for i in part], part, engine, out, record),
            name=f"davinci-sim-study-{k}",
            daemon=True,
        )
        for k, part in enumerate(parts)
    ]
    try:
        for p in procs:
            p.start()
        pending = set(range(len(procs)))
        while pending:
            try:
                msg = out.get(timeout=0.5)
            except queue.Empty:
                gone = [k for k in sorted(pending) if procs[k].exitcode is not None]
                if gone:
                    k = gone[0]
                    raise RuntimeError(
                        f"study worker {k} stopped (exit code {procs[k].exitcode}) "
                        "before its trials ended"
                    ) from None
                continue
            if msg[0] == "row":
                on_row(msg[1], msg[2])
            elif msg[0] == "done":
                pending.discard(msg[1])
            else:
                raise RuntimeError(f"study worker {msg[1]} failed: {msg[2]}")
    finally:
        for p in procs:
            if p.is_alive():
                p.terminate()
        for p in procs:
            p.join()
        out.close()
        out.cancel_join_thread()


def _ray(specs: list[TrialSpec], workers: int, engine: str, on_row: RowSink,
         record: str | None = None) -> None:  # fmt: skip
    try:
        import ray
    except ImportError as e:
        raise ImportError("the ray backend needs Ray: pip install 'davinci-sim[ray]'") from e
    started = not ray.is_initialized()
    if started:
        ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
    try:
        parts = chunks(len(specs), workers)
        remote = ray.remote(run_chunk)
        # (record: a folder every Ray worker reaches, e.g. on a shared file system)
        refs = [remote.remote([specs[i] for i in part], engine, record=record) for part in parts]
        pending = list(refs)
        while pending:  # (a chunk's rows arrive when the chunk ends)
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                part = parts[refs.index(ref)]
                for i, row in zip(part, ray.get(ref), strict=True):
                    on_row(i, row)
    finally:
        if started:
            ray.shutdown()


BACKENDS: dict[str, Callable[..., None]] = {
    "local": _local,
    "ray": _ray,
}


class _Progress:
    """A progress sink for a caller's callback ``report(done, total)`` (a web page's bar),
    with what :func:`run_study` uses of a tqdm bar (``update``)."""

    def __init__(self, report: Callable[[int, int], None], total: int, done: int = 0) -> None:
        self.report, self.total, self.n = report, total, done

    def update(self, k: int) -> None:
        self.n += k
        self.report(self.n, self.total)

    def close(self) -> None:
        pass


def run_study(
    config: StudyConfig,
    *,
    progress: bool | Callable[[int, int], None] = True,
    done: Mapping[int, dict] | None = None,
    on_row: Callable[[int, dict], None] | None = None,
    record: str | Path | None = None,
) -> StudyResult:
    """Run every trial of ``config`` (see :func:`~davinci_sim.study.config.plan_trials`).

    ``progress``: a progress bar on the terminal (True), none (False), or a callback called
    with (trials done, trials in all) as trials finish. ``done``: rows already finished,
    by plan index (kept by an interrupted run, :class:`~davinci_sim.study.store.StudyRows`):
    those trials are not run again. ``on_row(index, row)``: called in this process with each
    trial's row (plan index) as soon as the trial ends, e.g. to keep it on disk.
    ``record``: a folder every trial is recorded to, one MCAP file each (the batch engine
    only: :mod:`~davinci_sim.study.recording`)."""
    if record is not None and config.engine != "batch":
        raise ValueError("recording trials needs the batch engine (--engine batch)")
    record = None if record is None else str(record)
    specs = plan_trials(config)
    rows: list[dict | None] = [None] * len(specs)
    for i, row in (done or {}).items():
        if not 0 <= i < len(specs):
            raise ValueError(f"a finished row's plan index {i} is not in 0..{len(specs) - 1}")
        rows[i] = row
    todo = [i for i, row in enumerate(rows) if row is None]
    kept = len(specs) - len(todo)
    t0 = time.perf_counter()
    if callable(progress):
        bar = _Progress(progress, len(specs), kept)
    else:
        bar = tqdm(total=len(specs), initial=kept, desc="trials", unit="trial",
                   disable=not progress)  # fmt: skip

    hist = adaptive.histories(specs)
    try:
        # Rounds (study.adaptive): all that needs no earlier row first, then each round the
        # adaptive trials whose history is in. No adaptive condition: one round, as before.
        while todo:
            now = [i for i in todo if adaptive.ready(specs[i], hist[i], rows)]
            if not now:
                raise RuntimeError(f"{len(todo)} adaptive trials wait for rows that never come")
            run = [adaptive.resolve(specs[i], hist[i], rows) for i in now]

            def got(k: int, row: dict, now=now) -> None:
                i = now[k]
                rows[i] = row
                if on_row is not None:
                    on_row(i, row)
                bar.update(1)

            BACKENDS[config.backend](run, config.workers, config.engine, got, record=record)
            missing = [i for i in now if rows[i] is None]
            if missing:
                raise RuntimeError(f"trials {missing[:5]} ended without a row")
            todo = [i for i in todo if rows[i] is None]
    finally:
        bar.close()
    return StudyResult(config, rows, time.perf_counter() - t0, kept)  # type: ignore[arg-type]
