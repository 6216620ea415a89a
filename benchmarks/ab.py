"""Two versions of the code timed at the same time, each alone on a core, then the cores
swapped: an A/B that the VM's hour-to-hour speed cannot blur.

The development VM's speed changes by 30 % and more between runs a minute apart, so a change
worth a few per cent cannot be seen by timing the old code, then the new. Run at the same
time, one process per core, both versions see the same machine; swapping the cores takes out
a difference between the cores::

    python benchmarks/ab.py BASE [--rounds N] -- COMMAND [ARG ...]

``BASE``: a commit; a worktree of it is made in a temporary folder (removed afterwards).
``COMMAND`` runs in that tree and in this one (the working directory, ``PYTHONPATH`` the
tree's ``src``), first once in each to compile the numba kernels into that tree's cache, then
``N`` rounds of two concurrent runs (cores swapped in the second). Each run's last line of
output is printed: make ``COMMAND`` print its figure last (a benchmark that writes
``results/*.json`` writes it in the tree it runs in). Needs two cores.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _environment(tree: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(tree / "src"), "MUJOCO_GL": "egl"}


def _start(tree: Path, command: list[str], core: int | None) -> subprocess.Popen:
    pin = None if core is None else (lambda: os.sched_setaffinity(0, {core}))
    return subprocess.Popen(command, cwd=tree, env=_environment(tree), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, preexec_fn=pin)  # fmt: skip


def _last_line(process: subprocess.Popen) -> str:
    out, _ = process.communicate()
    lines = [line for line in out.splitlines() if line.strip()]
    if process.returncode != 0:
        tail = "\n".join(lines[-20:])
        raise SystemExit(f"the command failed (exit {process.returncode}):\n{tail}")
    return lines[-1] if lines else ""


def _check_source(tree: Path) -> None:
    """The tree's own package is the one imported (not the virtual environment's install)."""
    probe = [sys.executable, "-c", "import davinci_sim; print(davinci_sim.__file__)"]
    found = Path(_last_line(_start(tree, probe, None))).resolve()
    if not found.is_relative_to((tree / "src").resolve()):
        raise SystemExit(f"{tree}: imports davinci_sim from {found}, not from its src")


def main(argv: list[str] | None = None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    if "--" not in argv:
        raise SystemExit("usage: ab.py BASE [--rounds N] -- COMMAND [ARG ...]")
    split = argv.index("--")
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("base", help="the commit to compare this tree with")
    parser.add_argument("--rounds", type=int, default=1, help="pairs of concurrent runs")
    args = parser.parse_args(argv[:split])
    command = argv[split + 1 :]
    if not command:
        raise SystemExit("no command after --")
    if args.rounds < 1:
        raise SystemExit(f"--rounds must be at least 1, got {args.rounds}")
    cores = sorted(os.sched_getaffinity(0))
    if len(cores) < 2:
        raise SystemExit(f"needs two cores, this process may use {len(cores)}")
    if command[0] == "python":
        command = [sys.executable, *command[1:]]
    with tempfile.TemporaryDirectory(prefix="davinci-ab-") as folder:
        base = Path(folder) / "base"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "--quiet",
                        str(base), args.base], check=True)  # fmt: skip
        try:
            trees = {"base": base, "this": ROOT}
            for name, tree in trees.items():
                _check_source(tree)
                print(f"{name}: a first run (numba's kernels into this tree's cache) ...",
                      flush=True)  # fmt: skip
                _last_line(_start(tree, command, None))
            for r in range(args.rounds):
                for a, b in ((cores[0], cores[1]), (cores[1], cores[0])):
                    runs = {"base": _start(base, command, a), "this": _start(ROOT, command, b)}
                    lines = {name: _last_line(p) for name, p in runs.items()}
                    print(f"round {r + 1}  base (core {a}): {lines['base']}")
                    print(f"round {r + 1}  this (core {b}): {lines['this']}", flush=True)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base)],
                           check=False)  # fmt: skip


if __name__ == "__main__":
    main()
