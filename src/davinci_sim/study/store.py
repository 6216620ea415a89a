"""Keeping a study's results on disk: each trial's row as the trial ends, and the final files
written whole.

**Rows as they end.** :class:`StudyRows` keeps the rows of one study in the output folder,
in ``trials.partial.jsonl`` (JSON lines): the first line is the study's configuration (what
decides the rows: every :class:`~davinci_sim.study.config.StudyConfig` field but how the
trials are run — workers, backend — and the task file's SHA-256 when the task is a file),
then one line per finished trial, ``{"index": i, "key": [seed, subject, condition,
repetition], "row": {...}}`` (i: the trial's position in
:func:`~davinci_sim.study.config.plan_trials`; key: its
:attr:`~davinci_sim.study.trial.TrialSpec.key`). Each line goes to the file in one
``write`` of the whole line, then ``fsync``: a study stopped at any moment (Ctrl-C, kill,
power cut) keeps every row it has written, and at worst the last line is cut short — a line
without its newline, which :meth:`StudyRows.resume` drops (with a note) and cuts off the
file. JSON keeps Python's floats exactly (``repr``), NaN included, so a resumed study's
rows are the rows the trials gave. When the final outputs are written the file is removed:
a folder holding one holds an unfinished study.

**Final files.** :func:`atomic_path` gives a temporary file in the target's folder, which
replaces the target (``os.replace``) only once it is completely written: a reader (or a
crash) sees the old file or the new one, never a part.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from davinci_sim.study.config import StudyConfig, StudyError, plan_trials

#: The file of a study's finished rows, in its output folder (while it is unfinished).
PARTIAL = "trials.partial.jsonl"
FORMAT = 1
"""Version of the rows file's format (its first line says which)."""
#: Configuration fields that change how the trials run, not their rows (see
#: :mod:`davinci_sim.study.runner`): a study may be resumed with other values.
RUN_ONLY = ("workers", "backend")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _fsync_dir(folder: Path) -> None:
    """Make a rename or a new file in ``folder`` durable (where the OS allows it)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:  # (some file systems and OSes cannot sync a folder)
        pass
    finally:
        os.close(fd)


@contextmanager
def atomic_path(path) -> Iterator[Path]:
    """A temporary path in ``path``'s folder (same suffix, so that writers that go by it
    still do) to write ``path``'s new content into; when the block ends normally it is
    synced and replaces ``path``; on an exception it is removed and ``path`` is unchanged."""
    path = Path(path)
    fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix)
    os.close(fd)
    tmp = Path(name)
    try:
        os.chmod(tmp, 0o666 & ~_umask())  # (mkstemp makes it private; the outputs are not)
        yield tmp
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    _fsync_dir(path.parent)


def write_text_atomic(path, text: str) -> None:
    """Write ``text`` to ``path`` whole or not at all (:func:`atomic_path`)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def config_record(config: StudyConfig) -> dict:
    """What decides a study's rows, as JSON values: the configuration's fields but
    :data:`RUN_ONLY`, and ``task_sha256`` (the task file's digest, None for a named task)."""
    record = {k: v for k, v in dataclasses.asdict(config).items() if k not in RUN_ONLY}
    if record.get("population") == "trainee":  # (the default: as studies stored it before)
        del record["population"]
    task = Path(config.task)
    digest = hashlib.sha256(task.read_bytes()).hexdigest() if task.is_file() else None
    record["task_sha256"] = digest
    return json.loads(json.dumps(record, default=repr))  # (tuples as lists, as stored)


def differences(stored: dict, wanted: dict) -> list[str]:
    """The fields in which two :func:`config_record` differ, e.g. ``"seed 0 (stored) vs 3"``."""
    return [
        f"{k} {json.dumps(stored.get(k))} (stored) vs {json.dumps(wanted.get(k))}"
        for k in sorted(set(stored) | set(wanted))
        if stored.get(k) != wanted.get(k)
    ]


