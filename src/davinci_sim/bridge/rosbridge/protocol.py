"""The rosbridge v2 operations as typed messages (rosbridge.md §1).

Each op is a frozen dataclass. :func:`parse_op` builds an incoming op from decoded JSON and
checks every field against the dataclass's type hints (a float for ``throttle_rate`` is an
error, as in rosbridge's ``basic_type_check``); :func:`to_wire` turns any outgoing op into
its JSON object. Fields the protocol does not define are ignored on input (clients add their
own, e.g. ROS# sends ``fragment_size`` everywhere), except that ``fragment_size`` is read by
the session.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import dataclass
from typing import Any, ClassVar, Union

Id = str | int | None


class OpError(ValueError):
    """An op that cannot be parsed; ``op`` and ``id`` are kept to answer the client."""

    def __init__(self, message: str, op: str | None = None, id: Id = None) -> None:
        super().__init__(message)
        self.op = op
        self.id = id


# =========================================================================== client → server
@dataclass(frozen=True)
class Advertise:
    op: ClassVar[str] = "advertise"
    topic: str
    type: str
    id: Id = None
    latch: bool = False
    queue_size: int = 100


@dataclass(frozen=True)
class Unadvertise:
    op: ClassVar[str] = "unadvertise"
    topic: str
    id: Id = None


@dataclass(frozen=True)
class Publish:
    op: ClassVar[str] = "publish"
    topic: str
    msg: dict | None = None
    id: Id = None
    latch: bool = False


@dataclass(frozen=True)
class Subscribe:
    op: ClassVar[str] = "subscribe"
    topic: str
    type: str | None = None
    id: Id = None
    throttle_rate: int = 0
    queue_length: int = 0
    fragment_size: int | None = None
    compression: str | None = None


@dataclass(frozen=True)
class Unsubscribe:
    op: ClassVar[str] = "unsubscribe"
    topic: str
    id: Id = None


@dataclass(frozen=True)
class CallService:
    op: ClassVar[str] = "call_service"
    service: str
    args: dict | list | None = None
    id: Id = None
    fragment_size: int | None = None
    compression: str | None = None
    timeout: float | None = None
    type: str | None = None


@dataclass(frozen=True)
class ServiceResponse:
    """A client's answer to a call of a service it advertised (``result`` is ignored, as
    rosbridge does; rosbridge.md §1.4)."""

    op: ClassVar[str] = "service_response"
    service: str
    id: Id = None
    values: dict | list | str | None = None
    result: bool | None = None


@dataclass(frozen=True)
class AdvertiseService:
    op: ClassVar[str] = "advertise_service"
    service: str
    type: str
    id: Id = None


@dataclass(frozen=True)
class UnadvertiseService:
    op: ClassVar[str] = "unadvertise_service"
    service: str
    id: Id = None


@dataclass(frozen=True)
class AdvertiseAction:
    op: ClassVar[str] = "advertise_action"
    action: str
    type: str
    id: Id = None


@dataclass(frozen=True)
class UnadvertiseAction:
    op: ClassVar[str] = "unadvertise_action"
    action: str
    id: Id = None


@dataclass(frozen=True)
class SendActionGoal:
    op: ClassVar[str] = "send_action_goal"
    action: str
    action_type: str
    args: dict | list | None = None
    feedback: bool = False
    id: Id = None
    fragment_size: int | None = None
    compression: str | None = None


@dataclass(frozen=True)
class CancelActionGoal:
    op: ClassVar[str] = "cancel_action_goal"
    action: str
    id: Id = None


@dataclass(frozen=True)
class ActionFeedback:
    """Feedback from a client that advertised the action (and, outgoing, to the caller)."""

    op: ClassVar[str] = "action_feedback"
    action: str
    id: Id = None
    values: dict | None = None


@dataclass(frozen=True)
class ActionResult:
    """Result from a client that advertised the action (``status`` and ``result`` required,
    as rosbridge checks; rosbridge.md §1.5)."""

    op: ClassVar[str] = "action_result"
    action: str
    status: int
    result: bool
    id: Id = None
    values: dict | str | None = None


@dataclass(frozen=True)
class Fragment:
    op: ClassVar[str] = "fragment"
    id: str | int
    data: str
    num: int
    total: int | float


@dataclass(frozen=True)
class SetLevel:
    op: ClassVar[str] = "set_level"
    level: str
    id: Id = None


@dataclass(frozen=True)
class Auth:
    """rosbridge ROS 1 ``auth`` (rosbridge.md §1.6); roslibpy's ``Ros.authenticate``."""

    op: ClassVar[str] = "auth"
    mac: str
    client: str = ""
    dest: str = ""
    rand: str = ""
    t: float | int | str = 0
    level: str = ""
    end: float | int | str = 0


IncomingOp = (
    Advertise
    | Unadvertise
    | Publish
    | Subscribe
    | Unsubscribe
    | CallService
    | ServiceResponse
    | AdvertiseService
    | UnadvertiseService
    | AdvertiseAction
    | UnadvertiseAction
    | SendActionGoal
    | CancelActionGoal
    | ActionFeedback
    | ActionResult
    | Fragment
    | SetLevel
    | Auth
)

INCOMING: dict[str, type] = {
    cls.op: cls
    for cls in (
        Advertise,
        Unadvertise,
        Publish,
        Subscribe,
        Unsubscribe,
        CallService,
        ServiceResponse,
        AdvertiseService,
        UnadvertiseService,
        AdvertiseAction,
        UnadvertiseAction,
        SendActionGoal,
        CancelActionGoal,
        ActionFeedback,
        ActionResult,
        Fragment,
        SetLevel,
        Auth,
    )
}


