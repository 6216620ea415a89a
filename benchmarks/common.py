"""Shared helpers of the benchmarks: machine description, timing, JSON results."""

from __future__ import annotations

import json
import os
import platform
import statistics
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def machine() -> dict:
    """What the figures were measured on."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import mujoco
    import numpy

    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
        "numpy": numpy.__version__,
        "mujoco_gl": os.environ.get("MUJOCO_GL", ""),
    }


def time_each(fn, n: int, warmup: int = 50) -> list[float]:
    """Wall time of each of ``n`` calls of ``fn()`` in µs."""
    for _ in range(warmup):
        fn()
    out = []
    clock = time.perf_counter_ns
    for _ in range(n):
        t0 = clock()
        fn()
        out.append((clock() - t0) / 1000.0)
    return out


def summary(samples_us: list[float], prefix: str) -> dict:
    s = sorted(samples_us)
    return {
        f"{prefix}_median_us": statistics.median(s),
        f"{prefix}_p99_us": s[min(len(s) - 1, int(0.99 * len(s)))],
        f"{prefix}_mean_us": statistics.fmean(s),
    }


def write(name: str, figures: dict) -> Path:
    """Write ``results/<name>.json``: the figures (flat, unit in each name) and the machine."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    path = RESULTS / f"{name}.json"
    data = {k: (round(v, 3) if isinstance(v, float) else v) for k, v in figures.items()}
    data["machine"] = machine()
    path.write_text(json.dumps(data, indent=2) + "\n")
    print(f"{name}: " + ", ".join(f"{k}={v}" for k, v in data.items() if k != "machine"))
    return path
