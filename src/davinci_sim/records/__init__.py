"""Trainee records: every attempt at the console, per trainee, in a local SQLite file.

* :class:`RecordsDB` (:mod:`~davinci_sim.records.db`): the file (schema and migrations in
  :mod:`~davinci_sim.records.schema`), WAL mode, one committed transaction per attempt;
  :func:`default_path` (``$DAVINCI_SIM_RECORDS``, else the per-user data folder);
* :class:`AttemptRecorder` (:mod:`~davinci_sim.records.recorder`): writes each finished
  repetition of a task session, from a running simulation's handle, in its own thread;
  :func:`records_part` (:mod:`~davinci_sim.records.console`): the recorder as a part of
  ``davinci-sim serve``;
* :mod:`~davinci_sim.records.report`: what ``davinci-sim trainees list|show|export|curve``
  prints, writes and draws (learning curves with the pass band).
"""

from davinci_sim.records.console import records_part
from davinci_sim.records.db import (
    ENV_VAR,
    MetricInfo,
    RecordsDB,
    RecordsError,
    Score,
    default_path,
)
from davinci_sim.records.recorder import AttemptRecorder
from davinci_sim.records.schema import MIGRATIONS, SCHEMA_VERSION

__all__ = [
    "ENV_VAR",
    "MIGRATIONS",
    "SCHEMA_VERSION",
    "AttemptRecorder",
    "MetricInfo",
    "RecordsDB",
    "RecordsError",
    "Score",
    "default_path",
    "records_part",
]
