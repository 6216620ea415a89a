"""ROS 2-style message classes (``std_msgs.msg.Bool``, ``geometry_msgs.msg.PoseStamped`` …)
for scripts run against davinci-sim, made from the definitions the bridge holds
(:mod:`davinci_sim.bridge.rosbridge.msgdefs`).

A class has one attribute per field, set by keyword (``Bool(data=True)``) or to its default
(0, 0.0, False, "", the definition's ROS 2 default such as ``Quaternion.w = 1``, a nested
message, an empty list or a fixed-length one); ``header.stamp`` is a
``builtin_interfaces.msg.Time`` (``sec``, ``nanosec``). As rclpy's: ``==`` compares the
fields, ``repr`` reads ``std_msgs.msg.Bool(data=False)``, ``get_fields_and_field_types()``
names them; an unknown keyword raises ``TypeError``. ``_type`` is the ``pkg/Type`` name.

:func:`to_wire` turns a message of these classes, of rclpy or of genpy (a sourced ROS
installation's) into the rosbridge JSON object; :func:`from_wire` builds one of these
classes from it. ``davinci-sim run`` puts the packages on the import path
(``shim/msgs``) after everything else: a real ROS installation's are used when present.
"""

from __future__ import annotations

import base64
import functools
from typing import Any

from davinci_sim.bridge.rosbridge.dialect import dialect
from davinci_sim.bridge.rosbridge.types import (
    BINARY_ELEMENTS,
    FLOATS,
    INT_RANGES,
    Field,
    MsgSpec,
    TypeRegistry,
)

PACKAGES = ("builtin_interfaces", "std_msgs", "geometry_msgs", "sensor_msgs", "crtk_msgs")
"""The packages ``davinci-sim run`` provides (``<package>.msg``)."""

_TIME_FIELDS = (Field("sec", "int32"), Field("nanosec", "uint32"))
_BUILTIN_MESSAGES = {
    "time": MsgSpec("builtin_interfaces/Time", _TIME_FIELDS),
    "duration": MsgSpec("builtin_interfaces/Duration", _TIME_FIELDS),
}


@functools.cache
def registry() -> TypeRegistry:
    """The bridge's definitions in the ROS 2 dialect."""
    return TypeRegistry(dialect(2))


def _spec(type_name: str) -> MsgSpec:
    for builtin, spec in _BUILTIN_MESSAGES.items():
        if type_name in (builtin, spec.name):
            return spec
    return registry().message(type_name)


class MessageBase:
    """What every generated class shares (see the module docstring)."""

    __slots__ = ()
    _type = ""
    _spec = MsgSpec("", ())

    def __init__(self, **fields: Any) -> None:
        unknown = sorted(set(fields) - set(self.__slots__))
        if unknown:
            raise TypeError(
                f"{self._type} has no field {', '.join(unknown)} "
                f"(fields: {', '.join(self.__slots__) or 'none'})"
            )
        for f in self._spec.fields:
            setattr(self, f.name, fields[f.name] if f.name in fields else _default(f))

    @classmethod
    def get_fields_and_field_types(cls) -> dict[str, str]:
        return {f.name: _field_type_text(f) for f in cls._spec.fields}

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(getattr(self, n) == getattr(other, n) for n in self.__slots__)

    __hash__ = None  # mutable, as rclpy's

    def __repr__(self) -> str:
        fields = ", ".join(f"{n}={getattr(self, n)!r}" for n in self.__slots__)
        return f"{type(self).__module__}.{type(self).__name__}({fields})"


def _field_type_text(f: Field) -> str:
    base = {"time": "builtin_interfaces/Time", "duration": "builtin_interfaces/Duration"}.get(
        f.type, f.type
    )
    if not f.is_array:
        return base
    return f"{base}[{f.length}]" if f.length is not None else f"sequence<{base}>"


def message_class(type_name: str) -> type[MessageBase]:
    """The class of ``type_name`` (``pkg/Type``, ``pkg/msg/Type``, ``time``, ``duration``):
    one class per type, however it is spelled.

    Raises:
        UnknownTypeError: the bridge has no such message.
    """
    return _class(_spec(type_name).name)


@functools.cache
def _class(canonical: str) -> type[MessageBase]:
    spec = _spec(canonical)
    package, name = spec.name.split("/")[0], spec.name.split("/")[-1]
    constants = {c.name: _constant(c.type, c.value) for c in spec.constants}
    cls = type(name, (MessageBase,), {
        "__slots__": spec.field_names, "_type": spec.name, "_spec": spec,
        "__module__": f"{package}.msg", "__qualname__": name,
        "__doc__": f"``{spec.name}``: " + (", ".join(
            f"{_field_type_text(f)} {f.name}" for f in spec.fields) or "no field") + ".",
        **constants,
    })  # fmt: skip
    return cls


def _constant(type_name: str, text: str) -> Any:
    if type_name in FLOATS:
        return float(text)
    if type_name in INT_RANGES:
        return int(text, 0)
    if type_name == "bool":
        return text.strip().lower() in ("true", "1")
    return text.strip().strip("\"'")


