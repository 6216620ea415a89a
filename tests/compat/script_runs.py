"""Running ``davinci-sim run`` in a subprocess and reading what the scripts print."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

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


def check_psm_moves(v: dict[str, str]) -> None:
    """What ``psm_moves.py`` prints, on either transport: homed, each move waited for and
    reached (joint, relative, insertion, Cartesian there and back), the jaw opened and squeezed."""
    assert v["operating_state"] == "ENABLED" and v["is_homed"] == "True"
    assert v["busy_after_move_jp"] == "True"
    for name in ("move_jp_wait", "move_cp_wait", "jaw_open_wait", "jaw_close_wait"):
        assert v[name] == "True", name
    assert float(v["move_jp_error_deg"]) < 0.5 and float(v["move_jp_insertion_error_mm"]) < 0.5
    assert float(v["move_jr_yaw_deg"]) == pytest.approx(5.0, abs=0.5)
    assert float(v["insert_jp_mm"]) == pytest.approx(130.0, abs=0.5)
    assert float(v["move_cp_error_mm"]) < 1.0 and float(v["move_cp_back_error_mm"]) < 1.0
    assert float(v["move_cp_rotation_error_deg"]) < 1.0
    assert float(v["jaw_open_deg"]) == pytest.approx(50.0, abs=1.5)
    assert float(v["jaw_closed_deg"]) < 0.0  # squeezing, toward -20°
