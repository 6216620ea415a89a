"""Running the trials of a study: a local process pool or Ray, with a progress bar.

Both backends call the same :func:`~davinci_sim.study.trial.run_trial` on the same
:class:`~davinci_sim.study.trial.TrialSpec` list and return the rows in the plan's order, so
the results do not depend on the backend, the worker count or the order of completion.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
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


def _local(specs: list[TrialSpec], workers: int, progress: bool) -> list[dict]:
    bar = tqdm(total=len(specs), desc="trials", unit="trial", disable=not progress)
    rows: list[dict | None] = [None] * len(specs)
    try:
        if workers == 1:
            for i, spec in enumerate(specs):
                rows[i] = run_trial(spec)
                bar.update()
        else:
            with ProcessPoolExecutor(max_workers=workers) as pool:
                futures = {pool.submit(run_trial, spec): i for i, spec in enumerate(specs)}
                for future in as_completed(futures):
                    rows[futures[future]] = future.result()
                    bar.update()
    finally:
        bar.close()
    return rows  # type: ignore[return-value]


def _ray(specs: list[TrialSpec], workers: int, progress: bool) -> list[dict]:
    try:
        import ray
    except ImportError as e:
        raise ImportError("the ray backend needs Ray: pip install 'davinci-sim[ray]'") from e
    started = not ray.is_initialized()
    if started:
        ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
    try:
        remote = ray.remote(run_trial)
        refs = [remote.remote(spec) for spec in specs]
        index = {ref: i for i, ref in enumerate(refs)}
        rows: list[dict | None] = [None] * len(specs)
        pending = list(refs)
        with tqdm(total=len(specs), desc="trials", unit="trial", disable=not progress) as bar:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    rows[index[ref]] = ray.get(ref)
                    bar.update()
        return rows  # type: ignore[return-value]
    finally:
        if started:
            ray.shutdown()


BACKENDS: dict[str, Callable[[list[TrialSpec], int, bool], list[dict]]] = {
    "local": _local,
    "ray": _ray,
}


def run_study(config: StudyConfig, *, progress: bool = True) -> StudyResult:
    """Run every trial of ``config`` (see :func:`~davinci_sim.study.config.plan_trials`)."""
    specs = plan_trials(config)
    t0 = time.perf_counter()
    rows = BACKENDS[config.backend](specs, config.workers, progress)
    return StudyResult(config, rows, time.perf_counter() - t0)
