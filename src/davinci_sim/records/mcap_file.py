"""Writing and reading the recording files: MCAP (the ``mcap`` library), JSON messages.

:class:`McapWriter` registers each channel with its schema (:mod:`.mcap_schemas`) on first
use and writes messages into zstd-compressed chunks. A chunk is closed and handed to the
operating system when it reaches ``chunk_size`` bytes or ``flush_period`` seconds of wall
time after its first message (``mcap``'s ``Writer.flush``): a process killed at any moment
leaves a file that holds everything up to its last closed chunk, the schemas and channels
included (a chunked MCAP repeats them inside the chunks), lacking only the summary and the
footer that :meth:`McapWriter.close` writes.

:func:`read_mcap` reads a file whole, finished or not. ``mcap``'s own readers need the
footer to seek (``SeekingReader.get_summary`` reads it from the file's end) or raise at the
first incomplete record (``NonSeekingReader``); :func:`read_mcap` streams the records
(``StreamReader`` with ``emit_chunks``), checks each chunk's CRC before taking its
messages, and stops at the first record that is cut off or does not check, saying so in
:attr:`McapContents.complete` and :attr:`McapContents.problem`.
"""

from __future__ import annotations

import json
import struct
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from davinci_sim.records.mcap_schemas import SCHEMAS, schema_bytes

#: The MCAP profile of the files (an application's own: the messages are JSON).
PROFILE = "davinci-sim"
#: Chunks close at this size, bytes (uncompressed), or after FLUSH_PERIOD s.
CHUNK_SIZE = 1 << 20
#: Wall time, s, a chunk stays open at most: what a killed process can lose.
FLUSH_PERIOD = 1.0