class StudyRows:
    """The finished rows of one study, kept in ``folder``/:data:`PARTIAL` as they come
    (see the module docstring). Open with :meth:`create` or :meth:`resume`;
    :meth:`append` each row; :meth:`finish` once the final outputs are written."""

    def __init__(self, path: Path, config: StudyConfig, rows: dict[int, dict], notes=()):
        self.path = path
        self.config = config
        self.rows = rows
        """Finished rows by plan index (those kept and those appended since)."""
        self.notes = list(notes)
        """What :meth:`resume` had to say about the file (a line cut short)."""
        self._keys = [s.key for s in plan_trials(config)]
        self._fd: int | None = os.open(path, os.O_WRONLY | os.O_APPEND)

    @classmethod
    def create(cls, folder, config: StudyConfig) -> StudyRows:
        """Start keeping the rows of a new study in ``folder`` (made if missing).

        Raises:
            StudyError: ``folder`` holds an unfinished study (resume it or move it first:
                starting again would lose its rows).
        """
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / PARTIAL
        if path.exists():
            raise StudyError(
                f"{folder} holds an unfinished study ({path.name}, {cls.count(path)} rows): "
                "finish it with --resume, or choose another folder"
            )
        header = {"format": FORMAT, "n_trials": config.n_trials, "config": config_record(config)}
        write_text_atomic(path, json.dumps(header) + "\n")
        return cls(path, config, {})

    @staticmethod
    def count(path: Path) -> int:
        """Complete row lines in a rows file."""
        with open(path, "rb") as f:
            return max(0, f.read().count(b"\n") - 1)

    @classmethod
    def resume(cls, folder, config: StudyConfig) -> StudyRows:
        """The rows an interrupted study kept in ``folder``, to go on with ``config``.

        Raises:
            StudyError: (one line) no unfinished study in ``folder``; its configuration
                differs from ``config`` (the message names the fields); or the file is
                damaged elsewhere than in its last line.
        """
        folder = Path(folder)
        path = folder / PARTIAL
        if not path.is_file():
            raise StudyError(f"{folder} holds no unfinished study to resume (no {PARTIAL})")
        data = path.read_bytes()
        lines = data.split(b"\n")
        tail = lines.pop()  # after the last newline: empty, or a line cut short
        try:
            header = json.loads(lines[0])
            if header.get("format") != FORMAT:
                raise ValueError(f"format {header.get('format')!r}, not {FORMAT}")
            stored = header["config"]
        except (IndexError, ValueError, KeyError, TypeError, AttributeError) as e:
            raise StudyError(f"{path} is not a study's rows file ({e})") from None
        diff = differences(stored, config_record(config))
        if diff:
            raise StudyError(f"cannot resume {folder}: its study differs in " + "; ".join(diff))
        keys = [s.key for s in plan_trials(config)]
        rows: dict[int, dict] = {}
        for number, line in enumerate(lines[1:], start=2):
            try:
                entry = json.loads(line)
                i, key, row = entry["index"], tuple(entry["key"]), entry["row"]
                if not (isinstance(i, int) and 0 <= i < len(keys) and keys[i] == key):
                    raise ValueError(f"trial {i} {key} is not in the study's plan")
                if not isinstance(row, dict):
                    raise ValueError("its row is not a JSON object")
            except (ValueError, KeyError, TypeError) as e:
                raise StudyError(f"{path} line {number} is damaged ({e})") from None
            rows[i] = row
        notes = []
        if tail:
            notes.append(
                f"ignored the last line of {path.name} ({len(tail)} bytes, cut short when "
                "the study was stopped); that trial runs again"
            )
            os.truncate(path, len(data) - len(tail))
        return cls(path, config, rows, notes)

    def append(self, index: int, row: dict) -> None:
        """Keep ``row``, the row of the plan's trial ``index``, on disk now (written whole in
        one write, then synced)."""
        if self._fd is None:
            raise ValueError(f"the rows file {self.path} is closed")
        line = json.dumps({"index": index, "key": list(self._keys[index]), "row": row})
        data = (line + "\n").encode()
        written = 0
        while written < len(data):  # (a regular file takes it in one write)
            written += os.write(self._fd, data[written:])
        os.fsync(self._fd)
        self.rows[index] = row

    def close(self) -> None:
        """Stop appending (the file stays: the study can be resumed)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def finish(self) -> None:
        """The final outputs are written: close and remove the rows file."""
        self.close()
        self.path.unlink(missing_ok=True)
        _fsync_dir(self.path.parent)
