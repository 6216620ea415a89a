"""Leaner compiled calls: the reference counting of a compiled function's array arguments,
which numba does not prune, removed from the machine code of this package's kernels.

numba counts references to every array: a function increments the count of each array
argument on entry and decrements it on each way out. Its own pruning pass
(``NUMBA_LLVM_REFPRUNE_PASS``) removes a pair when both ends sit in one block or around a
simple branch, not when a loop or a second exit lies between them, which is the shape of
every row law here (a loop over joints, an early return on a refusal). Each count is an
atomic read-modify-write, and the kernels pass tens of arrays per call, a few calls per
tick: measured on the console's compiled tick (``make run``'s set-up, 2-core machine) 17 %
of the process's samples were these two functions, and the single environment's period 8 %.

The pair is redundant for an argument: the caller holds its own reference for the whole
call, so the array cannot be freed in between, and the count is back where it was on every
normal exit. It matters only where the function lets the array escape: stores it (a list,
a tuple in memory, its return slot), returns it or merges it with another value. So
:func:`prune_argument_refcounts` removes every increment and decrement of an argument's
reference only where the argument is used by nothing else than those and as an argument
of calls to other compiled functions (``_ZN``-mangled, which borrow it the same way):
any other use (``store``, ``insertvalue``, a comparison, a call to a C helper) keeps that
argument's counting as numba made it. A pointer chosen among arguments (a ``phi`` or
``select`` whose values are arguments, null or such choices) is always one of them and is
treated with them, as one group. On a raising exit numba leaves the increment unmatched
(the reference leaks with the exception); without it, nothing leaks there either.

:func:`install` applies it to every library numba finalises from then on (after numba's
own optimisation, before the machine code is made and cached); :mod:`davinci_sim.kinematics.jit`
installs it when numba compiles, unless ``DAVINCI_SIM_REFPRUNE=0``. The arithmetic is
untouched: the compiled ticks give the Python ticks' bits with it as before
(``tests/console/test_chunk.py`` and the other oracles), and their allocations and frees
balance (``tests/kinematics/test_jit_refcounts.py``, ``test_chunk.py``). Kernels cached by
numba before it was installed keep their counting until their module changes.
"""

from __future__ import annotations

import re
import warnings
from collections import defaultdict

_REFOP = re.compile(
    r"^\s*(?:tail |notail |musttail )?call void @NRT_(?:incref|decref)"
    r'\(ptr(?: \w+)* (%"[^"]*"|%[-\w.$]+)\)\s*(?:,\s*!.*)?$'
)
"""One increment or decrement of a reference count: group 1 is the value counted."""

_VALUE = re.compile(r'%"[^"]*"|%[-\w.$]+')
"""A local value's name in LLVM's text (``%name`` or ``%"quoted name"``)."""

_BORROWING_CALL = re.compile(
    r'^\s*(?:%"[^"]*" = |%[-\w.$]+ = )?(?:tail |notail |musttail )?call [^@(]*@"?_ZN'
)
"""A direct call to a numba-compiled function: its arguments are borrowed for the call
(an indirect call, ``call ty %f(...)``, is not one)."""


_PHI = re.compile(r'^\s*(%"[^"]*"|%[-\w.$]+) = phi ptr (.*)$')
_PHI_INCOMING = re.compile(r'\[ (%"[^"]*"|%[-\w.$]+|null), %[^\]]+ \]')
_SELECT = re.compile(
    r'^\s*(%"[^"]*"|%[-\w.$]+) = select i1 [^,]+, ptr (%"[^"]*"|%[-\w.$]+|null), '
    r'ptr (%"[^"]*"|%[-\w.$]+|null)\s*(?:,\s*!.*)?$'
)
"""A pointer chosen among others (``phi``, ``select``): group 1 is the value defined."""


def _is_argument(name: str) -> bool:
    """Whether ``name`` is one of numba's argument values (``%arg.<name>.<field>``)."""
    return name.startswith(("%arg.", '%"arg.'))


def _choices(body: list[str]) -> dict[str, tuple[int, list[str]]]:
    """The pointers of a function chosen among others (``phi``, ``select``): their line
    and the values they choose among."""
    chosen = {}
    for k in range(1, len(body)):
        line = body[k]
        if " = phi ptr " in line:
            m = _PHI.match(line)
            if m is not None:
                chosen[m.group(1)] = (k, _PHI_INCOMING.findall(m.group(2)))
        elif " = select i1 " in line:
            m = _SELECT.match(line)
            if m is not None:
                chosen[m.group(1)] = (k, [m.group(2), m.group(3)])
    return chosen


