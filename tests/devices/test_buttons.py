"""Button events with the dVRK Joy convention (dvrk.md 2.3)."""

import pytest

from davinci_sim.devices import ButtonEvent, parse_button_event


@pytest.mark.parametrize(
    ("value", "event"),
    [
        ([1], ButtonEvent.PRESSED),
        ([0], ButtonEvent.RELEASED),
        ([2], ButtonEvent.CLICKED),
        ((1,), ButtonEvent.PRESSED),
        ([2.0], ButtonEvent.CLICKED),
        ({"buttons": [1], "axes": []}, ButtonEvent.PRESSED),
        (True, ButtonEvent.PRESSED),
        (False, ButtonEvent.RELEASED),
        ("CLICKED", ButtonEvent.CLICKED),
        (" pressed ", ButtonEvent.PRESSED),
        (ButtonEvent.RELEASED, ButtonEvent.RELEASED),
    ],
)
def test_accepted_forms(value, event):
    assert parse_button_event(value) is event


@pytest.mark.parametrize("value", [[3], [1, 0], [], [True], "down", None, 1, {"axes": [1]}])
def test_rejected_forms_name_the_valid_ones(value):
    with pytest.raises(ValueError, match="Joy|buttons|expected"):
        parse_button_event(value)


def test_joy_round_trip():
    for event in ButtonEvent:
        assert parse_button_event(event.to_joy()) is event
