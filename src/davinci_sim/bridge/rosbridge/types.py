"""Parsed message, service and action specs, and the registry that resolves type names.

The registry compiles :mod:`davinci_sim.bridge.rosbridge.msgdefs` for one dialect: lines tagged
``# ros1``/``# ros2`` are kept only in their dialect, ROS 2 default values are applied only
in ROS 2 (ROS 1 fills zeros, as rosbridge does), ``Header`` means ``std_msgs/Header``,
``builtin_interfaces/Time`` is the builtin ``time``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from davinci_sim.bridge.rosbridge.dialect import Dialect, Kind, split_type
from davinci_sim.bridge.rosbridge.msgdefs import ACTIONS, MESSAGES, SERVICES

#: Builtin field types and their value class: int ranges, floats, strings, times.
INT_RANGES: dict[str, tuple[int, int]] = {
    "int8": (-(2**7), 2**7 - 1),
    "uint8": (0, 2**8 - 1),
    "byte": (-(2**7), 2**8 - 1),  # int8 in ROS 1, octet in ROS 2: accept both ranges
    "char": (0, 2**8 - 1),
    "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint64": (0, 2**64 - 1),
}
FLOATS = ("float32", "float64")
BUILTINS = frozenset([*INT_RANGES, *FLOATS, "bool", "string", "time", "duration"])
#: Arrays of these element types are base64 strings in JSON (rosbridge.md §3).
BINARY_ELEMENTS = frozenset(["uint8", "char"])
_BUILTIN_ALIASES = {"builtin_interfaces/Time": "time", "builtin_interfaces/Duration": "duration"}


class UnknownTypeError(KeyError):
    """A message, service or action type the bridge has no definition for."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


class DefinitionError(ValueError):
    """A malformed definition (a bug in the data, or in user-supplied extra definitions)."""


@dataclass(frozen=True)
class Field:
    """One field: ``type`` is a builtin name or a canonical ``pkg/Type``."""

    name: str
    type: str
    is_array: bool = False
    length: int | None = None
    """Fixed array length, None for unbounded arrays and scalars."""
    default: str | None = None
    """ROS 2 default value as written in the definition, if any."""

    @property
    def is_builtin(self) -> bool:
        return self.type in BUILTINS

    @property
    def is_binary(self) -> bool:
        """``uint8[]``/``char[]``: base64 in JSON, bytes in memory."""
        return self.is_array and self.type in BINARY_ELEMENTS


@dataclass(frozen=True)
class Constant:
    name: str
    type: str
    value: str


@dataclass(frozen=True)
class MsgSpec:
    name: str
    fields: tuple[Field, ...]
    constants: tuple[Constant, ...] = ()

    @property
    def field_names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.fields)


@dataclass(frozen=True)
class SrvSpec:
    name: str
    request: MsgSpec
    response: MsgSpec


@dataclass(frozen=True)
class ActionSpec:
    name: str
    goal: MsgSpec
    result: MsgSpec
    feedback: MsgSpec


def _resolve_field_type(raw: str, package: str) -> str:
    if raw in BUILTINS:
        return raw
    if raw == "Header":
        return "std_msgs/Header"
    if "/" in raw:
        canonical, _ = split_type(raw)
        return _BUILTIN_ALIASES.get(canonical, canonical)
    return f"{package}/{raw}"


def parse_definition(name: str, text: str, ros_version: int) -> MsgSpec:
    """Parse one ``.msg`` text (or one section of a ``.srv``/``.action``).

    Raises:
        DefinitionError: on a line that is not ``type name [default]`` or ``TYPE NAME=value``.
    """
    package = name.split("/")[0]
    fields: list[Field] = []
    constants: list[Constant] = []
    for raw_line in text.splitlines():
        line, _, comment = raw_line.partition("#")
        tag = comment.strip()
        if tag in ("ros1", "ros2") and tag != f"ros{ros_version}":
            continue
        line = line.strip()
        if not line:
            continue
        if "=" in line:
            left, value = line.split("=", 1)
            parts = left.split()
            if len(parts) != 2:
                raise DefinitionError(f"{name}: bad constant line {raw_line!r}")
            constants.append(Constant(parts[1], parts[0], value.strip()))
            continue
        parts = line.split()
        if len(parts) not in (2, 3):
            raise DefinitionError(f"{name}: bad field line {raw_line!r}")
        type_text, field_name = parts[0], parts[1]
        default = parts[2] if len(parts) == 3 and ros_version == 2 else None
        is_array, length = False, None
        if type_text.endswith("]"):
            base, _, size = type_text[:-1].partition("[")
            is_array = True
            if size.startswith("<="):  # bounded sequence: unbounded for JSON purposes
                size = ""
            length = int(size) if size else None
            type_text = base
        fields.append(
            Field(field_name, _resolve_field_type(type_text, package), is_array, length, default)
        )
    return MsgSpec(name, tuple(fields), tuple(constants))