def _borrowed(arguments: set[str], chosen: dict[str, tuple[int, list[str]]]) -> set[str]:
    """The arguments and the pointers that are always one of them (or null): the largest
    set of choices among arguments, nulls and such choices (a loop's ``phi`` may choose
    itself)."""
    borrowed = arguments | set(chosen)
    changed = True
    while changed:
        changed = False
        for name, (_, values) in chosen.items():
            if name in borrowed and not all(v in borrowed or v == "null" for v in values):
                borrowed.discard(name)
                changed = True
    return borrowed


def _prune_function(body: list[str]) -> set[int]:
    """The lines of one function's text (``define ...`` to ``}``) whose reference counting
    of an argument may go (see the module docstring). A pointer that is always one of the
    arguments (a ``phi`` or ``select`` among them) is counted with them: the arguments it
    may be and it go together, or stay together where one of them escapes."""
    arguments = {v for v in _VALUE.findall(body[0]) if _is_argument(v)}
    if not arguments:
        return set()
    chosen = _choices(body)
    borrowed = _borrowed(arguments, chosen)
    group = {name: name for name in borrowed}  # (union-find over a choice and its values)

    def root(name: str) -> str:
        while group[name] != name:
            group[name] = group[group[name]]
            name = group[name]
        return name

    for name, (_, values) in chosen.items():
        if name in borrowed:
            for v in values:
                if v != "null":
                    group[root(v)] = root(name)
    choice_lines = {k for name, (k, _) in chosen.items() if name in borrowed}
    counted: dict[str, list[int]] = defaultdict(list)
    escapes: set[str] = set()
    for k in range(1, len(body)):
        line = body[k]
        op = _REFOP.match(line) if "@NRT_" in line else None
        if op is not None:
            if op.group(1) in borrowed:
                counted[op.group(1)].append(k)
            continue
        if k in choice_lines:
            continue
        used = {v for v in _VALUE.findall(line) if v in borrowed}
        if used and not _BORROWING_CALL.match(line):
            escapes |= {root(v) for v in used}
    return {k for name, lines in counted.items() if root(name) not in escapes for k in lines}


SCOPE: tuple[str, ...] = ("davinci_sim",)
"""The top-level packages whose compiled functions :func:`install` prunes (numba compiles
everyone's code in a process: a user's own numba code keeps numba's counting)."""


def _in_scope(header: str, scope: tuple[str, ...]) -> bool:
    """Whether a function's ``define`` line names a function of one of the packages
    ``scope`` (numba's mangled names start with the module path: ``_ZN11davinci_sim``)."""
    return any(f"_ZN{len(p)}{p}" in header or f"_ZN7cpython{len(p)}{p}" in header
               for p in scope)  # fmt: skip


def prune_argument_refcounts(ir: str, scope: tuple[str, ...] | None = None) -> tuple[str, int]:
    """``ir`` (an LLVM module's text) with the redundant reference counting of its
    functions' arguments removed (of every function, or of the functions of the packages
    ``scope``), and how many calls were removed."""
    lines = ir.split("\n")
    kept: list[str] = []
    removed = 0
    i = 0
    while i < len(lines):
        if not lines[i].startswith("define "):
            kept.append(lines[i])
            i += 1
            continue
        end = i
        while end < len(lines) and lines[end] != "}":
            end += 1
        body = lines[i : end + 1]
        drop = _prune_function(body) if scope is None or _in_scope(body[0], scope) else set()
        removed += len(drop)
        kept.extend(line for k, line in enumerate(body) if k not in drop)
        i = end + 1
    return "\n".join(kept), removed


def install() -> bool:
    """Prune the functions of :data:`SCOPE` in every library numba finalises from now on
    (idempotent). Returns whether it is installed: False where this numba has no such step
    (then numba's code stays as it is)."""
    try:
        import llvmlite.binding as ll
        from numba.core import codegen

        library = codegen.CPUCodeLibrary
        optimise = library._optimize_final_module
    except (ImportError, AttributeError):  # pragma: no cover - depends on numba's version
        return False
    if getattr(optimise, "prunes_argument_refcounts", False):
        return True

    def _optimize_final_module(self) -> None:
        optimise(self)
        try:
            text, removed = prune_argument_refcounts(str(self._final_module), SCOPE)
            if removed:
                module = ll.parse_assembly(text)
                module.verify()
                module.name = self._final_module.name
                self._final_module = module
        except Exception as e:  # pragma: no cover - numba's code stays as it made it
            warnings.warn(f"reference counts not pruned in {self.name}: {e}", RuntimeWarning,
                          stacklevel=1)  # fmt: skip

    _optimize_final_module.prunes_argument_refcounts = True  # type: ignore[attr-defined]
    library._optimize_final_module = _optimize_final_module
    return True
