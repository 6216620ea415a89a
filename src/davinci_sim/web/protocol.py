"""The web console's messages from the page, checked before anything acts on them.

The page talks JSON over one websocket. Every message is a mapping with an ``op``; each op
has a declared set of fields with types and ranges (:data:`OPS`). :func:`parse_message`
turns a text frame into a :class:`Command` or raises :class:`ProtocolError` with a message
the page shows; nothing is sent to the simulation for a refused message. Pure: no sockets,
no simulation.

Ops (fields; units):

- ``hello`` (``token``: str, optional): the first message; with a token when the server
  asks for one (not on loopback).
- ``control`` (``take``: bool): take or release operating the console (one operator).
- ``input`` (``mtm``: MTML/MTMR; ``axes``: 3 numbers in [-1, 1], the hand's rate along the
  screen's right, up and into-the-screen directions; ``gripper``: rad in [−15°, 60°], optional;
  ``turn``: 3 numbers in [-1, 1], optional, the wrist's rate about the same three axes
  (right-hand rule: + about "right" turns a tool pointing into the scene up, + about "up"
  turns it to the left, + about "in" rolls it clockwise as seen on the screen)).
- ``button`` (``name``: clutch, camera, operator_present; ``pressed``: bool).
- ``condition`` (``condition``: a condition name of the task, or a fixture entry
  ``{"type": "viscous", "B": N·s/m, "G_max": N}``, ``{"type": "spring", ...}``,
  ``{"type": "none"}``).
- ``task`` (``action``: reset).
- ``trainee`` (``name``: str, ≤ 64 characters: tags the rows of the results table).
- ``teleop`` (``enable``: bool, optional; ``scale``: number in (0, 1], optional).
- ``arms`` (``action``: enable, home, disable).
- ``synthetic`` (``action``: start, stop; ``subject``: int ≥ 0, optional; ``practice``:
  int ≥ 1, optional): watch a synthetic trainee do the task on the live console.
- ``study`` (``action``: start; ``subjects``: 1 … 10; ``repetitions``: 1 … 5): a small
  study of the task with the study's synthetic trainees (progress, then the report).
- ``exercise`` (``task``: a name the server offers in ``hello``'s ``exercises``): switch the
  console to that exercise; the server restarts its system with it (the pages reconnect).
- ``view`` (``stereo``: bool; ``source``: ``server`` or ``page``, optional, default
  ``server``): whether this page shows both eyes (side by side, anaglyph; the right image
  is encoded and sent only while some page does), and who draws its endoscope: the server
  (JPEG frames) or the page itself (the scene once, then pose messages).
- ``ping`` (``t``: number, the page's clock, ms): answered with ``pong`` (latency).
- ``advance`` (``seconds``: number in (0, 10], s of simulated time): a stepped server
  (``hello``'s ``stepped``; ``ServeOptions.stepped``) ticks that much more and sends the
  page the state there, then ``advanced`` (``tick``); any other answers ``advanced`` with
  ``refused`` (why). For scripts at the page (``window.davinci.advance(s)``), any page.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

#: The largest message the page may send, bytes.
MAX_MESSAGE = 16 * 1024
#: The gripper's range, rad: squeezed past "just closed" (0) to −15° … 60° open (dvrk.md
#: 1.5, 4.1; devices.hand_input.GRIPPER_RANGE: −15° makes the jaw's goal −20°).
GRIPPER_MIN = math.radians(-15.0)
GRIPPER_MAX = math.radians(60.0)
#: Buttons the page may press.
BUTTONS = ("clutch", "camera", "operator_present")
MTMS = ("MTML", "MTMR")
#: Who draws a page's endoscope (the ``view`` op's ``source``).
VIEW_SOURCES = ("server", "page")


class ProtocolError(ValueError):
    """A message the web console refuses; ``str(e)`` is shown in the page."""


@dataclass(frozen=True)
class Command:
    """One checked message of the page: its op and its fields (only the declared ones)."""

    op: str
    args: dict[str, Any] = field(default_factory=dict)


def _number(name: str, lo: float = -math.inf, hi: float = math.inf, *, lo_open=False):
    def check(value):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ProtocolError(f"{name} must be a number, got {value!r}")
        v = float(value)
        if not math.isfinite(v):
            raise ProtocolError(f"{name} must be finite, got {value!r}")
        if v < lo or v > hi or (lo_open and v == lo):
            bracket = "(" if lo_open else "["
            raise ProtocolError(f"{name} must be in {bracket}{lo:g}, {hi:g}], got {v:g}")
        return v

    return check


def _integer(name: str, lo: int = 0):
    def check(value):
        if isinstance(value, bool) or not isinstance(value, int):
            raise ProtocolError(f"{name} must be an integer, got {value!r}")
        if value < lo:
            raise ProtocolError(f"{name} must be >= {lo}, got {value}")
        return int(value)

    return check


def _boolean(name: str):
    def check(value):
        if not isinstance(value, bool):
            raise ProtocolError(f"{name} must be true or false, got {value!r}")
        return value

    return check


def _choice(name: str, choices):
    def check(value):
        if value not in choices:
            raise ProtocolError(f"{name} must be one of {list(choices)}, got {value!r}")
        return value

    return check


def _text(name: str, max_length: int):
    def check(value):
        if not isinstance(value, str):
            raise ProtocolError(f"{name} must be text, got {value!r}")
        if len(value) > max_length:
            raise ProtocolError(f"{name} is longer than {max_length} characters")
        if any(ord(c) < 32 for c in value):
            raise ProtocolError(f"{name} must not contain control characters")
        return value.strip()

    return check


def _three(name: str):
    def check(value):
        if not isinstance(value, list) or len(value) != 3:
            raise ProtocolError(f"{name} must be a list of 3 numbers in [-1, 1], got {value!r}")
        return [_number(f"{name}[{i}]", -1.0, 1.0)(v) for i, v in enumerate(value)]

    return check


_axes = _three("axes")


_FIXTURE_PARAMETER = _number("a fixture parameter", 0.0, 1e4)


def _condition(value):
    if isinstance(value, str):
        return _text("condition", 64)(value)
    if isinstance(value, dict):
        kind = value.get("type")
        if not isinstance(kind, str):
            raise ProtocolError(f"a fixture entry needs a 'type', got {value!r}")
        out = {"type": kind}
        for k, v in value.items():
            if k == "type":
                continue
            if not isinstance(k, str) or len(k) > 32:
                raise ProtocolError(f"bad fixture parameter name {k!r}")
            try:
                out[k] = _FIXTURE_PARAMETER(v)
            except ProtocolError as e:
                raise ProtocolError(f"{k}: {e}") from None
        return out
    raise ProtocolError(f"condition must be a name or a fixture entry, got {value!r}")


#: The most simulated time one ``advance`` asks for, s (a script steps; it does not run a
#: stepped server for minutes in one message).
MAX_ADVANCE = 10.0

#: op -> {field: (checker, required)}
OPS: dict[str, dict[str, tuple[Any, bool]]] = {
    "hello": {"token": (_text("token", 256), False)},
    "control": {"take": (_boolean("take"), True)},
    "input": {
        "mtm": (_choice("mtm", MTMS), True),
        "axes": (_axes, True),
        "gripper": (_number("gripper", GRIPPER_MIN, GRIPPER_MAX), False),
        "turn": (_three("turn"), False),
    },
    "button": {"name": (_choice("name", BUTTONS), True), "pressed": (_boolean("pressed"), True)},
    "condition": {"condition": (_condition, True)},
    "task": {"action": (_choice("action", ("reset",)), True)},
    "exercise": {"task": (_text("task", 64), True)},
    "trainee": {"name": (_text("name", 64), True)},
    "teleop": {
        "enable": (_boolean("enable"), False),
        "scale": (_number("scale", 0.0, 1.0, lo_open=True), False),
    },
    "arms": {"action": (_choice("action", ("enable", "home", "disable")), True)},
    # The one-click remedy of a problem the page shows (an arm in FAULT, a teleoperation
    # stopped or stuck aligning): see ``WebConsole._recover``.
    "recover": {},
    "synthetic": {
        "action": (_choice("action", ("start", "stop")), True),
        "subject": (_integer("subject"), False),
        "practice": (_integer("practice", 1), False),
    },
    "study": {
        "action": (_choice("action", ("start",)), True),
        "subjects": (_integer("subjects", 1), True),
        "repetitions": (_integer("repetitions", 1), True),
    },
    "view": {
        "stereo": (_boolean("stereo"), True),
        "source": (_choice("source", VIEW_SOURCES), False),
    },
    "ping": {"t": (_number("t"), True)},
    # A stepped server only (``ServeOptions.stepped``, for scripted pages): tick this much
    # simulated time more, s; answered with the state there and an ``advanced`` message.
    "advance": {"seconds": (_number("seconds", 0.0, MAX_ADVANCE, lo_open=True), True)},
}

#: Ops that act on the simulation: only the operator may send them.
OPERATOR_OPS = frozenset(
    {
        "input",
        "button",
        "condition",
        "task",
        "exercise",
        "teleop",
        "arms",
        "recover",
        "synthetic",
        "study",
    }
)


def parse_message(text: str | bytes) -> Command:
    """The :class:`Command` of one websocket message from the page.

    Raises:
        ProtocolError: for a message that is not a JSON object, too large, of an unknown op,
            with unknown or missing fields, or a field of the wrong type or out of range.
    """
    if isinstance(text, bytes):
        raise ProtocolError("the page sends text (JSON) messages, not binary")
    if len(text) > MAX_MESSAGE:
        raise ProtocolError(f"message of {len(text)} bytes is over the {MAX_MESSAGE} limit")
    try:
        data = json.loads(text, parse_constant=_no_constant)
    except (json.JSONDecodeError, ProtocolError) as e:
        raise ProtocolError(f"not JSON: {e}") from None
    if not isinstance(data, dict):
        raise ProtocolError(f"a message must be a JSON object, got {type(data).__name__}")
    op = data.get("op")
    if op not in OPS:
        raise ProtocolError(f"unknown op {op!r}; ops: {sorted(OPS)}")
    spec = OPS[op]
    unknown = sorted(set(data) - set(spec) - {"op"})
    if unknown:
        raise ProtocolError(f"{op}: unknown fields {unknown}; fields: {sorted(spec)}")
    args = {}
    for name, (check, required) in spec.items():
        if name not in data:
            if required:
                raise ProtocolError(f"{op}: '{name}' is required")
            continue
        try:
            args[name] = check(data[name])
        except ProtocolError as e:
            raise ProtocolError(f"{op}: {e}") from None
    return Command(op, args)


def _no_constant(name: str):
    raise ProtocolError(f"{name} is not a number the console accepts")
