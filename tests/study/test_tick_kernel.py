"""The study tick's kernels read their argument tuples by the names the tuples are built
with (``TELEOP_ARGS``, ``PHYSICS_ARGS``, the trainee's ``ARGS``): numba passes them as
tuples, so a kernel that took the wrong item would compute with another array of the same
type. The bit-for-bit tests of the chunk and the tick would see most such slips; these read
the kernels' source and check every unpacking and every named position."""

from __future__ import annotations

import ast
import inspect

import pytest

pytest.importorskip("numba")

from davinci_sim.operators.trainee_row import ARGS  # noqa: E402
from davinci_sim.study import chunk_rows, tick_kernel  # noqa: E402
from davinci_sim.study.tick_kernel import PHYSICS_ARGS, TELEOP_ARGS  # noqa: E402

#: Each tuple's name in the kernels, its item names, and the prefix of its positions.
TUPLES = {"tp": (TELEOP_ARGS, "T_"), "pp": (PHYSICS_ARGS, "P_"), "tr_args": (ARGS, "A_")}


def _position(module, node: ast.expr | None, default: int) -> int:
    """The integer a subscript's index or slice bound names (a module constant)."""
    if node is None:
        return default
    assert isinstance(node, ast.Name), ast.unparse(node)
    return getattr(module, node.id)


def _expected(module, value: ast.expr) -> list[str] | None:
    """The item names ``value`` reads from a tuple, in order, or None if it reads none."""
    if isinstance(value, ast.Name) and value.id in TUPLES:
        return list(TUPLES[value.id][0])
    if isinstance(value, ast.Subscript) and isinstance(value.value, ast.Name):
        names = TUPLES.get(value.value.id)
        if names is None:
            return None
        items, s = names[0], value.slice
        if isinstance(s, ast.Slice):
            return list(items[_position(module, s.lower, 0) : _position(module, s.upper, None)])
        return [items[_position(module, s, 0)]]
    if isinstance(value, ast.Tuple):
        parts = [
            _expected(module, e.value if isinstance(e, ast.Starred) else e) for e in value.elts
        ]
        if any(p is None for p in parts):
            return None
        return [name for p in parts for name in p]  # type: ignore[union-attr]
    return None


def _by_position(value: ast.expr) -> bool:
    """Whether ``value`` reads items one by one at named positions (``pp[P_Q], pp[P_V]``),
    where a local may be renamed: the position constants say which item it is."""
    return isinstance(value, ast.Tuple) and all(
        isinstance(e, ast.Subscript) and not isinstance(e.slice, ast.Slice) for e in value.elts
    )


def _unpackings(module):
    """Every ``a, b, ... = <a run of tuple items>`` of ``module``'s source: (the local
    names, the items' names, the line)."""
    for node in ast.walk(ast.parse(inspect.getsource(module))):
        if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Tuple):
            expected = _expected(module, node.value)
            if expected is not None and not _by_position(node.value):
                yield [ast.unparse(t) for t in node.targets[0].elts], expected, node.lineno


def _misnamed(targets: list[str], expected: list[str]) -> list[tuple[str, str]]:
    """The locals that do not take their item's name (``_``: not used), or all of them if
    the counts differ."""
    if len(targets) != len(expected):
        return list(zip(targets, expected, strict=False)) or [("", "")]
    return [(a, e) for a, e in zip(targets, expected, strict=True) if a not in ("_", e)]


@pytest.mark.parametrize("module", [tick_kernel, chunk_rows], ids=lambda m: m.__name__)
def test_unpackings_name_every_item_in_order(module):
    found = list(_unpackings(module))
    for targets, expected, line in found:
        assert not _misnamed(targets, expected), f"{module.__name__}:{line}"
    assert len(found) >= (4 if module is tick_kernel else 0)


@pytest.mark.parametrize("module", [tick_kernel, chunk_rows], ids=lambda m: m.__name__)
def test_each_position_constant_is_its_items_position(module):
    constants = 0
    for items, prefix in TUPLES.values():
        for name, value in vars(module).items():
            if name.startswith(prefix) and name[len(prefix) :].isupper() and type(value) is int:
                assert items[value].upper() == name[len(prefix) :], (name, items[value])
                constants += 1
    assert constants >= 3


def test_a_wrong_unpacking_is_found():
    """The check itself: an unpacking that swaps two items is reported."""
    node = ast.parse("(model, address, data, body) = pp[:P_PSM_LINKS]").body[0]
    assert isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Tuple)
    expected = _expected(tick_kernel, node.value)
    assert expected is not None
    targets = [ast.unparse(t) for t in node.targets[0].elts]
    assert _misnamed(targets, expected[:4]) == [("address", "data"), ("data", "address")]
    assert _misnamed(targets, expected)  # (and too few names for the run)
