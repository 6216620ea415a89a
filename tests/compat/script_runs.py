"""Running ``davinci-sim run`` in a subprocess and reading what the scripts print."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = ROOT / "examples" / "dvrk_scripts"


def run(args: list[str], *, env: dict | None = None, timeout: float = 180.0):
    """``davinci-sim run ARGS`` with this interpreter and the tree's ``src`` first."""
    env = dict(env or {})
    extra = env.pop("PYTHONPATH", "")
    environment = {**os.environ, **env}
    environment["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT / "src"), extra) if p)
    command = [sys.executable, "-m", "davinci_sim.cli", "run", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=timeout, env=environment)


def values(stdout: str) -> dict[str, str]:
    """The ``name: value`` lines a script printed."""
    out = {}
    for line in stdout.splitlines():
        name, sep, value = line.partition(": ")
        if sep and " " not in name:
            out[name] = value.strip()
    return out


def check(result) -> dict[str, str]:
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout.splitlines()[-1] == "done", result.stdout + result.stderr
    return values(result.stdout)
