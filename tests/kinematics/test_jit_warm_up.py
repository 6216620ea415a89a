"""Every numba kernel is compiled (or loaded from the cache) when its module is imported,
never at its first call: a first call in the simulation's 1 kHz loop stalls it for seconds
(half a minute on a busy machine with an empty cache) and nothing says why."""

import importlib
import pkgutil

import davinci_sim
from davinci_sim.kinematics import jit


def test_every_kernel_is_compiled_at_import():
    for module in pkgutil.walk_packages(davinci_sim.__path__, "davinci_sim."):
        importlib.import_module(module.name)
    assert jit.KERNELS or not jit.ENABLED
    lazy = [k.__qualname__ for k in jit.KERNELS if not k.ready()]
    assert not lazy, f"kernels compiled at their first call, not at import: {lazy}"
