"""The CRTK state table of dvrk.md 2.4."""

import pytest

from davinci_sim.sim import operating_state as ops


@pytest.mark.parametrize(
    ("state", "command", "expected"),
    [
        ("DISABLED", "enable", "ENABLED"),
        ("DISABLED", "unhome", "DISABLED"),
        ("ENABLED", "pause", "PAUSED"),
        ("ENABLED", "home", "ENABLED"),
        ("ENABLED", "disable", "DISABLED"),
        ("PAUSED", "resume", "ENABLED"),
        ("PAUSED", "disable", "DISABLED"),
        ("FAULT", "enable", "ENABLED"),
        ("FAULT", "disable", "DISABLED"),
    ],
)
def test_accepted_transitions(state, command, expected):
    assert ops.transition(state, command) == (expected, "")


@pytest.mark.parametrize(
    ("state", "command"),
    [
        ("DISABLED", "home"),
        ("DISABLED", "pause"),
        ("DISABLED", "resume"),
        ("ENABLED", "resume"),
        ("PAUSED", "enable"),
        ("PAUSED", "home"),
        ("FAULT", "home"),
        ("FAULT", "resume"),
    ],
)
def test_refused_transitions_say_why(state, command):
    new, message = ops.transition(state, command)
    assert new is None
    assert command in message and state in message


def test_unknown_command_lists_valid_ones():
    new, message = ops.transition("ENABLED", "fly")
    assert new is None and "enable" in message