def package_classes(package: str) -> dict[str, type[MessageBase]]:
    """Every message class of ``package`` by name (``builtin_interfaces``: Time, Duration)."""
    if package == "builtin_interfaces":
        names = [s.name for s in _BUILTIN_MESSAGES.values()]
    else:
        names = [n for n in registry().message_names if n.split("/")[0] == package]
    return {n.split("/")[-1]: message_class(n) for n in names}


def export(namespace: dict, package: str) -> list[str]:
    """Fill a ``<package>.msg`` module's ``namespace`` with the package's classes; the names."""
    classes = package_classes(package)
    namespace.update(classes)
    return sorted(classes)


# =========================================================================== defaults
def _default(f: Field) -> Any:
    if f.is_array and f.type in BINARY_ELEMENTS:
        return bytes(f.length or 0)
    if f.is_array:
        return [_default_scalar(f) for _ in range(f.length or 0)]
    return _default_scalar(f)


def _default_scalar(f: Field) -> Any:
    t = f.type
    if t in FLOATS:
        return float(f.default) if f.default is not None else 0.0
    if t in INT_RANGES:
        return int(f.default, 0) if f.default is not None else 0
    if t == "bool":
        return f.default is not None and f.default.lower() in ("true", "1")
    if t == "string":
        return f.default.strip("\"'") if f.default is not None else ""
    return message_class(t)()


# =========================================================================== conversions
def _field_names(msg: Any) -> tuple[str, ...] | None:
    """The fields of a message object: ours, rclpy's or genpy's; None for a non-message."""
    if isinstance(msg, MessageBase):
        return msg.__slots__
    fields = getattr(type(msg), "get_fields_and_field_types", None)  # rclpy
    if callable(fields):
        return tuple(fields())
    if hasattr(type(msg), "_slot_types"):  # genpy (ROS 1)
        return tuple(type(msg).__slots__)
    return None


def is_message(value: Any) -> bool:
    return value is not None and _field_names(value) is not None


def is_message_class(cls: type) -> bool:
    """A message class: ours, rclpy's (``get_fields_and_field_types``) or genpy's."""
    rclpy = callable(getattr(cls, "get_fields_and_field_types", None))
    return issubclass(cls, MessageBase) or rclpy or hasattr(cls, "_slot_types")


def fill(msg: Any, value: dict) -> Any:
    """Set ``msg``'s fields (a message object of any kind) from rosbridge JSON, nested
    messages in place; returns ``msg``."""
    for name, v in value.items():
        current = getattr(msg, name, None)
        if is_message(current) and isinstance(v, dict):
            fill(current, v)
        else:
            setattr(msg, name, v)
    return msg


def to_wire(msg: Any, ros_version: int = 2) -> Any:
    """A message object (or value) as rosbridge JSON: objects → dicts, sequences → lists,
    bytes → lists of ints, numpy numbers → Python numbers; times ``sec``/``nanosec``, or
    ``secs``/``nsecs`` for a ROS 1 server (``ros_version`` 1)."""
    if ros_version == 1 and type(msg) in (_class("builtin_interfaces/Time"),
                                          _class("builtin_interfaces/Duration")):  # fmt: skip
        return {"secs": to_wire(msg.sec), "nsecs": to_wire(msg.nanosec)}
    names = _field_names(msg)
    if names is not None:
        return {n: to_wire(getattr(msg, n), ros_version) for n in names}
    if isinstance(msg, dict):
        return {k: to_wire(v, ros_version) for k, v in msg.items()}
    if isinstance(msg, bytes | bytearray):
        return list(msg)
    if isinstance(msg, str | bool | int | float) or msg is None:
        return msg
    if hasattr(msg, "tolist"):  # numpy arrays and numbers, array.array
        return to_wire(msg.tolist(), ros_version)
    if isinstance(msg, list | tuple):
        return [to_wire(v, ros_version) for v in msg]
    raise TypeError(f"cannot send {type(msg).__name__} {msg!r} in a ROS message")


def from_wire(type_name: str, value: dict) -> MessageBase:
    """A ``type_name`` object from rosbridge JSON (missing fields at their defaults; a time
    in either spelling; binary fields from base64 text or a list)."""
    return _build(_spec(type_name), value)


def _build(spec: MsgSpec, value: dict) -> MessageBase:
    cls = message_class(spec.name)
    if spec in _BUILTIN_MESSAGES.values() and isinstance(value, dict):
        value = {"sec": value.get("sec", value.get("secs", 0)),
                 "nanosec": value.get("nanosec", value.get("nsecs", 0))}  # fmt: skip
    msg = cls()
    for f in spec.fields:
        if f.name in value:
            setattr(msg, f.name, _field_value(f, value[f.name]))
    return msg


def _field_value(f: Field, v: Any) -> Any:
    if f.is_array and f.type in BINARY_ELEMENTS:
        return base64.b64decode(v) if isinstance(v, str) else bytes(v)
    if f.is_builtin and f.type not in ("time", "duration"):
        return list(v) if f.is_array else v
    spec = _spec(f.type)
    if f.is_array:
        return [_build(spec, e) for e in v]
    return _build(spec, v)