class McapWriter:
    """One recording file being written (see the module docstring). Not thread-safe: one
    thread writes.

    Args:
        path: the file (created or truncated).
        chunk_size, flush_period: when a chunk is closed (bytes, s of wall time).
        clock: the wall clock for ``flush_period`` (s).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        chunk_size: int = CHUNK_SIZE,
        flush_period: float = FLUSH_PERIOD,
        clock=time.monotonic,
    ) -> None:
        from mcap.writer import CompressionType, Writer

        self.path = Path(path)
        self._file = open(self.path, "wb")  # noqa: SIM115 (closed by close())
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile=PROFILE, library="davinci-sim")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._flush_period = flush_period
        self._clock = clock
        self._opened: float | None = None
        self.messages = 0
        """Messages written so far."""
        self.closed = False

    def channel(self, topic: str, schema: str, metadata: Mapping[str, str] | None = None) -> int:
        """The id of ``topic``'s channel (registered with ``schema`` on first use).

        Raises:
            ValueError: ``topic`` registered with another schema, or an unknown schema.
        """
        cid = self._channels.get(topic)
        if cid is not None:
            return cid
        if schema not in SCHEMAS:
            raise ValueError(f"unknown schema {schema!r}; known: {sorted(SCHEMAS)}")
        sid = self._schemas.get(schema)
        if sid is None:
            sid = self._schemas[schema] = self._writer.register_schema(
                schema, "jsonschema", schema_bytes(schema)
            )
        cid = self._channels[topic] = self._writer.register_channel(
            topic, "json", sid, dict(metadata or {})
        )
        return cid

    def write(self, topic: str, schema: str, log_time_ns: int, message: Mapping[str, Any]) -> None:
        """Write one JSON message on ``topic`` at ``log_time_ns``.

        Raises:
            ValueError: a message that is not strict JSON (NaN included).
        """
        data = json.dumps(message, separators=(",", ":"), allow_nan=False).encode()
        cid = self.channel(topic, schema)
        self._writer.add_message(cid, log_time_ns, data, log_time_ns, self.messages)
        self.messages += 1
        now = self._clock()
        if self._opened is None:
            self._opened = now
        elif now - self._opened >= self._flush_period:
            self.flush()

    def flush(self) -> None:
        """Close the chunk in progress and hand everything to the operating system."""
        self._writer.flush()
        self._opened = None

    def attach(self, name: str, media_type: str, data: bytes, log_time_ns: int = 0) -> None:
        """A file attached to the recording (the task file, the model's description)."""
        now = time.time_ns()
        self._writer.add_attachment(now, log_time_ns, name, media_type, data)
        self._file.flush()

    def metadata(self, name: str, values: Mapping[str, Any]) -> None:
        """A named set of key-value strings (values other than strings as JSON)."""
        data = {k: v if isinstance(v, str) else json.dumps(v) for k, v in values.items()}
        self._writer.add_metadata(name, data)
        self._file.flush()

    def close(self) -> None:
        """Write the summary and the footer; close the file (again: nothing)."""
        if self.closed:
            return
        self.closed = True
        try:
            self._writer.finish()
        finally:
            self._file.close()

    def __enter__(self) -> McapWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@dataclass
class McapContents:
    """What :func:`read_mcap` read: messages by topic (``(log_time_ns, decoded JSON)`` in
    file order), attachments (name → bytes), metadata (name → dict of strings), each
    topic's schema name; ``complete``: the file ended with its footer; ``problem``: why the
    reading stopped before (None if complete)."""

    messages: dict[str, list[tuple[int, Any]]] = field(default_factory=dict)
    attachments: dict[str, bytes] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    schemas: dict[str, str] = field(default_factory=dict)
    profile: str = ""
    complete: bool = False
    problem: str | None = None

    def topic(self, name: str) -> list[tuple[int, Any]]:
        """The messages of ``name`` (an empty list if the file has none)."""
        return self.messages.get(name, [])


class McapReadError(ValueError):
    """A file that is not a recording at all (no MCAP header)."""


def read_mcap(path: str | Path) -> McapContents:
    """Everything in the recording at ``path``, up to its last complete chunk (see the
    module docstring).

    Raises:
        McapReadError: not an MCAP file (or an empty one).
        OSError: the file cannot be read.
    """
    from mcap.exceptions import McapError
    from mcap.records import Attachment, Channel, Chunk, Footer, Header, Metadata, Schema
    from mcap.stream_reader import StreamReader, breakup_chunk

    out = McapContents()
    channels: dict[int, Channel] = {}
    schemas: dict[int, Schema] = {}
    cut = (McapError, EOFError, struct.error, ValueError, RuntimeError, KeyError)
    with open(path, "rb") as f:
        reader = StreamReader(f, emit_chunks=True, record_size_limit=1 << 31)
        records = reader.records
        try:
            first = next(records)
        except (StopIteration, *cut) as e:
            raise McapReadError(f"{path} is not an MCAP recording ({type(e).__name__})") from e
        if not isinstance(first, Header):
            raise McapReadError(f"{path} does not start with an MCAP header")
        out.profile = first.profile
        while True:
            try:
                record = next(records)
                inner = (
                    breakup_chunk(record, validate_crc=True)
                    if isinstance(record, Chunk)
                    else [record]
                )
            except StopIteration:
                break
            except Exception as e:  # (a cut record, a chunk failing its CRC or zstd)
                read = sum(map(len, out.messages.values()))
                out.problem = f"cut off after {read} messages ({type(e).__name__}: {e})"
                break
            for r in inner:
                if isinstance(r, Schema):
                    schemas[r.id] = r
                elif isinstance(r, Channel):
                    channels[r.id] = r
                    schema = schemas.get(r.schema_id)
                    out.schemas[r.topic] = schema.name if schema is not None else ""
                    out.messages.setdefault(r.topic, [])
                elif hasattr(r, "channel_id") and hasattr(r, "data"):  # a Message
                    channel = channels[r.channel_id]
                    data = json.loads(r.data) if channel.message_encoding == "json" else r.data
                    out.messages[channel.topic].append((r.log_time, data))
                elif isinstance(r, Attachment):
                    out.attachments[r.name] = r.data
                elif isinstance(r, Metadata):
                    out.metadata[r.name] = dict(r.metadata)
                elif isinstance(r, Footer):
                    out.complete = True
    out.complete = out.complete and out.problem is None  # (the closing magic too)
    return out
