"""Every benchmark module imports (``make bench`` is not run by the tests; an API it uses that
moved must fail here, not on the day someone measures)."""

from __future__ import annotations

import importlib
import pathlib
import sys

import pytest

BENCHMARKS = pathlib.Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.mark.parametrize("path", sorted(BENCHMARKS.glob("bench_*.py")), ids=lambda p: p.stem)
def test_benchmark_imports(path, monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    module = importlib.import_module(path.stem)
    try:
        assert callable(module.main), f"{path.name} has no main()"
    finally:
        sys.modules.pop(path.stem, None)


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["HEAD"], "usage"),
        (["HEAD", "--"], "no command"),
        (["HEAD", "--rounds", "0", "--", "true"], "at least 1"),
    ],
)
def test_the_ab_tool_refuses_a_call_it_cannot_run(argv, said, monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    ab = importlib.import_module("ab")
    try:
        with pytest.raises(SystemExit, match=said):
            ab.main(argv)
    finally:
        sys.modules.pop("ab", None)
