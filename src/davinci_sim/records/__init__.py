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

Recordings (MCAP files that Foxglove opens as they are, JSON messages with Foxglove's
well-known schemas, :mod:`~davinci_sim.records.mcap_schemas`):

* :class:`SessionRecorder` (:mod:`~davinci_sim.records.recording`): a running session
  (``serve --record``; :func:`recording_part`), its messages per snapshot in
  :mod:`~davinci_sim.records.messages`; :class:`EpisodeRecorder`
  (:mod:`~davinci_sim.records.episodes`): environment rollouts and study trials;
* :func:`read_mcap` (:mod:`~davinci_sim.records.mcap_file`, with the writer): any recording,
  finished or cut off by a killed process;
* :func:`load_recording` and the two replays (:mod:`~davinci_sim.records.replay`: the recorded
  commands through the physics, or the recorded states; ``davinci-sim replay``);
* :func:`to_dataset` (:mod:`~davinci_sim.records.dataset`): recordings to robomimic's HDF5
  layout (``replay --to-dataset``); :mod:`~davinci_sim.records.jsonvalue`: exact JSON of the
  recorded calls' arguments.
"""

from davinci_sim.records.console import records_part
from davinci_sim.records.dataset import to_dataset
from davinci_sim.records.db import (
    ENV_VAR,
    MetricInfo,
    RecordsDB,
    RecordsError,
    Score,
    default_path,
)
from davinci_sim.records.episodes import EpisodeRecorder
from davinci_sim.records.mcap_file import McapReadError, McapWriter, read_mcap
from davinci_sim.records.recorder import AttemptRecorder
from davinci_sim.records.recording import SessionRecorder, recording_description, recording_part
from davinci_sim.records.replay import ReplayError, load_recording, replay_inputs, replay_states
from davinci_sim.records.schema import MIGRATIONS, SCHEMA_VERSION

__all__ = [
    "ENV_VAR",
    "MIGRATIONS",
    "SCHEMA_VERSION",
    "AttemptRecorder",
    "EpisodeRecorder",
    "McapReadError",
    "McapWriter",
    "MetricInfo",
    "RecordsDB",
    "RecordsError",
    "ReplayError",
    "Score",
    "SessionRecorder",
    "default_path",
    "load_recording",
    "read_mcap",
    "recording_description",
    "recording_part",
    "records_part",
    "replay_inputs",
    "replay_states",
    "to_dataset",
]