# =========================================================================== server → client
@dataclass(frozen=True)
class PublishOut:
    op: ClassVar[str] = "publish"
    topic: str
    msg: dict


@dataclass(frozen=True)
class ServiceResponseOut:
    """On success ``values`` is always an object; on failure it is the error text and
    ``result`` is false (rosbridge.md §1.4)."""

    op: ClassVar[str] = "service_response"
    service: str
    values: dict | str
    result: bool
    id: Id = None


@dataclass(frozen=True)
class CallServiceOut:
    op: ClassVar[str] = "call_service"
    service: str
    args: dict
    id: Id = None


@dataclass(frozen=True)
class StatusOut:
    op: ClassVar[str] = "status"
    level: str
    msg: str
    id: Id = None


@dataclass(frozen=True)
class FragmentOut:
    op: ClassVar[str] = "fragment"
    id: str | int
    data: str
    num: int
    total: int


@dataclass(frozen=True)
class SendActionGoalOut:
    op: ClassVar[str] = "send_action_goal"
    action: str
    action_type: str
    args: dict
    feedback: bool
    id: Id = None


@dataclass(frozen=True)
class CancelActionGoalOut:
    op: ClassVar[str] = "cancel_action_goal"
    action: str
    id: Id = None


@dataclass(frozen=True)
class ActionFeedbackOut:
    op: ClassVar[str] = "action_feedback"
    action: str
    values: dict
    id: Id = None


@dataclass(frozen=True)
class ActionResultOut:
    op: ClassVar[str] = "action_result"
    action: str
    values: dict | str
    status: int
    result: bool
    id: Id = None


OutgoingOp = (
    PublishOut
    | ServiceResponseOut
    | CallServiceOut
    | StatusOut
    | FragmentOut
    | SendActionGoalOut
    | CancelActionGoalOut
    | ActionFeedbackOut
    | ActionResultOut
)

ALL_OPS: tuple[type, ...] = (
    *INCOMING.values(),
    PublishOut,
    ServiceResponseOut,
    CallServiceOut,
    StatusOut,
    FragmentOut,
    SendActionGoalOut,
    CancelActionGoalOut,
    ActionFeedbackOut,
    ActionResultOut,
)

GOAL_STATUS = {
    "UNKNOWN": 0,
    "ACCEPTED": 1,
    "EXECUTING": 2,
    "CANCELING": 3,
    "SUCCEEDED": 4,
    "CANCELED": 5,
    "ABORTED": 6,
}
"""``action_msgs/GoalStatus`` values (rosbridge.md §1.5)."""


# =========================================================================== generic functions
_HINTS: dict[type, dict[str, tuple[type, ...]]] = {}


def _allowed_types(hint: Any) -> tuple[type, ...]:
    origin = typing.get_origin(hint)
    if origin in (Union, types.UnionType):
        out: tuple[type, ...] = ()
        for arg in typing.get_args(hint):
            out += _allowed_types(arg)
        return out
    if hint is type(None) or hint is None:
        return (type(None),)
    if hint is Any:
        return (object,)
    return (origin or hint,)


def field_types(cls: type) -> dict[str, tuple[type, ...]]:
    """The allowed Python types of each field of an op class (from its type hints)."""
    if cls not in _HINTS:
        hints = typing.get_type_hints(cls)
        _HINTS[cls] = {f.name: _allowed_types(hints[f.name]) for f in dataclasses.fields(cls)}
    return _HINTS[cls]


def _matches(value: Any, allowed: tuple[type, ...]) -> bool:
    if object in allowed:
        return True
    if isinstance(value, bool):
        return bool in allowed
    if isinstance(value, int) and float in allowed:
        return True
    return isinstance(value, allowed)


def _type_names(allowed: tuple[type, ...]) -> str:
    names = {
        str: "string",
        int: "integer",
        float: "number",
        bool: "boolean",
        dict: "object",
        list: "array",
        type(None): "null",
    }
    return " or ".join(names.get(t, t.__name__) for t in allowed)


def parse_op(obj: Any) -> IncomingOp:
    """The typed op of a decoded JSON object.

    Raises:
        OpError: not an object, no ``op``, an unknown op (the message lists the known ones),
            a missing required field or a field of the wrong type.
    """
    if not isinstance(obj, dict):
        raise OpError(f"a rosbridge message must be a JSON object, got {type(obj).__name__}")
    op = obj.get("op")
    raw_id = obj.get("id")
    msg_id = raw_id if isinstance(raw_id, str | int) and not isinstance(raw_id, bool) else None
    if not isinstance(op, str):
        raise OpError("message has no 'op' string field", None, msg_id)
    cls = INCOMING.get(op)
    if cls is None:
        raise OpError(
            f"unknown op {op!r}; supported ops: {', '.join(sorted(INCOMING))}", op, msg_id
        )
    kwargs = {}
    for f in dataclasses.fields(cls):
        allowed = field_types(cls)[f.name]
        if f.name in obj:
            value = obj[f.name]
            if not _matches(value, allowed):
                raise OpError(
                    f"{op}: field {f.name!r} must be {_type_names(allowed)}, "
                    f"got {type(value).__name__} {value!r}"[:300],
                    op,
                    msg_id,
                )
            kwargs[f.name] = value
        elif f.default is dataclasses.MISSING:
            raise OpError(f"{op}: missing required field {f.name!r}", op, msg_id)
    return cls(**kwargs)


def to_wire(msg: Any) -> dict:
    """The JSON object of an outgoing op; an ``id`` of None is left out."""
    out: dict[str, Any] = {"op": msg.op}
    for f in dataclasses.fields(msg):
        value = getattr(msg, f.name)
        if f.name == "id" and value is None:
            continue
        out[f.name] = value
    return out
