"""Python values as JSON that comes back bit for bit: the arguments of recorded calls.

A recording keeps the calls a session's handle ran (``sim/inputs.py``) so that a replay can
run them again; their arguments are numbers, strings, lists, numpy arrays (a ``servo_cp``
goal, a hand velocity) and the simulator's frozen value types. :func:`encode` turns such a
value into JSON-able data and :func:`decode` turns it back:

* ``None``, bools, ints, strings, lists and dicts with string keys as themselves;
* finite floats as themselves (Python writes a float's shortest repr, which reads back to the
  same double), non-finite ones as ``{"__float__": "nan" | "inf" | "-inf"}``;
* tuples as ``{"__tuple__": [...]}``;
* numpy arrays and scalars as ``{"__ndarray__": [...], "dtype": "float64", "shape": [...]}``
  (non-finite elements as the strings ``"nan"``, ``"inf"``, ``"-inf"``);
* frozen dataclasses of ``davinci_sim`` as ``{"__dataclass__": "module:QualName",
  "fields": {...}}``, rebuilt only if the class is a dataclass of the ``davinci_sim``
  package (a recording names no other code to run).

Anything else raises :class:`TypeError` in :func:`encode`: a recording says it cannot keep
that call rather than keep something a replay would run differently.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
from typing import Any

import numpy as np

_FLOATS = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}


def _float_tag(x: float) -> str:
    return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")


def encode(value: Any) -> Any:
    """``value`` as JSON-able data that :func:`decode` reads back exactly (module docstring).

    Raises:
        TypeError: a value of another type.
    """
    if value is None or isinstance(value, bool | int | str):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else {"__float__": _float_tag(value)}
    if isinstance(value, np.ndarray | np.generic):
        a = np.asarray(value)
        if a.dtype.kind not in "biuf":
            raise TypeError(f"cannot record an array of dtype {a.dtype}")
        flat = a.ravel().tolist()
        if a.dtype.kind == "f":
            flat = [x if math.isfinite(x) else _float_tag(x) for x in flat]
        return {"__ndarray__": flat, "dtype": a.dtype.str, "shape": list(a.shape)}
    if isinstance(value, tuple):
        return {"__tuple__": [encode(v) for v in value]}
    if isinstance(value, list):
        return [encode(v) for v in value]
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            raise TypeError("cannot record a dict with non-string keys")
        if any(k.startswith("__") and k.endswith("__") for k in value):
            raise TypeError("cannot record a dict with a key of the form __name__")
        return {k: encode(v) for k, v in value.items()}
    cls = type(value)
    if dataclasses.is_dataclass(value) and cls.__module__.startswith("davinci_sim."):
        fields = {f.name: encode(getattr(value, f.name)) for f in dataclasses.fields(value)}
        return {"__dataclass__": f"{cls.__module__}:{cls.__qualname__}", "fields": fields}
    raise TypeError(f"cannot record a value of type {cls.__name__}")


def decode(data: Any) -> Any:
    """The value :func:`encode` wrote.

    Raises:
        ValueError: data :func:`encode` does not write (or a class outside ``davinci_sim``).
    """
    if isinstance(data, list):
        return [decode(v) for v in data]
    if not isinstance(data, dict):
        return data
    if "__float__" in data:
        return _FLOATS[data["__float__"]]
    if "__tuple__" in data:
        return tuple(decode(v) for v in data["__tuple__"])
    if "__ndarray__" in data:
        dtype = np.dtype(data["dtype"])
        flat = [_FLOATS[x] if isinstance(x, str) else x for x in data["__ndarray__"]]
        return np.array(flat, dtype=dtype).reshape(data["shape"])
    if "__dataclass__" in data:
        return _dataclass(data["__dataclass__"], {k: decode(v) for k, v in data["fields"].items()})
    return {k: decode(v) for k, v in data.items()}


def _dataclass(name: str, fields: dict) -> Any:
    module, _, qualname = name.partition(":")
    if not module.startswith("davinci_sim.") or not qualname:
        raise ValueError(f"a recorded value names {name!r}, not a class of davinci_sim")
    obj: Any = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    if not (isinstance(obj, type) and dataclasses.is_dataclass(obj)):
        raise ValueError(f"a recorded value names {name!r}, which is not a dataclass")
    return obj(**fields)


def plain(value: Any) -> Any:
    """``value`` as plain JSON for a viewer (lossy: arrays as lists, tuples as lists,
    non-finite floats as null, dataclasses as dicts, other objects as their ``repr``)."""
    if value is None or isinstance(value, bool | int | str):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, np.ndarray | np.generic):
        return plain(np.asarray(value).tolist())
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if hasattr(value, "_asdict"):
        return plain(value._asdict())
    return repr(value)
