"""Compile every numba kernel into numba's on-disk cache, on every core:
``python -m davinci_sim.warm_up [PROCESSES]``.

Each module that has kernels warms them up at import (``kinematics.jit.warm``), one after
the other: on a clean checkout, importing the study and the environments compiles for
about 100 s on one core. This runs the same warm-ups in ``PROCESSES`` processes (default:
the machine's cores). Each imports the kernel modules with the warm-ups deferred
(``DAVINCI_SIM_DEFER_WARM_UP``: collected, not run, in the same order in every process),
then takes the next one not yet taken, until none is left: the last imported first, so
that the kernels that compose the others (the study's chunk, the longest) start at once. A
warm-up whose callees another process compiled already loads them from the cache; a few
are compiled twice. On the 2-core machine: 58 s instead of 106 s on a clean checkout when
this was written; 108 s on 2026-12-03, the compiled engine's kernels since added (the
console's chunk, ~90 s of one process, sets it; the other process's work is about as long).
Afterwards every import loads its kernels from the cache: the test workers, servers and
studies start in seconds.
"""

from __future__ import annotations

import importlib
import multiprocessing
import os
import sys

#: The modules whose import compiles every kernel (each warms its own up at import).
KERNEL_MODULES = (
    "davinci_sim.sim.simulation",
    "davinci_sim.console",
    "davinci_sim.study.batch",
    "davinci_sim.envs.vector",
    "davinci_sim.tasks.handling",  # (the exercises that hand objects over)
    "davinci_sim.tasks.needle_row",  # (the needle exercises' steps)
)


def _console_chunk() -> None:
    """The console's compiled ticks (``console/chunk_kernel.py``, about a minute to compile):
    a console's install compiles them (``ConsoleChunk._warm``), so install one."""
    from davinci_sim.system import ConsoleDescription, SystemDescription, build_simulation

    console = ConsoleDescription(hand_inputs=("MTML", "MTMR"))
    build_simulation(SystemDescription("full", console=console, runner="none"))


#: Warm-ups of kernels no module compiles at import, run after the modules' (taken first:
#: the console's is the longest).
EXTRA_WARM_UPS = (_console_chunk,)

_DEFER = "DAVINCI_SIM_DEFER_WARM_UP"


def _worker(modules, extra, counter, lock, compiled) -> None:
    """One process: import ``modules`` (warm-ups deferred), then run their warm-ups and
    ``extra``, last first, whose turn it takes from ``counter`` (shared by the
    processes); adds to ``compiled`` the signatures it compiled (not loaded)."""
    for name in modules:
        importlib.import_module(name)
    from davinci_sim.kinematics import jit

    if not jit.DEFERRED:  # (run as the parent wanted: the warm-ups ran at import)
        return
    jit.WARM_UPS.extend(extra)
    while True:
        with lock:
            index = counter.value
            counter.value += 1
        if index >= len(jit.WARM_UPS):
            break
        try:
            jit.WARM_UPS[-1 - index]()
        except Exception:  # (the module's own import warns of it and takes its Python path)
            continue
    import gc

    from numba.core.dispatcher import Dispatcher

    misses = sum(sum(d.stats.cache_misses.values()) for d in gc.get_objects()
                 if isinstance(d, Dispatcher))  # fmt: skip
    with lock:
        compiled.value += misses


def warm_up(
    processes: int | None = None,
    modules: tuple[str, ...] = KERNEL_MODULES,
    extra: tuple = EXTRA_WARM_UPS,
) -> None:
    """Compile (or find cached) every kernel that importing ``modules`` warms up, and those
    the ``extra`` warm-ups compile, in ``processes`` processes (default:
    ``os.cpu_count()``); returns when all are in the cache.

    Raises:
        ValueError: if ``processes`` < 1.
        RuntimeError: if a process failed (its traceback is on stderr).
    """
    n = (os.cpu_count() or 1) if processes is None else processes
    if n < 1:
        raise ValueError(f"processes must be >= 1, got {processes!r}")
    context = multiprocessing.get_context("spawn")  # (fresh interpreters: nothing compiled)
    codes, compiled = _run(context, n, modules, extra)
    failed = [code for code in codes if code != 0]
    if failed:
        raise RuntimeError(f"warming the kernels up failed in {len(failed)} of {n} processes")
    # Where they compiled, every warm-up once more in one process: each loads its kernels
    # from the cache, and compiles again those whose entry another process dropped (a
    # kernel's cache index is rewritten whole by each process that saves one of its
    # signatures: two saving at once can each drop the other's; a second warm-up on the
    # 2-core machine compiled six signatures again, and `make test`'s pytest controller
    # eleven, 8 s before its workers could start). Processes that only loaded saved nothing.
    if n > 1 and compiled and _run(context, 1, modules, extra)[0] != [0]:
        raise RuntimeError("checking the kernels' cache after the warm-up failed")


def _run(context, n: int, modules, extra) -> tuple[list[int], int]:
    """``n`` processes of :func:`_worker` sharing one counter, their warm-ups deferred;
    their exit codes once all have finished, and the signatures they compiled."""
    counter, lock = context.Value("i", 0, lock=False), context.Lock()
    compiled = context.Value("i", 0, lock=False)
    before = os.environ.get(_DEFER)
    os.environ[_DEFER] = "1"  # (the children's environment, copied at their start)
    try:
        workers = [
            context.Process(target=_worker, args=(modules, extra, counter, lock, compiled))
            for _ in range(n)
        ]
        for w in workers:
            w.start()
    finally:
        if before is None:
            os.environ.pop(_DEFER, None)
        else:
            os.environ[_DEFER] = before
    for w in workers:
        w.join()
    return [w.exitcode for w in workers], compiled.value


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    try:
        if args and not args[0].lstrip("-").isdigit():
            raise ValueError(f"the number of processes must be a whole number, got {args[0]!r}")
        warm_up(int(args[0]) if args else None)
    except (ValueError, RuntimeError) as e:
        print(f"davinci_sim.warm_up: {e}", file=sys.stderr)
        return 2 if isinstance(e, ValueError) else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
