"""The input log: every call ``execute`` runs, with the tick it runs before."""

from __future__ import annotations

import numpy as np
import pytest

from davinci_sim.sim.handle import execute
from davinci_sim.sim.inputs import INPUT_LOG, InputLog
from davinci_sim.sim.simulation import Simulation


@pytest.fixture(scope="module")
def sim():
    sim = Simulation("psm1")
    yield sim
    sim.close()


def test_calls_are_logged_with_their_tick_and_drained_once(sim):
    log = InputLog(sim, maxlen=3)
    sim.add_component(log)
    events = []
    unsubscribe = log.channels.subscribe(lambda event, payload: events.append((event, payload)))
    try:
        q = np.zeros(6)
        execute(sim, "PSM1", "servo_jp", (q,), {})
        sim.tick()
        sim.tick()
        execute(sim, "PSM1/jaw", "servo_jp", (0.2,), {})
        execute(sim, INPUT_LOG, "info", (), {})  # (the log's own calls are not logged)
        with pytest.raises(AttributeError):
            execute(sim, "PSM1", "no_such_method", (), {})  # (refused before it runs: none)
        t0 = sim.tick_count
        assert [(e[0], e[1][:4]) for e in events] == [
            ("call", (1, t0 - 2, "PSM1", "servo_jp")),
            ("call", (2, t0, "PSM1/jaw", "servo_jp")),
        ]
        assert events[0][1][4][0] is q  # the arguments as given
        assert [e[0] for e in log.drain()] == [1, 2]
        execute(sim, "PSM1", "measured_js", (), {})
        assert log.drain() == [] and len(events) == 3  # after a drain: events only
        assert log.info()["signature"] == sim.signature and log.info()["nq"] == sim.model.nq
    finally:
        unsubscribe()
        sim.remove_component(INPUT_LOG)


def test_the_buffer_keeps_the_newest_and_counts_the_dropped(sim):
    log = InputLog(sim, maxlen=2)
    for k in range(5):
        log.record(k, "PSM1", "measured_js", (), {})
    assert [e[0] for e in log.drain()] == [4, 5] and log.dropped == 3
