"""Validation of incoming messages against their spec, defaults, and CBOR typed arrays.

Incoming JSON follows rosbridge's rules (rosbridge.md §3): missing fields get their
defaults, an unknown field is an error, an int is accepted for a float, ``uint8[]``/``char[]``
are base64 strings (or lists of ints), times may be spelled ``sec``/``nanosec`` or
``secs``/``nsecs``. Values come out in the server's dialect with binary fields as
``bytes``. Unlike rosbridge, every type error is reported with the path of the field.
"""

from __future__ import annotations

import base64
import binascii
import math
import struct
import time
from typing import Any

from davinci_sim.bridge.rosbridge.types import FLOATS, INT_RANGES, Field, MsgSpec, TypeRegistry

#: Fields accepted and dropped although the dialect lacks them: a ROS 1 ``Header.seq`` sent to
#: a ROS 2 server (roslibpy's ``Header`` always has it, rosbridge.md §3).
_TOLERATED: dict[str, tuple[str, ...]] = {"std_msgs/Header": ("seq",)}


class MessageError(ValueError):
    """A message that does not match its type; the text names the field."""


def _type_label(value: Any) -> str:
    return f"{type(value).__name__} {value!r}"[:80]


def from_wire(registry: TypeRegistry, spec: MsgSpec, value: Any, path: str = "msg") -> dict:
    """Validate ``value`` (decoded JSON) as a ``spec`` message and fill its defaults.

    Raises:
        MessageError: on an unknown field, a wrong type, an out-of-range integer, a bad base64
            string or a wrong fixed-array length.
    """
    if value is None:
        value = {}
    if not isinstance(value, dict):
        raise MessageError(f"{path}: expected an object for {spec.name}, got {_type_label(value)}")
    names = spec.field_names
    for key in value:
        if key not in names and key not in _TOLERATED.get(spec.name, ()):
            raise MessageError(
                f"{path}: unknown field {key!r} for {spec.name} (fields: {', '.join(names) or '-'})"
            )
    out: dict[str, Any] = {}
    for f in spec.fields:
        v = value.get(f.name)
        if v is None and not (f.type in FLOATS and f.name in value):
            # Missing, or null (roslibpy sends ``seq: null``, ``frame_id: null``): the
            # default. A null float stays an error: it is how NaN goes out (codec.py).
            out[f.name] = default_field(registry, f)
        else:
            out[f.name] = _field_from_wire(registry, f, v, f"{path}.{f.name}")
    return out


def _field_from_wire(registry: TypeRegistry, f: Field, value: Any, path: str) -> Any:
    if f.is_binary:
        data = _binary(value, path)
        if f.length is not None and len(data) != f.length:
            raise MessageError(f"{path}: expected {f.length} bytes, got {len(data)}")
        return data
    if f.is_array:
        if not isinstance(value, list):
            raise MessageError(f"{path}: expected an array of {f.type}, got {_type_label(value)}")
        if f.length is not None and len(value) != f.length:
            raise MessageError(f"{path}: expected {f.length} elements, got {len(value)}")
        return [_scalar(registry, f.type, v, f"{path}[{i}]") for i, v in enumerate(value)]
    return _scalar(registry, f.type, value, path)


def _scalar(registry: TypeRegistry, typ: str, value: Any, path: str) -> Any:
    if typ in FLOATS:
        if value is None:
            raise MessageError(f"{path}: null is not a number ({typ}; NaN/inf are not accepted)")
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise MessageError(f"{path}: expected a number ({typ}), got {_type_label(value)}")
        try:
            value = float(value)
        except OverflowError:  # JSON integers have no bound; a float does
            digits = len(str(abs(value)))
            raise MessageError(
                f"{path}: an integer of {digits} digits is too large for {typ}"
            ) from None
        if not math.isfinite(value):
            raise MessageError(f"{path}: NaN and infinity are not accepted")
        return value
    if typ in INT_RANGES:
        if isinstance(value, bool) or not isinstance(value, int):
            raise MessageError(f"{path}: expected an integer ({typ}), got {_type_label(value)}")
        lo, hi = INT_RANGES[typ]
        if not lo <= value <= hi:
            raise MessageError(f"{path}: {value} is out of range for {typ} [{lo}, {hi}]")
        return value
    if typ == "bool":
        if isinstance(value, bool):
            return value
        if isinstance(value, int) and value in (0, 1):
            return bool(value)
        raise MessageError(f"{path}: expected true or false, got {_type_label(value)}")
    if typ == "string":
        if not isinstance(value, str):
            raise MessageError(f"{path}: expected a string, got {_type_label(value)}")
        return value
    if typ in ("time", "duration"):
        return _time(registry, value, path, signed=typ == "duration")
    return from_wire(registry, registry.message(typ), value, path)


