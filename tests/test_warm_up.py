"""``python -m davinci_sim.warm_up``: every kernel compiled into numba's cache on all cores,
so that a process started afterwards compiles nothing."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from davinci_sim.kinematics import jit
from davinci_sim.warm_up import main, warm_up

pytestmark = pytest.mark.skipif(not jit.ENABLED, reason="numba is off: nothing compiles")

#: Run in a new interpreter: import the modules given, then print how many of the project's
#: compiled functions compiled a signature (cache misses) and how many loaded one.
_COUNT = """
import gc, importlib, sys
from numba.core.dispatcher import Dispatcher
for name in sys.argv[1:]:
    importlib.import_module(name)
ours = [d for d in gc.get_objects() if isinstance(d, Dispatcher)
        and d.py_func.__module__.startswith("davinci_sim.")]
print(sum(sum(d.stats.cache_misses.values()) for d in ours),
      sum(sum(d.stats.cache_hits.values()) for d in ours))
"""

#: A module with kernels of its own that compiles in seconds.
SMALL = ("davinci_sim.kinematics.fk_compiled",)


def _python(code: str, *args: str, **env) -> str:
    out = subprocess.run(
        [sys.executable, "-c", code, *args], env={**os.environ, **env}, capture_output=True,
        text=True, check=True, timeout=600,
    )  # fmt: skip
    return out.stdout


def test_after_the_warm_up_a_new_process_loads_every_kernel_and_compiles_none(
    tmp_path, monkeypatch
):
    """In an empty cache (``NUMBA_CACHE_DIR``), a module's import compiles its kernels;
    after the warm-up of that module, a new process loads them all and compiles none."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cold"))
    misses, hits = map(int, _python(_COUNT, *SMALL).split())
    assert misses >= 1 and hits == 0
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "warmed"))
    warm_up(2, SMALL, extra=())
    misses, hits = map(int, _python(_COUNT, *SMALL).split())
    assert misses == 0 and hits >= 1


def test_deferred_warm_ups_are_collected_not_run():
    """What the warm-up's processes see: the modules' warm-ups listed, none compiled."""
    code = (
        "from davinci_sim.kinematics import jit, fk_compiled as f\n"
        "print(len(jit.WARM_UPS), f.tip_poses.ready())"
    )
    collected, ready = _python(code, DAVINCI_SIM_DEFER_WARM_UP="1").split()
    assert int(collected) >= 1 and ready == "False"
    assert _python(code).split() == ["0", "True"]  # (a normal import warms them up)


@pytest.mark.parametrize("argv", [["0"], ["-1"], ["two"]])
def test_a_bad_process_count_is_refused_in_one_line(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("davinci_sim.warm_up: ") and err.count("\n") == 1


def test_every_module_warms_its_kernels_up_through_jit():
    """A module that called its ``_warm_up()`` itself at import would compile it in every
    warm-up process (and before the others start): each goes through ``jit.warm`` or
    ``jit.warmed_up``, which the warm-up processes defer."""
    import pathlib

    import davinci_sim

    root = pathlib.Path(davinci_sim.__file__).parent
    direct = [
        f"{path.relative_to(root)}:{n}"
        for path in sorted(root.rglob("*.py"))
        for n, line in enumerate(path.read_text().splitlines(), 1)
        if line.strip() == "_warm_up()" and not line.startswith(" ")
    ]
    assert not direct, f"call jit.warm(_warm_up) instead: {direct}"


#: In a new interpreter, warm-ups deferred (nothing compiles): the warm-ups that importing
#: every module of the package collects and importing the warm-up's modules does not.
_WARM_UPS = """
import importlib, pkgutil
import davinci_sim
from davinci_sim.kinematics import jit
from davinci_sim.warm_up import KERNEL_MODULES
for name in KERNEL_MODULES:
    importlib.import_module(name)
before = {f"{w.__module__}.{w.__qualname__}" for w in jit.WARM_UPS}
for module in pkgutil.walk_packages(davinci_sim.__path__, "davinci_sim."):
    importlib.import_module(module.name)
print(sorted({f"{w.__module__}.{w.__qualname__}" for w in jit.WARM_UPS} - before))
"""


def test_the_warm_up_imports_every_module_that_has_kernels():
    """A module outside the warm-up's imports compiles in each process that imports it
    (``tasks.handling``'s kernel compiled in both of `make test`'s workers)."""
    assert _python(_WARM_UPS, DAVINCI_SIM_DEFER_WARM_UP="1").strip() == "[]"
