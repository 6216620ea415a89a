"""Shared memory between the loop process and its readers: files in ``/dev/shm``, mapped.

:class:`SharedBuffer` is a named memory-mapped file (created and removed by the parent
process, opened by the children by path; this avoids ``multiprocessing.shared_memory``'s
resource tracker, which unlinks blocks when any process that attached them exits).

:class:`LatestSlot` keeps the latest message of a single writer for many readers without
locks: two alternating slots, each with a sequence number that is odd while the slot is
being written (a seqlock). A reader copies the newest complete slot and retries if the
writer overwrote it meanwhile. This relies on stores becoming visible in program order,
which x86-64 guarantees (TSO); the writes are done by separate C calls, which the compiler
cannot reorder.
"""

from __future__ import annotations

import mmap
import os
import tempfile
import uuid

import numpy as np

_DIR = "/dev/shm" if os.path.isdir("/dev/shm") else tempfile.gettempdir()


class SharedBuffer:
    """A shared memory-mapped file of ``size`` bytes.

    Args:
        size: bytes (creating), or None to open an existing ``path``.
        path: the file (default: a new unique name in ``/dev/shm``).
    """

    def __init__(self, size: int | None = None, path: str | None = None) -> None:
        self.owner = size is not None
        if self.owner:
            if size <= 0:
                raise ValueError(f"size must be > 0 bytes, got {size!r}")
            self.path = path or os.path.join(_DIR, f"davinci-sim-{uuid.uuid4().hex}")
            fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_RDWR, 0o600)
            try:
                os.ftruncate(fd, size)
                self.mm = mmap.mmap(fd, size)
            finally:
                os.close(fd)
        else:
            if path is None:
                raise ValueError("opening a shared buffer needs its path")
            self.path = path
            fd = os.open(path, os.O_RDWR)
            try:
                self.mm = mmap.mmap(fd, 0)
            finally:
                os.close(fd)
        self.size = len(self.mm)

    def close(self) -> None:
        """Unmap; the owner also removes the file. Idempotent."""
        try:
            self.mm.close()
        except BufferError:
            pass  # numpy views still alive: the mapping goes with them
        if self.owner:
            try:
                os.unlink(self.path)
            except FileNotFoundError:
                pass
            self.owner = False


class LatestSlot:
    """Latest-message exchange over a :class:`SharedBuffer` (see the module docstring).

    Layout: ``int64 latest`` then two slots of ``[int64 seq, int64 length, data…]``.
    """

    HEADER = 8

    def __init__(self, buffer: SharedBuffer, offset: int = 0, size: int | None = None) -> None:
        size = buffer.size - offset if size is None else size
        self.capacity = (size - self.HEADER) // 2 - 16
        if self.capacity <= 0:
            raise ValueError(f"a LatestSlot needs more than {self.HEADER + 32} bytes")
        self._mm = buffer.mm
        self._latest = np.ndarray((1,), dtype=np.int64, buffer=buffer.mm, offset=offset)
        self._slots = []
        for i in range(2):
            start = offset + self.HEADER + i * (self.capacity + 16)
            hdr = np.ndarray((2,), dtype=np.int64, buffer=buffer.mm, offset=start)
            self._slots.append((hdr, start + 16))
        self._written = 0

    @classmethod
    def size_for(cls, capacity: int) -> int:
        """Bytes needed for messages of up to ``capacity`` bytes."""
        return cls.HEADER + 2 * (capacity + 16) + 16

    def write(self, *parts) -> None:
        """Publish the concatenation of ``parts`` (bytes-like).

        Raises:
            ValueError: if it does not fit (nothing is published then).
        """
        n = sum(memoryview(p).nbytes for p in parts)
        if n > self.capacity:
            raise ValueError(f"message of {n} bytes exceeds the slot capacity {self.capacity}")
        slot = (self._written + 1) % 2
        hdr, start = self._slots[slot]
        hdr[0] += 1  # odd: being written
        pos = start
        for p in parts:
            m = memoryview(p).cast("B")
            self._mm[pos : pos + m.nbytes] = m
            pos += m.nbytes
        hdr[1] = n
        hdr[0] += 1  # even: complete
        self._latest[0] = slot
        self._written += 1

    def read(self, retries: int = 100) -> bytes | None:
        """The latest complete message, or None if nothing was published yet."""
        for _ in range(retries):
            slot = int(self._latest[0])
            hdr, start = self._slots[slot]
            seq = int(hdr[0])
            if seq == 0:
                return None
            if seq % 2:
                continue  # being written: the other slot is complete, try again
            n = int(hdr[1])
            data = bytes(self._mm[start : start + n])
            if int(hdr[0]) == seq:
                return data
        raise RuntimeError("shared slot kept changing while being read")
