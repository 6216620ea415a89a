"""What ``davinci-sim trainees`` shows: the trainees, one trainee's history, the attempts as
CSV, and learning curves as figures.

* :func:`list_text` — one line per trainee (sessions, attempts, last attempt);
* :func:`show_text` — a trainee's sessions, then per task the attempts, the latest
  attempt's metrics (with units) and the best value of each metric with a direction;
* :func:`export_csv` — one row per attempt, the metrics as columns (the union of the
  attempts' metric names, in the order first recorded);
* :func:`draw_curves` — a trainee's learning curves: per task (rows) and metric (columns),
  the metric (y, in its unit) against the attempt number (x, in the order recorded), the
  sessions' boundaries dotted; with a pass mark, the pass band (the side of the mark that
  passes, by the metric's better direction) shaded and the attempts that pass filled. The
  pass mark of a metric is the ``pass_marks`` argument's (``--pass-mark METRIC=VALUE``),
  else the one the trainee's latest attempt with a mark was judged against (recorded with
  the attempt from the task's scoring), and for the overall ``score`` the score the latest
  scored attempt had to reach.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

from davinci_sim.records.db import RecordsDB, RecordsError

#: The columns of an exported attempt before its metrics.
EXPORT_COLUMNS = ("trainee", "session", "attempt", "task", "kind", "condition", "settings",
                  "repetition", "started_at", "ended_at", "finished", "software_version",
                  "host", "score", "passed", "pass_mark")  # fmt: skip


def _value(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def list_text(db: RecordsDB) -> str:
    """The trainees, one line each (or a line saying there are none)."""
    rows = db.trainees()
    if not rows:
        return f"no trainees in {db.path}"
    width = max(len(r["name"]) for r in rows)
    lines = [f"{'trainee':{width}s}  sessions  attempts  last attempt"]
    for r in rows:
        lines.append(f"{r['name']:{width}s}  {r['sessions']:8d}  {r['attempts']:8d}  "
                     f"{r['last'] or '-'}")  # fmt: skip
    return "\n".join(lines)


def show_text(db: RecordsDB, trainee: str) -> str:
    """``trainee``'s sessions, attempts per task, latest metrics and best values.

    Raises:
        RecordsError: an unknown trainee.
    """
    sessions = db.sessions(trainee)
    attempts = db.attempts(trainee)
    lines = [f"trainee {trainee!r}: {len(sessions)} session(s), {len(attempts)} attempt(s)"]
    lines.append("sessions:")
    for s in sessions:
        lines.append(f"  #{s['id']} {s['started_at']} .. {s['ended_at'] or '(not ended)'}  "
                     f"{s['attempts']} attempt(s)  davinci-sim {s['software_version']} on "
                     f"{s['host']}{' (' + s['source'] + ')' if s['source'] else ''}")  # fmt: skip
    by_task: dict[str, list[dict]] = {}
    for a in attempts:
        by_task.setdefault(a["task"], []).append(a)
    for task, rows in by_task.items():
        last = rows[-1]
        passed = sum(1 for r in rows if r["passed"])
        scored = sum(1 for r in rows if r["passed"] is not None)
        lines.append(f"task {task!r} ({last['kind'] or 'kind unknown'}): {len(rows)} attempt(s)"
                     + (f", {passed} of {scored} scored passed" if scored else ""))  # fmt: skip
        lines.append(f"  latest: attempt {len(rows)}, repetition {last['repetition']}, "
                     f"condition {last['condition'] or '-'}, {last['ended_at']}"
                     + (f", score {_value(last['score'])}" if last["score"] is not None else "")
                     + ("" if last["passed"] is None
                        else (" (pass)" if last["passed"] else " (fail)")))  # fmt: skip
        for name, (value, unit, better) in last["metrics"].items():
            best = _best(rows, name, better)
            best_text = "" if best is None else f"   best {_value(best)}"
            lines.append(f"    {name:20s} {_value(value):>10s} {unit or '':5s}{best_text}")
    return "\n".join(lines)


def _best(rows: Sequence[dict], name: str, better: str | None) -> float | None:
    values = [r["metrics"][name][0] for r in rows if r["metrics"].get(name, (None,))[0] is not None]
    if not values or better not in ("lower", "higher"):
        return None
    return min(values) if better == "lower" else max(values)


def export_csv(db: RecordsDB, out: io.TextIOBase, trainee: str | None = None) -> int:
    """Write every attempt (of ``trainee`` if given) to ``out`` as CSV, one row per attempt
    with the metrics as columns (SI values as recorded; empty: not measured); returns the
    number of rows.

    Raises:
        RecordsError: an unknown trainee.
    """
    attempts = db.attempts(trainee)
    names: dict[str, None] = {}
    for a in attempts:
        names.update(dict.fromkeys(a["metrics"]))
    writer = csv.writer(out)
    writer.writerow([*EXPORT_COLUMNS, *names])
    for a in attempts:
        base = dict(a, attempt=a["id"])
        cells = ["" if base.get(c) is None else base[c] for c in EXPORT_COLUMNS]
        metrics = a["metrics"]
        cells += ["" if metrics.get(n, (None,))[0] is None else metrics[n][0] for n in names]
        writer.writerow(cells)
    return len(attempts)


def curve_metrics(attempts: Sequence[dict]) -> list[str]:
    """The metrics a learning curve shows by default: the overall ``score`` when attempts
    are scored, then each metric with a better direction (in the order recorded)."""
    names: dict[str, None] = {}
    if any(a["score"] is not None for a in attempts):
        names["score"] = None
    for a in attempts:
        for name, (_, _, better) in a["metrics"].items():
            if better in ("lower", "higher"):
                names[name] = None
    return list(names)


def draw_curves(
    db: RecordsDB,
    trainee: str,
    path: str | Path,
    *,
    task: str | None = None,
    metrics: Sequence[str] | None = None,
    pass_marks: Mapping[str, float] | None = None,
) -> Path:
    """Draw ``trainee``'s learning curves (see the module docstring) to the PNG ``path``
    (the arguments as :func:`curves_png`'s).

    Raises:
        RecordsError: as :func:`curves_png`, or a file that cannot be written (nothing is
            written then).
    """
    png = curves_png(db, trainee, task=task, metrics=metrics, pass_marks=pass_marks)
    out = Path(path)
    try:
        out.write_bytes(png)
    except OSError as e:
        raise RecordsError(f"cannot write {out}: {e.strerror or e}") from e
    return out


def curves_png(
    db: RecordsDB,
    trainee: str,
    *,
    task: str | None = None,
    metrics: Sequence[str] | None = None,
    pass_marks: Mapping[str, float] | None = None,
    columns: int | None = None,
) -> bytes:
    """``trainee``'s learning curves (see the module docstring) as PNG bytes. Drawn on a
    figure of its own (no pyplot state), so any thread may draw.

    Args:
        task: one task (None: every task of the trainee, one row each).
        metrics: the metrics to draw (None: :func:`curve_metrics`); ``score`` is the
            overall score.
        pass_marks: metric name → pass mark (in the metric's unit); passing is at or below
            it for a lower-is-better metric, at or above for a higher-is-better one and for
            the score.
        columns: panels per row (None: one row per task, one column per metric).

    Raises:
        RecordsError: an unknown trainee or task, no attempts, an unknown metric.
    """
    from matplotlib.figure import Figure

    attempts = db.attempts(trainee, task=task)
    if not attempts:
        what = f" of task {task!r}" if task is not None else ""
        raise RecordsError(f"trainee {trainee!r} has no attempts{what}")
    tasks: dict[str, list[dict]] = {}
    for a in attempts:
        tasks.setdefault(a["task"], []).append(a)
    names = list(metrics) if metrics else curve_metrics(attempts)
    known = {"score", *(n for a in attempts for n in a["metrics"])}
    unknown = [n for n in names if n not in known]
    if unknown:
        raise RecordsError(f"no metric {unknown[0]!r} in {trainee!r}'s attempts; "
                           f"metrics: {sorted(known - {'score'})}")  # fmt: skip
    if not names:
        raise RecordsError("no metric to draw (none has a better direction); name one")
    marks = dict(pass_marks or {})
    panels = [(task_name, rows, name) for task_name, rows in tasks.items() for name in names]
    ncols = len(names) if columns is None else max(1, min(int(columns), len(panels)))
    nrows = -(-len(panels) // ncols)
    fig = Figure(figsize=(4.0 * ncols, 3.2 * nrows))
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax, (task_name, rows, name) in zip(axes, panels, strict=False):
        _draw_one(ax, rows, name, marks.get(name))
        ax.set_title(f"{task_name}: {name.replace('_', ' ')}", fontsize=9)
    for ax in axes[len(panels) :]:
        ax.set_visible(False)
    fig.suptitle(f"learning curves of {trainee}")
    fig.tight_layout()
    out = io.BytesIO()
    fig.savefig(out, dpi=100, format="png")
    return out.getvalue()


def note_png(text: str) -> bytes:
    """A one-line note as a small PNG (where a learning curve would be)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.0, 0.5))
    fig.text(0.5, 0.5, text, ha="center", va="center", fontsize=10, color="0.35")
    out = io.BytesIO()
    fig.savefig(out, dpi=100, format="png")
    return out.getvalue()


