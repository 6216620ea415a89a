"""Running the trials of a study: batched engines on a local process pool or on Ray.

The plan's trials are dealt round-robin into one chunk per worker (so every chunk holds a
mix of subjects, conditions and practice levels, and the chunks take about as long), and
each chunk runs as one :class:`~davinci_sim.study.batch.TrialBatch` (engine ``batch``) or
trial by trial on the live simulator (engine ``live``,
:func:`~davinci_sim.study.trial.run_trial`, the slow reference). Every backend and worker
count gives the same rows, in the plan's order: a trial's result depends only on its
:class:`~davinci_sim.study.trial.TrialSpec`.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import Manager
from typing import NamedTuple

from tqdm import tqdm

from davinci_sim.study.config import StudyConfig, plan_trials
from davinci_sim.study.trial import TrialSpec, run_trial


class StudyResult(NamedTuple):
    config: StudyConfig
    rows: list[dict]
    """One row per trial, in the plan's order (subject, condition block, repetition)."""
    wall_time: float
    """Wall time of running the trials, s."""


def run_chunk(specs: list[TrialSpec], engine: str, progress=None) -> list[dict]:
    """Run ``specs`` with ``engine``; ``progress`` (a queue or None) gets the number of
    trials that end, as they end."""
    report = (lambda k: None) if progress is None else progress.put
    if engine == "live":
        rows = []
        for spec in specs:
            rows.append(run_trial(spec))
            report(1)
        return rows
    from davinci_sim.study.batch import run_batch

    return run_batch(specs, on_done=report)


def chunks(n: int, workers: int) -> list[list[int]]:
    """Indices ``0..n-1`` dealt round-robin into at most ``workers`` non-empty chunks."""
    return [list(range(i, n, workers)) for i in range(min(workers, n))]


def _gather(specs, parts, results, bar) -> list[dict]:
    rows: list[dict | None] = [None] * len(specs)
    for part, part_rows in zip(parts, results, strict=True):
        for i, row in zip(part, part_rows, strict=True):
            rows[i] = row
    bar.n = len(specs)
    bar.refresh()
    return rows  # type: ignore[return-value]


def _drain(progress, bar, stop: threading.Event) -> None:
    while not stop.is_set():
        try:
            bar.update(progress.get(timeout=0.2))
        except queue.Empty:
            continue
        except (EOFError, OSError):
            return


def _local(specs: list[TrialSpec], workers: int, engine: str, bar) -> list[dict]:
    parts = chunks(len(specs), workers)
    if len(parts) == 1:
        q: queue.SimpleQueue = queue.SimpleQueue()
        stop = threading.Event()
        drain = threading.Thread(target=_drain, args=(q, bar, stop), daemon=True)
        drain.start()
        try:
            results = [run_chunk(specs, engine, q)]
        finally:  # (the drain stops before the total is set: no update after it)
            stop.set()
            drain.join()
        return _gather(specs, parts, results, bar)
    with Manager() as manager, ProcessPoolExecutor(max_workers=len(parts)) as pool:
        progress = manager.Queue()
        stop = threading.Event()
        drain = threading.Thread(target=_drain, args=(progress, bar, stop), daemon=True)
        drain.start()
        try:
            futures = [
                pool.submit(run_chunk, [specs[i] for i in part], engine, progress) for part in parts
            ]
            results = [f.result() for f in futures]
        finally:
            stop.set()
            drain.join()
    return _gather(specs, parts, results, bar)


def _ray(specs: list[TrialSpec], workers: int, engine: str, bar) -> list[dict]:
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
        refs = [remote.remote([specs[i] for i in part], engine) for part in parts]
        results: list = [None] * len(refs)
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                k = refs.index(ref)
                results[k] = ray.get(ref)
                bar.update(len(parts[k]))
        return _gather(specs, parts, results, bar)
    finally:
        if started:
            ray.shutdown()


BACKENDS: dict[str, Callable[[list[TrialSpec], int, str, tqdm], list[dict]]] = {
    "local": _local,
    "ray": _ray,
}


class _Progress:
    """A progress sink for a caller's callback ``report(done, total)`` (a web page's bar),
    with what the backends use of a tqdm bar (``update``, ``n``, ``refresh``)."""

    def __init__(self, report: Callable[[int, int], None], total: int) -> None:
        self.report, self.total, self.n = report, total, 0

    def update(self, k: int) -> None:
        self.n += k
        self.refresh()

    def refresh(self) -> None:
        self.report(self.n, self.total)


def run_study(
    config: StudyConfig, *, progress: bool | Callable[[int, int], None] = True
) -> StudyResult:
    """Run every trial of ``config`` (see :func:`~davinci_sim.study.config.plan_trials`).

    ``progress``: a progress bar on the terminal (True), none (False), or a callback called
    with (trials done, trials in all) as trials finish."""
    specs = plan_trials(config)
    t0 = time.perf_counter()
    if callable(progress):
        rows = BACKENDS[config.backend](specs, config.workers, config.engine,
                                        _Progress(progress, len(specs)))  # fmt: skip
        return StudyResult(config, rows, time.perf_counter() - t0)
    with tqdm(total=len(specs), desc="trials", unit="trial", disable=not progress) as bar:
        rows = BACKENDS[config.backend](specs, config.workers, config.engine, bar)
    return StudyResult(config, rows, time.perf_counter() - t0)
