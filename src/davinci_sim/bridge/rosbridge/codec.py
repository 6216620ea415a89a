"""Wire encodings: JSON text out and in, fragments, PNG and CBOR frames (rosbridge.md §1.6, §6).

Outgoing JSON is compact and ASCII-escaped (ROS# decodes frames as ASCII), ``bytes`` become
base64 text, numpy values become lists/numbers, and NaN/±inf become ``null``: they never go out
as the invalid JSON tokens ``NaN``/``Infinity`` (rosbridge.md §3, §5).

Incoming JSON must be strict: ``NaN``, ``Infinity`` and numbers that overflow to infinity are
refused with a clear error. Several objects concatenated in one frame are accepted, as
rosbridge does (rosbridge.md §1.1).
"""

from __future__ import annotations

import base64
import io
import json
import math
from typing import Any

import numpy as np


class DecodeError(ValueError):
    """An incoming frame that is not valid JSON of rosbridge ops."""


def _default(o: Any) -> Any:
    if isinstance(o, bytes | bytearray | memoryview):
        return base64.b64encode(bytes(o)).decode("ascii")
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, tuple | set | frozenset):
        return list(o)
    raise TypeError(f"cannot encode {type(o).__name__} as JSON")


_ENCODER = json.JSONEncoder(allow_nan=False, separators=(",", ":"), default=_default)


def finite_json(o: Any) -> Any:
    """A copy of ``o`` with non-finite floats replaced by None (JSON has no NaN; the
    encoder's slow path, rarely taken)."""
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, dict):
        return {k: finite_json(v) for k, v in o.items()}
    if isinstance(o, list | tuple):
        return [finite_json(v) for v in o]
    if isinstance(o, np.ndarray):
        return finite_json(o.tolist())
    if isinstance(o, np.floating):
        return finite_json(float(o))
    return o


def dumps(obj: Any) -> str:
    """Compact ASCII JSON; NaN and ±inf become ``null``."""
    try:
        return _ENCODER.encode(obj)
    except ValueError:  # a non-finite float somewhere: take the slow path
        return _ENCODER.encode(finite_json(obj))


# --------------------------------------------------------------------------- incoming
def _reject_constant(name: str) -> float:
    raise DecodeError(f"{name} is not valid JSON (NaN and infinity are not accepted)")


def _finite_float(text: str) -> float:
    v = float(text)
    if not math.isfinite(v):
        raise DecodeError(f"number {text} overflows to infinity")
    return v


_DECODER = json.JSONDecoder(parse_constant=_reject_constant, parse_float=_finite_float)


def loads_frames(data: str | bytes) -> list[Any]:
    """The JSON values of one frame (usually one; several if concatenated).

    Raises:
        DecodeError: for binary that is not UTF-8, malformed JSON, NaN/inf, or an empty frame.
    """
    if isinstance(data, bytes | bytearray | memoryview):
        try:
            text = bytes(data).decode("utf-8")
        except UnicodeDecodeError as e:
            raise DecodeError(f"binary frame is not UTF-8 JSON: {e}") from None
    else:
        text = data
    values = []
    i, n = 0, len(text)
    try:
        while True:
            while i < n and text[i] in " \t\r\n":
                i += 1
            if i >= n:
                break
            value, i = _DECODER.raw_decode(text, i)
            values.append(value)
    except json.JSONDecodeError as e:
        raise DecodeError(f"malformed JSON: {e.msg} at line {e.lineno} column {e.colno}") from None
    except RecursionError:
        raise DecodeError("malformed JSON: nested too deeply") from None
    if not values:
        raise DecodeError("empty frame")
    return values


# --------------------------------------------------------------------------- fragments
def fragments(text: str, size: int, frag_id: str | int) -> list[dict]:
    """The ``fragment`` ops carrying ``text`` in pieces of ``size`` characters (spec §3.1.1)."""
    total = max(1, math.ceil(len(text) / size))
    return [
        {
            "op": "fragment",
            "id": frag_id,
            "data": text[k * size : (k + 1) * size],
            "num": k,
            "total": total,
        }
        for k in range(total)
    ]


# --------------------------------------------------------------------------- png
def png_op(text: str) -> str:
    """The ``png`` op: the JSON text as the RGB pixels of a PNG, padded with newlines
    (rosbridge.md §1.6)."""
    from PIL import Image

    raw = text.encode("utf-8")
    pixels = math.ceil(len(raw) / 3)
    width = max(1, math.ceil(math.sqrt(pixels)))
    height = max(1, math.ceil(pixels / width))
    raw = raw.ljust(width * height * 3, b"\n")
    buf = io.BytesIO()
    Image.frombytes("RGB", (width, height), raw).save(buf, format="PNG")
    return dumps({"op": "png", "data": base64.b64encode(buf.getvalue()).decode("ascii")})


def png_decode(op: dict) -> str:
    """The JSON text inside a ``png`` op (what roslibjs does; used by the tests)."""
    from PIL import Image

    img = Image.open(io.BytesIO(base64.b64decode(op["data"]))).convert("RGB")
    return img.tobytes().decode("utf-8").rstrip("\n")


# --------------------------------------------------------------------------- cbor
def cbor_frame(obj: Any) -> bytes:
    """A binary CBOR frame (bytes stay byte strings, NaN stays NaN: CBOR has it)."""
    import cbor2

    return cbor2.dumps(obj)