def _series(rows: Sequence[dict], name: str) -> tuple[list[float], str | None, str | None]:
    """(values, unit, better) of metric ``name`` over ``rows`` (nan: not measured)."""
    if name == "score":
        values = [math.nan if r["score"] is None else r["score"] for r in rows]
        return values, None, "higher"
    unit = better = None
    values = []
    for r in rows:
        value, u, b = r["metrics"].get(name, (None, None, None))
        unit, better = unit or u, better or b
        values.append(math.nan if value is None else value)
    return values, unit, better


def _draw_one(ax, rows: Sequence[dict], name: str, mark: float | None) -> None:
    values, unit, better = _series(rows, name)
    if mark is None:  # the mark the latest attempt that had one was judged against
        if name == "score":
            recorded = [r["pass_mark"] for r in rows if r["pass_mark"] is not None]
        else:
            recorded = [r["pass_marks"][name] for r in rows if name in r["pass_marks"]]
        mark = recorded[-1] if recorded else None
    x = list(range(1, len(rows) + 1))
    ax.plot(x, values, "-", color="tab:blue", lw=1.2)
    if mark is not None and better in ("lower", "higher"):
        finite = [v for v in values if math.isfinite(v)] + [mark]
        span = (max(finite) - min(finite)) or abs(mark) or 1.0
        lo, hi = min(finite) - 0.1 * span, max(finite) + 0.1 * span
        band = (lo, mark) if better == "lower" else (mark, hi)
        ax.axhspan(*band, color="tab:green", alpha=0.15, lw=0, label="pass band")
        ax.axhline(mark, color="tab:green", lw=1.0, ls="--", label=f"pass mark {mark:.4g}")
        ax.set_ylim(lo, hi)
        passes = [(v <= mark) if better == "lower" else (v >= mark) for v in values]
        ax.plot([xi for xi, p in zip(x, passes, strict=True) if p],
                [v for v, p in zip(values, passes, strict=True) if p], "o", color="tab:green",
                ms=5, label="passed")  # fmt: skip
        ax.plot([xi for xi, p in zip(x, passes, strict=True) if not p],
                [v for v, p in zip(values, passes, strict=True) if not p], "o", mfc="white",
                color="tab:red", ms=5, label="not passed")  # fmt: skip
        ax.legend(fontsize=7)
    else:
        ax.plot(x, values, "o", color="tab:blue", ms=4)
    for i in range(1, len(rows)):  # the sessions' boundaries
        if rows[i]["session"] != rows[i - 1]["session"]:
            ax.axvline(i + 0.5, color="0.6", lw=0.8, ls=":")
    from matplotlib.ticker import MaxNLocator

    ax.set_xlim(0.5, len(rows) + 0.5)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("attempt")
    arrow = {"lower": " (lower is better)", "higher": " (higher is better)"}.get(better, "")
    ax.set_ylabel(f"{name.replace('_', ' ')}" + (f" [{unit}]" if unit else "") + arrow, fontsize=8)
    ax.grid(alpha=0.3)
