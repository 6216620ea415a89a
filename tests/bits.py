"""One check the oracle tests share: two results hold the same bits."""

from __future__ import annotations

import dataclasses

import numpy as np


def assert_same_bits(a, b, where: str = "") -> None:
    """``a`` and ``b`` hold the same bits: arrays and floats of the same dtype and shape with
    equal values (NaN where the other has NaN, zeros of the same sign), recursing through
    dicts, sequences, dataclasses (samples, states) and metric values (``.metrics`` and
    ``[name]``); anything else equal. ``where`` names the part in the message."""
    if isinstance(a, np.ndarray | float | np.floating) or isinstance(b, np.ndarray):
        x, y = np.asarray(a), np.asarray(b)
        assert x.dtype == y.dtype and x.shape == y.shape, (where, x, y)
        assert np.array_equal(x, y, equal_nan=x.dtype.kind in "fc"), (where, x, y)
        if x.dtype.kind == "f":
            assert np.array_equal(np.signbit(x), np.signbit(y)), (where, x, y)
    elif isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), (where, a, b)
        for k in a:
            assert_same_bits(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, tuple | list):
        assert type(a) is type(b) and len(a) == len(b), (where, a, b)
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same_bits(x, y, f"{where}[{i}]")
    elif dataclasses.is_dataclass(a) and not isinstance(a, type):
        assert type(a) is type(b), (where, a, b)
        for f in dataclasses.fields(a):
            assert_same_bits(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif hasattr(a, "metrics") and hasattr(a, "__getitem__"):  # (MetricValues)
        assert type(a) is type(b) and a.metrics == b.metrics, where
        for m in a.metrics:
            assert_same_bits(a[m.name], b[m.name], f"{where}.{m.name}")
    else:
        assert a == b or (a != a and b != b), (where, a, b)
