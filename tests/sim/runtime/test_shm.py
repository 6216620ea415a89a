"""Shared buffers and the lock-free latest-message slot."""

import numpy as np
import pytest

from davinci_sim.sim.runtime.shm import LatestSlot, SharedBuffer


def test_latest_slot_round_trip_between_two_mappings():
    owner = SharedBuffer(LatestSlot.size_for(1024))
    other = SharedBuffer(path=owner.path)
    try:
        writer, reader = LatestSlot(owner), LatestSlot(other)
        assert reader.read() is None
        writer.write(b"abc", np.arange(3, dtype=np.float64))
        data = reader.read()
        assert data[:3] == b"abc"
        np.testing.assert_array_equal(np.frombuffer(data, offset=3), [0.0, 1.0, 2.0])
        for i in range(5):
            writer.write(bytes([i]) * 10)
            assert reader.read() == bytes([i]) * 10
        with pytest.raises(ValueError, match="capacity"):
            writer.write(b"x" * 2000)
        assert reader.read() == bytes([4]) * 10  # unchanged
    finally:
        del writer, reader
        other.close()
        owner.close()
    with pytest.raises(FileNotFoundError):
        SharedBuffer(path=owner.path)
    with pytest.raises(ValueError):
        SharedBuffer(0)