def _time(registry: TypeRegistry, value: Any, path: str, signed: bool) -> dict:
    d = registry.dialect
    if value == "now":  # rosbridge accepts "now" for a time
        return d.stamp(time.time())
    if not isinstance(value, dict):
        raise MessageError(f"{path}: expected a time object, got {_type_label(value)}")
    keys = set(value)
    if keys <= {"sec", "nanosec"}:
        sec, nsec = value.get("sec", 0), value.get("nanosec", 0)
    elif keys <= {"secs", "nsecs"}:
        sec, nsec = value.get("secs", 0), value.get("nsecs", 0)
    else:
        raise MessageError(
            f"{path}: a time has fields sec/nanosec (ROS 2) or secs/nsecs (ROS 1), "
            f"got {sorted(keys)}"
        )
    for v, what in ((sec, "seconds"), (nsec, "nanoseconds")):
        if isinstance(v, bool) or not isinstance(v, int):
            raise MessageError(f"{path}: {what} must be an integer, got {_type_label(v)}")
    if (not signed and sec < 0) or not (-(2**31) <= sec < 2**32) or not 0 <= nsec < 2**32:
        raise MessageError(f"{path}: time out of range ({sec}, {nsec})")
    return {d.sec_key: sec, d.nsec_key: nsec}


def _binary(value: Any, path: str) -> bytes:
    if isinstance(value, str):
        try:
            return base64.b64decode(value, validate=True)
        except (binascii.Error, ValueError) as e:
            raise MessageError(f"{path}: not a valid base64 string ({e})") from None
    if isinstance(value, bytes | bytearray):
        return bytes(value)
    if isinstance(value, list):
        if not all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v < 256 for v in value):
            raise MessageError(f"{path}: a byte array must hold integers in [0, 255]")
        return bytes(value)
    raise MessageError(f"{path}: expected base64 text or a list of bytes, got {_type_label(value)}")


# --------------------------------------------------------------------------- defaults
def default_message(registry: TypeRegistry, spec: MsgSpec) -> dict:
    """A ``spec`` message with every field at its default."""
    return {f.name: default_field(registry, f) for f in spec.fields}


def default_field(registry: TypeRegistry, f: Field) -> Any:
    if f.is_binary:
        return bytes(f.length or 0)
    if f.is_array:
        if f.length is None:
            return []
        return [_default_scalar(registry, f) for _ in range(f.length)]
    return _default_scalar(registry, f)


def _default_scalar(registry: TypeRegistry, f: Field) -> Any:
    t = f.type
    if t in FLOATS:
        return float(f.default) if f.default is not None else 0.0
    if t in INT_RANGES:
        return int(f.default) if f.default is not None else 0
    if t == "bool":
        return f.default is not None and f.default.lower() in ("true", "1")
    if t == "string":
        return f.default.strip("\"'") if f.default is not None else ""
    if t in ("time", "duration"):
        return registry.dialect.stamp(0.0)
    return default_message(registry, registry.message(t))


# --------------------------------------------------------------------------- CBOR
# RFC 8746 typed-array tags, little endian (rosbridge.md §1.6).
_TYPED_ARRAY_TAGS = {
    "float64": (86, "d"),
    "float32": (85, "f"),
    "int8": (72, "b"),
    "int16": (77, "h"),
    "uint16": (69, "H"),
    "int32": (78, "i"),
    "uint32": (70, "I"),
    "int64": (79, "q"),
    "uint64": (71, "Q"),
}


def to_cbor_value(registry: TypeRegistry, spec: MsgSpec, msg: dict) -> dict:
    """``msg`` with numeric arrays as typed-array tags (binary fields stay byte strings)."""
    import cbor2

    out = {}
    for f in spec.fields:
        v = msg.get(f.name)
        if v is None:
            out[f.name] = v
        elif f.is_binary:
            out[f.name] = bytes(v) if not isinstance(v, str) else base64.b64decode(v)
        elif f.is_array and f.type in _TYPED_ARRAY_TAGS:
            tag, code = _TYPED_ARRAY_TAGS[f.type]
            packed = struct.pack(f"<{len(v)}{code}", *v)
            out[f.name] = cbor2.CBORTag(tag, packed)
        elif f.is_array and not f.is_builtin:
            sub = registry.message(f.type)
            out[f.name] = [to_cbor_value(registry, sub, x) for x in v]
        elif not f.is_builtin and isinstance(v, dict):
            out[f.name] = to_cbor_value(registry, registry.message(f.type), v)
        else:
            out[f.name] = v
    return out


# --------------------------------------------------------------------------- rosapi TypeDef
def typedefs(registry: TypeRegistry, spec: MsgSpec) -> list[dict]:
    """rosapi ``TypeDef`` list for ``spec`` and every message type it contains (rosbridge.md 2.2).

    ``fieldarraylen`` is -1 for a scalar, 0 for an unbounded array, N for a fixed array.
    """
    out: list[dict] = []
    seen: set[str] = set()

    def visit(s: MsgSpec) -> None:
        if s.name in seen:
            return
        seen.add(s.name)
        types, examples = [], []
        for f in s.fields:
            if f.is_builtin:
                types.append(f.type)
            else:
                types.append(registry.wire_name(f.type))
            if f.is_array:
                examples.append("[]")
            elif f.is_builtin and f.type not in ("time", "duration"):
                examples.append(str(_default_scalar(registry, f)))
            else:
                examples.append("{}")
        out.append(
            {
                "type": registry.wire_name(s.name) if "/" in s.name else s.name,
                "fieldnames": [f.name for f in s.fields],
                "fieldtypes": types,
                "fieldarraylen": [-1 if not f.is_array else (f.length or 0) for f in s.fields],
                "examples": examples,
                "constnames": [c.name for c in s.constants],
                "constvalues": [c.value for c in s.constants],
            }
        )
        for f in s.fields:
            if not f.is_builtin:
                visit(registry.message(f.type))

    visit(spec)
    return out
