"""Every numba kernel is compiled (or loaded from the cache) when its module is imported,
never at its first call: a first call in the simulation's 1 kHz loop stalls it for seconds
(half a minute on a busy machine with an empty cache) and nothing says why."""

import importlib
import os
import pkgutil
import subprocess
import sys

import davinci_sim
from davinci_sim.kinematics import jit


def test_every_kernel_is_compiled_at_import():
    for module in pkgutil.walk_packages(davinci_sim.__path__, "davinci_sim."):
        importlib.import_module(module.name)
    assert jit.KERNELS or not jit.ENABLED
    lazy = [k.__qualname__ for k in jit.KERNELS if not k.ready()]
    assert not lazy, f"kernels compiled at their first call, not at import: {lazy}"


#: In a process with ``DAVINCI_SIM_JIT=0``: the console's system homes and PSM1 reaches a
#: joint goal, the kernels Python calls running as Python.
_SWITCHED_OFF = """
import numpy as np
from davinci_sim.kinematics import jit, psm_closed_form
from davinci_sim.system import ConsoleDescription, SystemDescription, build_system

assert not jit.ENABLED
rows = psm_closed_form.closed_form_rows
assert rows is rows.py_func and rows.dispatcher is not rows
system = build_system(SystemDescription(scene="psm1_ecm_mtmr", keyframe="home", home=True,
                                        console=ConsoleDescription()), start=False)
sim = system.sim
psm = sim.arms["PSM1"]
for _ in range(20):
    if psm.operating_state().is_homed:
        break
    sim.step(500)
q0 = psm.measured_js().position.copy()
goal = q0 + np.array([0.05, -0.05, 0.0, 0.0, 0.0, 0.0])
psm.move_jp(goal)
sim.step(1500)
print(np.abs(psm.measured_js().position - goal).max())
"""


def test_with_the_switch_off_python_runs_the_laws_and_the_arms_move(tmp_path):
    """``DAVINCI_SIM_JIT=0`` (documented for comparing the compiled laws with their Python
    form) runs: the kernels Python calls are the Python functions, the compiled tick's own
    kernels still call them compiled, and an arm reaches a joint goal."""
    env = dict(os.environ, DAVINCI_SIM_JIT="0")
    out = subprocess.run([sys.executable, "-c", _SWITCHED_OFF], env=env, capture_output=True,
                         text=True, timeout=600, cwd=tmp_path)  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    assert float(out.stdout.split()[-1]) < 1e-3, out.stdout