class TypeRegistry:
    """All known types for one dialect.

    Args:
        dialect: the server's dialect.
        messages, services, actions: extra definitions (``pkg/Type`` → ``.msg`` text), added
            to (and overriding) the built-in tables.
    """

    def __init__(
        self,
        dialect: Dialect,
        *,
        messages: Mapping[str, str] | None = None,
        services: Mapping[str, str] | None = None,
        actions: Mapping[str, str] | None = None,
    ) -> None:
        self.dialect = dialect
        v = dialect.ros_version
        self._messages: dict[str, MsgSpec] = {}
        for name, text in {**MESSAGES, **(messages or {})}.items():
            canonical, _ = split_type(name)
            self._messages[canonical] = parse_definition(canonical, text, v)
        self._services: dict[str, SrvSpec] = {}
        for name, text in {**SERVICES, **(services or {})}.items():
            canonical, _ = split_type(name)
            req, resp = _sections(canonical, text, 2)
            self._services[canonical] = SrvSpec(
                canonical,
                parse_definition(f"{canonical}Request", req, v),
                parse_definition(f"{canonical}Response", resp, v),
            )
        self._actions: dict[str, ActionSpec] = {}
        for name, text in {**ACTIONS, **(actions or {})}.items():
            canonical, _ = split_type(name)
            goal, result, feedback = _sections(canonical, text, 3)
            self._actions[canonical] = ActionSpec(
                canonical,
                parse_definition(f"{canonical}Goal", goal, v),
                parse_definition(f"{canonical}Result", result, v),
                parse_definition(f"{canonical}Feedback", feedback, v),
            )
        self._check_references()

    def _check_references(self) -> None:
        specs = [*self._messages.values()]
        for s in self._services.values():
            specs += [s.request, s.response]
        for a in self._actions.values():
            specs += [a.goal, a.result, a.feedback]
        for spec in specs:
            for f in spec.fields:
                if not f.is_builtin and f.type not in self._messages:
                    raise DefinitionError(f"{spec.name}.{f.name}: unknown type {f.type!r}")

    # ------------------------------------------------------------------ lookups
    def message(self, name: str) -> MsgSpec:
        """The spec of a message type in any spelling.

        Raises:
            UnknownTypeError: naming the known types.
            TypeNameError: for a malformed name.
        """
        canonical, kind = split_type(name)
        canonical = _BUILTIN_ALIASES.get(canonical, canonical)
        spec = self._messages.get(canonical) if kind in (None, "msg") else None
        if spec is None:
            raise UnknownTypeError(
                f"unknown message type {name!r}; known types: {', '.join(sorted(self._messages))}"
            )
        return spec

    def service(self, name: str) -> SrvSpec:
        canonical, kind = split_type(name)
        spec = self._services.get(canonical) if kind in (None, "srv") else None
        if spec is None:
            raise UnknownTypeError(
                f"unknown service type {name!r}; known types: {', '.join(sorted(self._services))}"
            )
        return spec

    def action(self, name: str) -> ActionSpec:
        canonical, kind = split_type(name)
        spec = self._actions.get(canonical) if kind in (None, "action") else None
        if spec is None:
            raise UnknownTypeError(
                f"unknown action type {name!r}; known types: {', '.join(sorted(self._actions))}"
            )
        return spec

    def has_message(self, name: str) -> bool:
        try:
            self.message(name)
        except (KeyError, ValueError):
            return False
        return True

    def wire_name(self, canonical: str, kind: Kind = "msg") -> str:
        return self.dialect.type_name(canonical, kind)

    @property
    def message_names(self) -> tuple[str, ...]:
        return tuple(sorted(self._messages))

    @property
    def service_names(self) -> tuple[str, ...]:
        return tuple(sorted(self._services))

    @property
    def action_names(self) -> tuple[str, ...]:
        return tuple(sorted(self._actions))


def _sections(name: str, text: str, n: int) -> list[str]:
    parts: list[list[str]] = [[]]
    for line in text.splitlines():
        if line.strip() == "---":
            parts.append([])
        else:
            parts[-1].append(line)
    if len(parts) != n:
        raise DefinitionError(f"{name}: expected {n} sections separated by '---', got {len(parts)}")
    return ["\n".join(p) for p in parts]
