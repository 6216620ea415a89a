"""The trainee records (:mod:`davinci_sim.records`): recording one attempt (one committed
transaction, WAL, ``synchronous=FULL``: an fsync per attempt) with the seed task's nine
metrics and a score, reading a trainee's attempts back, and drawing a learning curve.

``python benchmarks/bench_records.py`` writes ``results/records.json``. The file is in a
temporary folder (its file system's fsync decides the write time).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import davinci_sim  # noqa: E402, F401  (sets MUJOCO_GL)
from common import summary, time_each, write  # noqa: E402
from davinci_sim.records import RecordsDB, Score  # noqa: E402
from davinci_sim.records.recorder import metric_info  # noqa: E402
from davinci_sim.records.report import curves_png  # noqa: E402
from davinci_sim.tasks import load_task  # noqa: E402


def main(n: int = 500) -> None:
    task = load_task("seed_path")
    info = metric_info(task)
    metrics = {m.name: 0.001 * (i + 1) for i, m in enumerate(task.METRICS)}
    with tempfile.TemporaryDirectory() as folder, RecordsDB(Path(folder) / "r.sqlite3") as db:
        session = db.start_session("bench")
        count = iter(range(10**9))

        def record() -> None:
            db.record_attempt(session, task=task.name, kind=task.kind, condition="B=40",
                              settings={"type": "viscous", "B": 40.0, "G_max": 5.0},
                              repetition=next(count), metrics=metrics, info=info,
                              score=Score(80.0, True, 70.0))  # fmt: skip

        figures = {"metrics_per_attempt": len(metrics)}
        figures.update(summary(time_each(record, n, warmup=20), "record_attempt"))
        attempts = len(db.attempts("bench"))
        figures["attempts_read"] = attempts
        figures.update(summary(time_each(lambda: db.attempts("bench"), 20, warmup=2),
                               "read_attempts"))  # fmt: skip
        t0 = time.perf_counter()
        png = curves_png(db, "bench", task=task.name)
        figures["curve_png_s"] = time.perf_counter() - t0
        figures["curve_png_bytes"] = len(png)
    write("records", figures)


if __name__ == "__main__":
    main()
